#include "volpar/engine/core/status.hpp"

#include <cstdio>
#include <cstdlib>

namespace volpar {

std::string Error::toString() const {
  std::string out;
  if (!file.empty()) {
    out += file;
    if (line > 0) {
      out += ':' + std::to_string(line);
      if (column > 0) out += ':' + std::to_string(column);
    }
    out += ": ";
  }
  out += message;
  return out;
}

void assertionFailed(const char* expr, const char* file, int line, const char* message) {
  std::fprintf(stderr, "%s:%d: volpar assertion failed: %s (%s)\n", file, line, message, expr);
  std::abort();
}

}  // namespace volpar
