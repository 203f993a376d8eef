// Normals estimated from the connector neighbourhood (explicit particle lists).

#include <gtest/gtest.h>

#include "collision/normal_cache.hpp"
#include "engine/builders/fill.hpp"

namespace volpar {
namespace {

TEST(NormalEstimation, LatticeBoxFacesPointOutwardAndInteriorHasNone) {
  // a 5x5x5 cubic block as an explicit list: estimated normals against the exact ones
  std::vector<Vec3> p;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j)
      for (int k = 0; k < 5; ++k) p.emplace_back(0.1 * (i - 2), 0.1 * (j - 2), 0.1 * (k - 2));
  const auto connectors = connectWithin(p, 0.15);
  const EstimatedNormals est = estimateNormals(p, connectors);
  int surface = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    const bool outer = p[i].cwiseAbs().maxCoeff() > 0.15;
    EXPECT_EQ(static_cast<bool>(est.surface[i]), outer) << p[i].transpose();
    if (!outer) continue;
    ++surface;
    // face centres: exactly the face normal
    const Vec3 a = p[i].cwiseAbs();
    if ((a.array() > 0.15).count() == 1) {
      Vec3 face = Vec3::Zero();
      for (int k = 0; k < 3; ++k)
        if (a[k] > 0.15) face[k] = p[i][k] > 0 ? 1 : -1;
      EXPECT_LT((est.normal[i] - face).norm(), 1e-9) << p[i].transpose();
    } else {
      EXPECT_GT(est.normal[i].dot(p[i].normalized()), 0.9) << p[i].transpose();  // edges and corners
    }
  }
  EXPECT_EQ(surface, 125 - 27);
}

TEST(NormalEstimation, LoneParticleIsSurfaceWithoutDirection) {
  const std::vector<Vec3> p{Vec3(0, 0, 0)};
  const EstimatedNormals est = estimateNormals(p, {});
  EXPECT_TRUE(est.surface[0]);
  EXPECT_TRUE(est.normal[0].isZero());
}

}  // namespace
}  // namespace volpar
