#pragma once
// PNG files of volpar render's images (libpng: the only file that includes it).

#include <string>

#include "volpar/engine/core/status.hpp"
#include "tools/render/canvas.hpp"

namespace volpar::render {

/// Writes the canvas as an 8-bit RGB PNG to `path` (created or truncated). Only the image goes in: no time or
/// text chunks, so the same pixels give the same bytes.
Status writePng(const std::string& path, const Canvas& canvas);

}  // namespace volpar::render
