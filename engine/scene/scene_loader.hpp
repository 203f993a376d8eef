#pragma once
// Loading scene files (YAML). The schema is documented in docs/scene-format.md.

#include <string>

#include "engine/core/status.hpp"
#include "engine/scene/scene_desc.hpp"

namespace volpar {

/// Reads and validates a scene file. Errors name the file, line and column and what was expected.
[[nodiscard]] Result<SceneDesc> loadScene(const std::string& path);

/// Parses scene text; `path` is used in messages and to resolve mesh files (relative to its folder).
[[nodiscard]] Result<SceneDesc> parseScene(const std::string& text, const std::string& path);

}  // namespace volpar
