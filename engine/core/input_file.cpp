#include "volpar/engine/core/input_file.hpp"

#include <filesystem>
#include <fstream>

namespace volpar {

Result<std::string> readInputFile(const std::string& path, std::uintmax_t limit, const std::string& what) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec || !fs::exists(st)) return Error{path, 0, 0, "cannot open " + what + ": no such file"};
  if (!fs::is_regular_file(st)) return Error{path, 0, 0, "cannot read " + what + ": not a regular file (a folder, device or pipe)"};
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) return Error{path, 0, 0, "cannot read " + what + ": " + ec.message()};
  if (size > limit)
    return Error{path, 0, 0, what + " of " + std::to_string(size) + " bytes; expected at most " + std::to_string(limit) + " bytes"};
  std::ifstream file(path, std::ios::binary);
  if (!file) return Error{path, 0, 0, "cannot open " + what};
  std::string text(static_cast<std::size_t>(size), '\0');
  file.read(text.data(), static_cast<std::streamsize>(size));
  if (file.gcount() != static_cast<std::streamsize>(size)) return Error{path, 0, 0, "cannot read " + what + " (it changed while read)"};
  return text;
}

}  // namespace volpar
