// Builds a world from code with volpar's builders, steps it and reads the state back: a 0.2 m cube of
// 4 x 4 x 4 particles dropped from 1 m onto a floor. It falls freely (its centre of mass at
// z0 - g t (t + dt) / 2 after t = n dt: the fall z0 - g t^2 / 2 as semi-implicit Euler steps it, velocity
// first), then comes to rest on the floor with its centre half its size above it (within a
// tenth of a particle radius). On the way down it saves the world's state (a checkpoint), builds a second
// world alike, restores the state into it, and checks that both step on bit for bit. Exits 1 when any of
// this disagrees.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/core/version.hpp"
#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/io/h5md_writer.hpp"
#include "volpar/engine/world.hpp"

namespace {

constexpr double kSize = 0.2, kRadius = 0.025;  // the cube's edge and its particles' radius [m]

/// The floor and the cube above it.
volpar::Result<volpar::BodyId> build(volpar::World& world) {
  using namespace volpar;
  const MaterialId wood = world.addMaterial(Material{"wood", 700.0, 0.2, 0.6});
  world.addPlane(Plane{Vec3::UnitZ(), 0.0, wood});
  const Result<ParticleCloud> cloud = fillShape(BoxShape(Vec3(kSize, kSize, kSize)), FillSettings{Lattice::Cubic, kRadius});
  if (!cloud.ok()) return cloud.error();
  BodyDef cube;
  cube.name = "cube";
  cube.material = wood;
  cube.position = Vec3(0.0, 0.0, 1.0);
  return world.addBody(cube, cloud.value());
}

}  // namespace

int main() {
  using namespace volpar;
  WorldSettings settings;  // dt 1/240 s, gravity -9.81 m/s^2 along z
  World world(settings);
  const Result<BodyId> id = build(world);
  if (!id.ok()) {
    std::fprintf(stderr, "embed: %s\n", id.error().message.c_str());
    return 1;
  }
  const double size = kSize, radius = kRadius;
  std::printf("volpar %s: %zu particles\n", kVersion, world.particles().size());

  // free fall for 0.25 s (the cube's underside, 0.9 m up, is still clear of the floor)
  const double z0 = world.bodies().state[id.value().index()].position.z();
  const int fall = 60;
  for (int s = 0; s < fall; ++s) world.step();
  const double t = world.time(), g = -settings.gravity.z();
  const double z = world.bodies().state[id.value().index()].position.z();
  const double expected = z0 - 0.5 * g * t * (t + settings.dt);
  std::printf("t = %.4f s: z = %.6f m, free fall %.6f m (%.6f m in continuous time)\n", t, z, expected,
              z0 - 0.5 * g * t * t);
  const bool fell = std::abs(z - expected) <= 1e-9 * z0;

  // a checkpoint as it lands (its contacts, planes and warm-starting impulses in it): a world built alike,
  // given the saved state, steps on as this one
  for (int s = 0; s < 50; ++s) world.step();
  StateArchive saved;
  world.saveState(saved);
  World again(settings);
  if (!build(again).ok() || !again.restoreState(saved).ok()) {
    std::fprintf(stderr, "embed: the saved state could not be restored\n");
    return 1;
  }
  const double saveTime = world.time();
  bool same = true;
  for (int s = 0; s < 430; ++s) {
    world.step();
    again.step();
    const auto& a = world.particles().position;
    const auto& b = again.particles().position;
    same = same && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
  }
  std::printf("t = %.4f s: state saved; restored into a second world, it steps on %s\n", saveTime,
              same ? "bit for bit as the first" : "differently");

  // by then (2 s after the fall) it has landed and rests
  const double rest = world.bodies().state[id.value().index()].position.z();
  std::printf("t = %.4f s: z = %.6f m, resting at %.6f m\n", world.time(), rest, 0.5 * size);
  const bool rests = std::abs(rest - 0.5 * size) < 0.1 * radius;

  // the resting world as a trajectory of one frame (docs/trajectory-format.md), read back
  const std::string path = (std::filesystem::temp_directory_path() / "volpar-embed.h5").string();
  TrajectoryMeta meta;
  meta.sceneName = "embed";
  bool stored = false;
  if (auto writer = H5mdWriter::create(path, world, meta); writer.ok())
    stored = writer.value()->writeFrame(world).ok() && writer.value()->close().ok();
  if (auto reader = H5mdReader::open(path); stored && reader.ok()) {
    const auto summary = reader.value()->summary();
    const auto positions = reader.value()->positions(0);
    stored = summary.ok() && positions.ok() && summary.value().frames == 1 && positions.value().size() == world.particles().size() &&
             std::memcmp(positions.value().data(), world.particles().position.data(), positions.value().size() * sizeof(Vec3)) == 0;
  } else {
    stored = false;
  }
  std::filesystem::remove(path);
  std::printf("trajectory: the last state written and read back %s\n", stored ? "as it was" : "differently");
  return fell && rests && same && stored ? 0 : 1;
}
