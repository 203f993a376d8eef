#pragma once
// Wavefront OBJ reader for closed triangle meshes: `v x y z [w]` and `f` with polygon faces
// (triangulated as fans; `i`, `i/t`, `i//n`, `i/t/n` and negative indices). Normals, texture
// coordinates, groups, smoothing, lines and material statements are ignored. Vertices with
// identical coordinates are welded. Errors give file, line, column and what was expected.

#include <string>

#include "volpar/engine/builders/triangle_mesh.hpp"
#include "volpar/engine/core/status.hpp"

namespace volpar {

/// Parses OBJ text; `source` names it in messages. The mesh is scaled by `scale`.
[[nodiscard]] Result<TriangleMesh> parseObj(const std::string& text, const std::string& source, double scale = 1.0);

/// Reads and parses an OBJ file.
[[nodiscard]] Result<TriangleMesh> readObj(const std::string& path, double scale = 1.0);

}  // namespace volpar
