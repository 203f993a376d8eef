#pragma once
// Loading scene files (YAML). The schema is documented in docs/scene-format.md, the limits on input in
// docs/hardening.md.

#include <cstdint>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/scene/scene_desc.hpp"

namespace volpar {

struct LoadOptions {
  /// Folders besides the scene's own that files the scene names (meshes) may lie in.
  std::vector<std::string> allowedDirs;
};

/// Reads and validates a scene file (at most kMaxSceneFileBytes). Errors name the file, line and column and
/// what was expected.
[[nodiscard]] Result<SceneDesc> loadScene(const std::string& path, const LoadOptions& options = {});

/// Parses scene text; `path` is used in messages and to resolve mesh files (relative to its folder, and
/// confined to it and to `options.allowedDirs`).
[[nodiscard]] Result<SceneDesc> parseScene(const std::string& text, const std::string& path,
                                           const LoadOptions& options = {});

}  // namespace volpar
