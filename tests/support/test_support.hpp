#pragma once
// Helpers shared by the test suites: scenes from strings, paths, running the CLI.

#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "volpar/engine/core/percentile.hpp"

#include "volpar/engine/builders/triangle_mesh.hpp"
#include "volpar/engine/core/source_shape.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "volpar/engine/world.hpp"

namespace volpar::test {

/// Absolute path of a file in the source tree, e.g. sourcePath("scenes/examples/demo.yaml").
std::string sourcePath(const std::string& relative);

/// A fresh temporary directory for one test (removed at exit).
std::string tempDir();

/// Parses a scene given as text; `name` is the file name used in messages (resolved in scenes/).
Result<SceneDesc> sceneFromString(const std::string& text, const std::string& name = "inline.yaml");

/// Parses and builds a scene from text (named like sceneFromString); fails the test on error.
World worldFromString(const std::string& text, const std::string& name = "inline.yaml");

struct CommandResult {
  int exitCode = -1;
  std::string output;  ///< stdout and stderr together
};
/// Runs a shell command and captures its output.
CommandResult runCommand(const std::string& command);

/// The volpar executable built with these tests.
std::string volparBinary();

using volpar::percentile;  // engine/core/percentile.hpp

/// A number as YAML reads it back exactly (17 significant digits).
[[nodiscard]] std::string exactNumber(double v);

/// "[x, y, z], [x, y, z], ..." for a scene's particle list, every coordinate exact.
[[nodiscard]] std::string positionList(const std::vector<Vec3>& xs);

/// A box of half sizes `half` as a closed triangle mesh (two counter-clockwise triangles per face, seen from
/// outside), turned by `turn`; not yet made solid.
[[nodiscard]] std::shared_ptr<TriangleMesh> turnedBoxMesh(const Quat& turn, const Vec3& half);

/// The solid a mesh made solid (TriangleMesh::makeSolid) was filled from: kind Mesh with its convex face planes
/// (none where it is not convex).
[[nodiscard]] SourceShape meshSource(const TriangleMesh& mesh);

}  // namespace volpar::test
