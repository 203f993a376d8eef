#pragma once
// Turning a SceneDesc into a World: builders fill each shape, repeats are expanded, and the scene is
// checked for bodies that overlap each other or a plane at start (an error unless the scene sets
// allow_initial_overlap: true).

#include <cstdint>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/scene/scene_desc.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

struct BuiltScene {
  World world;
  std::vector<std::size_t> bodySource;   ///< for each body, the index of its entry in SceneDesc::bodies
  std::vector<std::string> meshFiles;    ///< resolved paths of the mesh files used, in scene order
  /// What the user should know about the build, one line each: bodies whose particles fall short of their
  /// solid's size (sites are filled only where a whole particle fits inside; such a body collides at the
  /// particles' size, and weighs and turns as the whole solid)
  std::vector<std::string> notes;
};

/// The note for a filled body whose particles (spheres included) reach less far than its solid along some
/// axis of its shape frame, by more than 1e-6 of the solid's size; nothing for a body that fills it.
[[nodiscard]] std::optional<std::string> latticeFitNote(const std::string& body, const ParticleCloud& cloud);

/// The largest number of particles a scene may create.
inline constexpr std::size_t kMaxSceneParticles = 50'000'000;

/// What a scene will need, estimated from its description alone (meshes are read for their volume).
struct SceneEstimate {
  double particles = 0.0;
  double connectors = 0.0;  ///< rods and springs
  double bodies = 0.0;
  double bytes = 0.0;       ///< memory of the world while it runs, contacts included
  SourceMark largest;       ///< where the body that needs the most is described
};
/// Memory per particle (its state, grid cell, contacts and normal caches), per connector and per body [bytes],
/// measured on rigid fills (docs/hardening.md).
inline constexpr double kBytesPerParticle = 1500.0;
inline constexpr double kBytesPerConnector = 70.0;
inline constexpr double kBytesPerBody = 4096.0;

[[nodiscard]] Result<SceneEstimate> estimateScene(const SceneDesc& desc);

/// 80 % of the memory this process may use: the machine's, its container's (cgroup) or its address-space
/// limit, whichever is least [bytes].
[[nodiscard]] std::uint64_t defaultMemoryLimit();

struct BuildOptions {
  /// The most memory the scene may be estimated to need [bytes]; 0: defaultMemoryLimit().
  std::uint64_t memoryLimit = 0;
};

/// Builds the world of a scene; refuses, before allocating anything for it, a scene whose estimate exceeds
/// the memory limit.
[[nodiscard]] Result<BuiltScene> buildScene(const SceneDesc& desc, const BuildOptions& options = {});

/// Fills the shape of one body description (no placement), with the surface normals SceneDesc::normalsOf
/// gives it. `desc.path` locates errors. With `source`, also describes the solid it filled (SourceShape; for
/// a convex mesh with its face planes) and whether its normals were estimated.
[[nodiscard]] Result<ParticleCloud> buildCloud(const SceneDesc& desc, const BodyDesc& body, SourceShape* source = nullptr);

}  // namespace volpar
