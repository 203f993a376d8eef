// A rigid body's particles at its pose (placeRigidParticles): four at a time in AVX lanes where the processor
// has AVX, two at a time otherwise. Both give, bit for bit, the particle-by-particle arithmetic written out
// below: positions, velocities and the box of the spheres, for bodies of any size whose particles are
// numbered in runs, backwards, shuffled or in runs broken at any place, or given as a run by its first id and
// count, and leave every other particle alone.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <iostream>
#include <limits>
#include <string>
#include <numeric>
#include <random>
#include <vector>

#include "volpar/dynamics/rigid_particles.hpp"
#include "volpar/engine/core/processor.hpp"

namespace volpar {
namespace {

struct Placed {
  std::vector<Vec3> position, velocity;
  ParticleBounds box;
};

/// The arithmetic placeRigidParticles() promises, one particle at a time.
Placed reference(const BodyState& s, const std::vector<ParticleId>& ids, const std::vector<Vec3>& local,
                 const std::vector<double>& radius, Placed placed) {
  const Mat3 r = s.orientation.toRotationMatrix();
  const Vec3 c = s.position, v = s.linearVelocity, w = s.angularVelocity;
  const double inf = std::numeric_limits<double>::infinity();
  placed.box = {Vec3::Constant(inf), Vec3::Constant(-inf)};
  for (const ParticleId p : ids) {
    const std::size_t i = p.index();
    const Vec3& l = local[i];
    const double ax = (r(0, 0) * l.x() + r(0, 1) * l.y()) + r(0, 2) * l.z();
    const double ay = (r(1, 0) * l.x() + r(1, 1) * l.y()) + r(1, 2) * l.z();
    const double az = r(2, 0) * l.x() + (r(2, 1) * l.y() + r(2, 2) * l.z());
    const Vec3 x(c.x() + ax, c.y() + ay, c.z() + az);
    placed.position[i] = x;
    placed.velocity[i] = Vec3(v.x() + (w.y() * az - w.z() * ay), v.y() + (w.z() * ax - w.x() * az), v.z() + (w.x() * ay - w.y() * ax));
    placed.box.lo = placed.box.lo.cwiseMin(x - Vec3::Constant(radius[i]));
    placed.box.hi = placed.box.hi.cwiseMax(x + Vec3::Constant(radius[i]));
  }
  return placed;
}

bool sameBits(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), sizeof(Vec3)) == 0; }

void expectSame(const Placed& got, const Placed& want, const std::string& what) {
  for (std::size_t i = 0; i < want.position.size(); ++i) {
    ASSERT_TRUE(sameBits(got.position[i], want.position[i])) << what << ": position of particle " << i;
    ASSERT_TRUE(sameBits(got.velocity[i], want.velocity[i])) << what << ": velocity of particle " << i;
  }
  EXPECT_TRUE(sameBits(got.box.lo, want.box.lo)) << what << ": box's low corner";
  EXPECT_TRUE(sameBits(got.box.hi, want.box.hi)) << what << ": box's high corner";
}

TEST(RigidParticles, FourAndTwoLanesGiveTheParticleByParticleArithmetic) {
  constexpr std::size_t kParticles = 64;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> local(kParticles);
  std::vector<double> radius(kParticles);
  for (std::size_t i = 0; i < kParticles; ++i) {
    local[i] = Vec3(u(rng), u(rng), u(rng)) * 0.3;
    radius[i] = 0.01 + 0.05 * (u(rng) + 1.0);
  }
  // every other particle keeps this: a particle outside the body must not be written
  const Placed untouched{std::vector<Vec3>(kParticles, Vec3(7.0, 8.0, 9.0)), std::vector<Vec3>(kParticles, Vec3(-1.0, -2.0, -3.0)), {}};
  for (int pose = 0; pose < 5; ++pose) {
    BodyState s;
    s.position = Vec3(u(rng), u(rng), u(rng)) * 10.0;
    s.orientation = Quat(u(rng), u(rng), u(rng), u(rng)).normalized();
    s.linearVelocity = Vec3(u(rng), u(rng), u(rng)) * 3.0;
    s.angularVelocity = Vec3(u(rng), u(rng), u(rng)) * 20.0;
    for (const std::size_t n : {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 13, 27, 30}) {
      std::vector<std::pair<std::string, std::vector<ParticleId>>> numberings;
      std::vector<ParticleId> ids(n);
      const std::size_t start = n > 0 ? static_cast<std::size_t>(rng() % (kParticles - n + 1)) : 0;
      for (std::size_t k = 0; k < n; ++k) ids[k] = ParticleId{static_cast<std::uint32_t>(start + k)};
      numberings.emplace_back("a run", ids);
      std::reverse(ids.begin(), ids.end());
      numberings.emplace_back("backwards", ids);
      std::shuffle(ids.begin(), ids.end(), rng);
      numberings.emplace_back("shuffled", ids);
      // runs broken at random places: ids rising by one, sometimes by two
      std::uint32_t next = 0;
      for (std::size_t k = 0; k < n; ++k) {
        ids[k] = ParticleId{next};
        next += rng() % 4 == 0 ? 2 : 1;
      }
      numberings.emplace_back("broken runs", ids);
      for (const auto& [how, numbering] : numberings) {
        const Placed want = reference(s, numbering, local, radius, untouched);
        for (const bool wide : {false, true}) {
          Placed got = untouched;
          got.box = placeRigidParticles(s, numbering, local.data(), radius.data(), got.position.data(), got.velocity.data(), wide);
          expectSame(got, want, std::string(wide ? "four lanes, " : "two lanes, ") + how + ", " + std::to_string(n) + " particles");
        }
      }
      // the run itself, given as its first id and count instead of its list
      const ParticleRun run{static_cast<std::uint32_t>(start), static_cast<std::uint32_t>(n), true};
      const Placed want = reference(s, numberings.front().second, local, radius, untouched);
      for (const bool wide : {false, true}) {
        Placed got = untouched;
        got.box = placeRigidParticles(s, run, local.data(), radius.data(), got.position.data(), got.velocity.data(), wide);
        expectSame(got, want, std::string(wide ? "four lanes, " : "two lanes, ") + "a run by its first id, " + std::to_string(n) + " particles");
      }
    }
  }
  // (without AVX both calls take two lanes, and the test says so)
  if (!processorHasAvx()) std::cout << "this processor has no AVX: only two lanes ran\n";
}

}  // namespace
}  // namespace volpar
