// The exact reference of the plane accuracy checks (collision/reference/fcl_adapter.hpp, coreContact):
// cores fitted to particle centres, and the closest-point direction between cores in closed-form poses.

#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/shapes.hpp"

namespace volpar {
namespace {

SourceShape box(const Vec3& size) { return SourceShape{SourceShape::Kind::Box, size, 0, 0, Vec3::Zero(), {}}; }

TEST(CoreReference, FittedCoresAreTheSolidsShrunkByTheRadiusWhereTheLatticeFillsThem) {
  const double r = 0.025;
  auto cloud = fillShape(BoxShape(Vec3(0.4, 0.3, 0.05)), {Lattice::Cubic, r});
  ASSERT_TRUE(cloud.ok());
  const SourceShape core = fittedCore(box(Vec3(0.4, 0.3, 0.05)), cloud->positions);
  EXPECT_LT((core.size - Vec3(0.35, 0.25, 0.0)).norm(), 1e-12);  // a one-layer plate has a flat core
  auto ball = fillShape(SphereShape(0.25), {Lattice::Cubic, r});
  ASSERT_TRUE(ball.ok());
  const SourceShape sphereCore = fittedCore(SourceShape{SourceShape::Kind::Sphere, Vec3::Zero(), 0.25, 0, Vec3::Zero(), {}}, ball->positions);
  EXPECT_LE(sphereCore.radius, 0.25 - r + 1e-12);
  EXPECT_GT(sphereCore.radius, 0.25 - r - 0.05);
}

TEST(CoreReference, ClosedFormPoses) {
  // face to face: boxes 0.1 apart along x
  const reference::CoreContact faces =
      reference::coreContact(box(Vec3(0.2, 0.2, 0.2)), Vec3::Zero(), Quat::Identity(), box(Vec3(0.2, 0.2, 0.2)),
                             Vec3(0.3, 0.05, -0.02), Quat::Identity());
  ASSERT_TRUE(faces.valid);
  EXPECT_NEAR(faces.distance, 0.1, 1e-9);
  EXPECT_LT((faces.normal - Vec3::UnitX()).norm(), 1e-9);
  // crossing edges: A turned 45 degrees about x, B about y, B above A: the normal is z
  const Quat qa(Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitX()));
  const Quat qb(Eigen::AngleAxisd(std::numbers::pi / 4, Vec3::UnitY()));
  const double h = 0.1 * std::sqrt(2.0);
  const reference::CoreContact edges =
      reference::coreContact(box(Vec3(0.2, 0.2, 0.2)), Vec3::Zero(), qa, box(Vec3(0.2, 0.2, 0.2)), Vec3(0.01, 0.02, 2 * h + 0.05), qb);
  ASSERT_TRUE(edges.valid);
  EXPECT_NEAR(edges.distance, 0.05, 1e-9);
  EXPECT_LT((edges.normal - Vec3::UnitZ()).norm(), 1e-7);
  // a corner of A below the middle of B's face: B's face normal, whatever the corner's offset
  const Quat corner = Quat::FromTwoVectors(Vec3(1, 1, 1).normalized(), Vec3::UnitZ());
  const reference::CoreContact vf = reference::coreContact(box(Vec3(0.2, 0.2, 0.2)), Vec3::Zero(), corner,
                                                           box(Vec3(0.6, 0.6, 0.2)), Vec3(0.03, -0.04, 0.1 * std::sqrt(3.0) + 0.12),
                                                           Quat::Identity());
  ASSERT_TRUE(vf.valid);
  EXPECT_NEAR(vf.distance, 0.02, 1e-9);
  EXPECT_LT((vf.normal - Vec3::UnitZ()).norm(), 1e-7);
  // spheres: the centre line
  const SourceShape ball{SourceShape::Kind::Sphere, Vec3::Zero(), 0.2, 0, Vec3::Zero(), {}};
  const reference::CoreContact balls = reference::coreContact(ball, Vec3::Zero(), Quat::Identity(), ball, Vec3(0.4, 0.2, 0.1),
                                                              Quat(Eigen::AngleAxisd(1.0, Vec3::UnitY())));
  ASSERT_TRUE(balls.valid);
  EXPECT_LT((balls.normal - Vec3(0.4, 0.2, 0.1).normalized()).norm(), 1e-9);
  EXPECT_NEAR(balls.distance, Vec3(0.4, 0.2, 0.1).norm() - 0.4, 1e-9);
  // overlapping cores have no reference
  const reference::CoreContact deep = reference::coreContact(ball, Vec3::Zero(), Quat::Identity(), ball, Vec3(0.3, 0, 0),
                                                             Quat::Identity());
  EXPECT_FALSE(deep.valid);
  EXPECT_TRUE(deep.overlap);
}

TEST(CoreReference, ConvexMeshCoreAgreesWithTheSameBoxAsAPrimitive) {
  // a box given by its six face planes (a convex mesh) against a sphere and a box: the same answers as
  // the box primitive, over random poses (FCL's Convex path against its box path)
  const Vec3 half(0.2, 0.15, 0.1);
  SourceShape mesh;
  mesh.kind = SourceShape::Kind::Mesh;
  for (int k = 0; k < 3; ++k) {
    mesh.facePlanes.emplace_back(Vec3::Unit(k), half[k]);
    mesh.facePlanes.emplace_back(-Vec3::Unit(k), half[k]);
  }
  EXPECT_EQ(reference::polytopeVertices(mesh.facePlanes).size(), 8u);
  const SourceShape prim = box(2.0 * half);
  const SourceShape other = box(Vec3(0.1, 0.3, 0.2));
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  int compared = 0;
  for (int i = 0; i < 300; ++i) {
    const Quat qa = Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
    const Quat qb = Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
    const Vec3 pb = Vec3(g(rng), g(rng), g(rng)).normalized() * 0.6;
    const reference::CoreContact x = reference::coreContact(mesh, Vec3::Zero(), qa, other, pb, qb);
    const reference::CoreContact y = reference::coreContact(prim, Vec3::Zero(), qa, other, pb, qb);
    ASSERT_EQ(x.valid, y.valid);
    if (!x.valid) continue;
    ++compared;
    EXPECT_NEAR(x.distance, y.distance, 1e-6);
    EXPECT_GT(x.normal.dot(y.normal), std::cos(1e-3));
  }
  EXPECT_GT(compared, 100);
}

}  // namespace
}  // namespace volpar
