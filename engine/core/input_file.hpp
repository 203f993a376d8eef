#pragma once
// Reading an input file whole, with a cap on its size checked before anything is allocated.

#include <cstdint>
#include <string>

#include "volpar/engine/core/status.hpp"

namespace volpar {

/// The whole of a regular file of at most `limit` bytes; `what` ("scene file") names it in errors. Folders,
/// devices (/dev/zero) and pipes are refused, as is a file that changes size while read.
[[nodiscard]] Result<std::string> readInputFile(const std::string& path, std::uintmax_t limit, const std::string& what);

}  // namespace volpar
