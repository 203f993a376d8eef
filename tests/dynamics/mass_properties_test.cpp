#include "volpar/dynamics/mass_properties.hpp"

#include <gtest/gtest.h>

#include <random>

namespace volpar {
namespace {

TEST(MassProperties, SingleSphere) {
  const std::vector<Vec3> p{Vec3(1, 2, 3)};
  const std::vector<double> m{2.0}, own{sphereMoment(2.0, 0.5)};
  const MassProperties mp = computeMassProperties(p, m, own);
  EXPECT_EQ(mp.mass, 2.0);
  EXPECT_EQ(mp.centre, Vec3(1, 2, 3));
  EXPECT_LT((mp.inertia - 0.4 * 2.0 * 0.25 * Mat3::Identity()).norm(), 1e-15);
}

TEST(MassProperties, ParallelAxisForTwoSpheres) {
  const std::vector<Vec3> p{Vec3(-1, 0, 0), Vec3(3, 0, 0)};
  const std::vector<double> m{3.0, 1.0}, moments{sphereMoment(3.0, 0.1), sphereMoment(1.0, 0.1)};
  const MassProperties mp = computeMassProperties(p, m, moments);
  EXPECT_EQ(mp.centre, Vec3(0, 0, 0));
  const double own = 0.4 * 0.01;
  EXPECT_NEAR(mp.inertia(0, 0), 4.0 * own, 1e-15);
  EXPECT_NEAR(mp.inertia(1, 1), 4.0 * own + 3.0 * 1 + 1.0 * 9, 1e-12);
  EXPECT_NEAR(mp.inertia(2, 2), mp.inertia(1, 1), 1e-15);
}

TEST(PrincipalAxes, DiagonalInputKeepsTheFrame) {
  const PrincipalAxes pa = principalAxes(Vec3(3, 1, 2).asDiagonal());
  EXPECT_EQ(pa.rotation.coeffs(), Quat::Identity().coeffs());
  EXPECT_EQ(pa.moments, Vec3(3, 1, 2));
}

TEST(PrincipalAxes, RecoversARotatedTensor) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 100; ++i) {
    const Quat q = Quat(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Mat3 r = q.toRotationMatrix();
    const Mat3 inertia = r * Vec3(1.0, 2.0, 3.5).asDiagonal() * r.transpose();
    const PrincipalAxes pa = principalAxes(inertia);
    const Mat3 axes = pa.rotation.toRotationMatrix();
    EXPECT_NEAR(axes.determinant(), 1.0, 1e-12);
    EXPECT_LT((axes * pa.moments.asDiagonal() * axes.transpose() - inertia).norm(), 1e-12);
    EXPECT_LT((pa.moments - Vec3(1.0, 2.0, 3.5)).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace volpar
