#include "tools/render/png_writer.hpp"

#include <png.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace volpar::render {

Status writePng(const std::string& path, const Canvas& canvas) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) return Error{path, 0, 0, std::string("cannot create the file: ") + std::strerror(errno)};
  // libpng's simplified API: no setjmp/longjmp, errors come back in image.message
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  image.width = static_cast<png_uint_32>(canvas.width());
  image.height = static_cast<png_uint_32>(canvas.height());
  image.format = PNG_FORMAT_RGB;
  const int wrote = png_image_write_to_stdio(&image, file, 0, canvas.pixels().data(), 0, nullptr);
  const std::string message = image.message;
  png_image_free(&image);
  const bool flushed = std::fflush(file) == 0 && !std::ferror(file);
  const int savedErrno = errno;
  const bool closed = std::fclose(file) == 0;
  if (!wrote) return Error{path, 0, 0, "cannot write the PNG: " + message};
  if (!flushed || !closed) return Error{path, 0, 0, std::string("cannot write the PNG: ") + std::strerror(savedErrno)};
  return okStatus();
}

}  // namespace volpar::render
