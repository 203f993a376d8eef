// Builds a world from code with volpar's builders, steps it and reads the state back: a 0.2 m cube of
// 4 x 4 x 4 particles dropped from 1 m onto a floor. It falls freely (its centre of mass at
// z0 - g t (t + dt) / 2 after t = n dt: the fall z0 - g t^2 / 2 as semi-implicit Euler steps it, velocity
// first), then comes to rest on the floor with its centre half its size above it (within a
// tenth of a particle radius). Exits 1 when either disagrees.
#include <cmath>
#include <cstdio>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/core/version.hpp"
#include "volpar/engine/world.hpp"

int main() {
  using namespace volpar;
  WorldSettings settings;  // dt 1/240 s, gravity -9.81 m/s^2 along z
  World world(settings);
  const MaterialId wood = world.addMaterial(Material{"wood", 700.0, 0.2, 0.6});
  world.addPlane(Plane{Vec3::UnitZ(), 0.0, wood});

  const double size = 0.2, radius = 0.025;
  const Result<ParticleCloud> cloud = fillShape(BoxShape(Vec3(size, size, size)), FillSettings{Lattice::Cubic, radius});
  if (!cloud.ok()) {
    std::fprintf(stderr, "embed: %s\n", cloud.error().message.c_str());
    return 1;
  }
  BodyDef cube;
  cube.name = "cube";
  cube.material = wood;
  cube.position = Vec3(0.0, 0.0, 1.0);
  const Result<BodyId> id = world.addBody(cube, cloud.value());
  if (!id.ok()) {
    std::fprintf(stderr, "embed: %s\n", id.error().message.c_str());
    return 1;
  }
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

  // then 2 s more: it lands and rests
  for (int s = 0; s < 480; ++s) world.step();
  const double rest = world.bodies().state[id.value().index()].position.z();
  std::printf("t = %.4f s: z = %.6f m, resting at %.6f m\n", world.time(), rest, 0.5 * size);
  const bool rests = std::abs(rest - 0.5 * size) < 0.1 * radius;
  return fell && rests ? 0 : 1;
}
