// The uniform grid against a brute-force reference.

#include "volpar/collision/particle_grid.hpp"

#include <gtest/gtest.h>

#include <random>

namespace volpar {
namespace {

TEST(ParticleGrid, PairsEqualBruteForce) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const double cutoff : {0.05, 0.1, 0.3}) {
    std::vector<Vec3> p(800);
    for (Vec3& x : p) x = Vec3(u(rng), u(rng), 0.2 * u(rng));
    p.push_back(p[5]);  // a coincident pair
    ParticleGrid grid;
    grid.build(p, cutoff);
    std::vector<std::pair<std::uint32_t, std::uint32_t>> brute;
    for (std::uint32_t i = 0; i < p.size(); ++i)
      for (std::uint32_t j = i + 1; j < p.size(); ++j)
        if ((p[i] - p[j]).norm() < cutoff) brute.emplace_back(i, j);
    EXPECT_EQ(grid.pairsWithin(cutoff), brute) << cutoff;

    std::vector<std::uint32_t> near;
    const Vec3 q(0.1, -0.2, 0.0);
    grid.queryRadius(q, cutoff, near);
    std::vector<std::uint32_t> expected;
    for (std::uint32_t i = 0; i < p.size(); ++i)
      if ((p[i] - q).norm() < cutoff) expected.push_back(i);
    EXPECT_EQ(near, expected);
  }
}

TEST(ParticleGrid, FarApartCoordinatesDoNotCollide) {
  // points in cells whose hashed keys could collide are still separated by the distance test
  const std::vector<Vec3> p{Vec3(0, 0, 0), Vec3(1e6, -3e5, 7e4), Vec3(1e6, -3e5, 7e4 + 0.01)};
  ParticleGrid grid;
  grid.build(p, 0.1);
  const auto pairs = grid.pairsWithin(0.1);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], (std::pair<std::uint32_t, std::uint32_t>{1, 2}));
}

}  // namespace
}  // namespace volpar
