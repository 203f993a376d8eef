#pragma once
// Turning a SceneDesc into a World: builders fill each shape, repeats are expanded, and the scene is
// checked for bodies that overlap each other or a plane at start (an error unless the scene sets
// allow_initial_overlap: true).

#include <string>
#include <vector>

#include "engine/core/status.hpp"
#include "engine/scene/scene_desc.hpp"
#include "engine/world.hpp"

namespace volpar {

struct BuiltScene {
  World world;
  std::vector<std::size_t> bodySource;   ///< for each body, the index of its entry in SceneDesc::bodies
  std::vector<std::string> meshFiles;    ///< resolved paths of the mesh files used, in scene order
};

/// The largest number of particles a scene may create.
inline constexpr std::size_t kMaxSceneParticles = 50'000'000;

[[nodiscard]] Result<BuiltScene> buildScene(const SceneDesc& desc);

/// Fills the shape of one body description (no placement), with the surface normals SceneDesc::normalsOf
/// gives it. `desc.path` locates errors. With `source`, also describes the solid it filled (SourceShape; for
/// a convex mesh with its face planes) and whether its normals were estimated.
[[nodiscard]] Result<ParticleCloud> buildCloud(const SceneDesc& desc, const BodyDesc& body, SourceShape* source = nullptr);

}  // namespace volpar
