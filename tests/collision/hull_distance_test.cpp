// Closest points of point-set hulls (collision/hull_distance.hpp): against FCL's box-box distance for
// lattice blocks (collinear and coplanar points everywhere), and by the optimality certificate on random
// and degenerate sets (the closest points are convex combinations of the inputs and the planes through
// them normal to the direction support the two sets).

#include <gtest/gtest.h>
#include <fcl/fcl.h>

#include <random>

#include "volpar/collision/hull_distance.hpp"

namespace volpar {
namespace {

/// The lattice points of a block of nx x ny x nz points with spacing s, turned by q and moved to c.
std::vector<Vec3> block(int nx, int ny, int nz, double s, const Quat& q, const Vec3& c) {
  std::vector<Vec3> out;
  for (int k = 0; k < nz; ++k)
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i)
        out.push_back(c + q * Vec3((i - 0.5 * (nx - 1)) * s, (j - 0.5 * (ny - 1)) * s, (k - 0.5 * (nz - 1)) * s));
  return out;
}

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
}

/// The optimality certificate of a separated result.
void expectCertificate(const HullDistance& h, std::span<const Vec3> a, std::span<const Vec3> b) {
  ASSERT_TRUE(h.separated);
  double sum = 0.0;
  Vec3 pa = Vec3::Zero(), pb = Vec3::Zero();
  for (int k = 0; k < h.count; ++k) {
    EXPECT_GE(h.weight[static_cast<std::size_t>(k)], -1e-12);
    sum += h.weight[static_cast<std::size_t>(k)];
    pa += h.weight[static_cast<std::size_t>(k)] * a[h.indexA[static_cast<std::size_t>(k)]];
    pb += h.weight[static_cast<std::size_t>(k)] * b[h.indexB[static_cast<std::size_t>(k)]];
  }
  EXPECT_NEAR(sum, 1.0, 1e-12);
  EXPECT_LT((pa - h.pointA).norm(), 1e-12);
  EXPECT_LT((pb - h.pointB).norm(), 1e-12);
  EXPECT_NEAR((h.pointB - h.pointA).norm(), h.distance, 1e-12);
  const double tol = 1e-9 * (1.0 + h.distance);
  for (const Vec3& x : a) EXPECT_LE(h.direction.dot(x - h.pointA), tol);
  for (const Vec3& x : b) EXPECT_GE(h.direction.dot(x - h.pointB), -tol);
}

TEST(HullDistance, LatticeBlocksAgreeWithFclBoxDistance) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int compared = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Quat qa = randomRotation(rng), qb = randomRotation(rng);
    const int na = 2 + trial % 3, nb = 2 + (trial / 3) % 4;
    const double s = 0.1;
    const Vec3 cb = Vec3(u(rng), u(rng), u(rng)).normalized() * (0.25 + 0.3 * (u(rng) + 1.0));
    const std::vector<Vec3> a = block(na, na + 1, 2, s, qa, Vec3::Zero());
    const std::vector<Vec3> b = block(nb, 2, nb + 1, s, qb, cb);
    // the same blocks as FCL boxes (a lattice block's hull is the box through its outer points)
    fcl::Transform3d xa = fcl::Transform3d::Identity(), xb = fcl::Transform3d::Identity();
    xa.linear() = qa.toRotationMatrix();
    xb.linear() = qb.toRotationMatrix();
    xb.translation() = cb;
    fcl::CollisionObjectd oa(std::make_shared<fcl::Boxd>((na - 1) * s, na * s, s), xa);
    fcl::CollisionObjectd ob(std::make_shared<fcl::Boxd>((nb - 1) * s, s, nb * s), xb);
    fcl::DistanceRequestd req(true, false);
    req.distance_tolerance = 1e-12;
    fcl::DistanceResultd res;
    fcl::distance(&oa, &ob, req, res);
    const HullDistance h = hullDistance(a, b);
    if (!(res.min_distance > 1e-6)) {
      EXPECT_FALSE(h.separated && h.distance > 1e-6) << trial;
      continue;
    }
    ++compared;
    expectCertificate(h, a, b);
    EXPECT_NEAR(h.distance, res.min_distance, 1e-7) << trial;
    const Vec3 fclDirection = (res.nearest_points[1] - res.nearest_points[0]).normalized();
    EXPECT_GT(h.direction.dot(fclDirection), std::cos(1e-4)) << trial;
  }
  EXPECT_GT(compared, 200);
}

TEST(HullDistance, RandomAndDegenerateSetsSatisfyTheCertificate) {
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<Vec3> a, b;
    const int shape = trial % 4;  // 0: random clouds, 1: coplanar, 2: collinear, 3: single points
    const Vec3 offset = Vec3(g(rng), g(rng), g(rng)).normalized() * 4.0;
    const auto point = [&](bool onB) {
      Vec3 x(g(rng), g(rng), g(rng));
      if (shape == 1) x.z() = 0.0;
      if (shape == 2) x = Vec3(x.x(), 0.0, 0.0);
      return onB ? Vec3(x + offset) : x;
    };
    const int n = shape == 3 ? 1 : 2 + trial % 9;
    for (int i = 0; i < n; ++i) a.push_back(point(false));
    for (int i = 0; i < n + 1 - (shape == 3); ++i) b.push_back(point(true));
    const HullDistance h = hullDistance(a, b);
    if (!h.separated) continue;  // the random clouds may overlap
    expectCertificate(h, a, b);
  }
}

TEST(HullDistance, OverlappingHullsAreNotSeparated) {
  const std::vector<Vec3> a = block(3, 3, 3, 0.1, Quat::Identity(), Vec3::Zero());
  const std::vector<Vec3> b = block(3, 3, 3, 0.1, Quat(Eigen::AngleAxisd(0.3, Vec3::UnitZ())), Vec3(0.15, 0.0, 0.0));
  EXPECT_FALSE(hullDistance(a, b).separated);
}

TEST(HullDistance, FaceOnFaceGivesTheExactFaceNormal) {
  // two lattice blocks face to face, B shifted sideways by a fraction of the spacing: the face normal exactly
  const Quat q(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const std::vector<Vec3> a = block(3, 3, 3, 0.1, q, Vec3::Zero());
  const std::vector<Vec3> b = block(3, 3, 3, 0.1, q, q * Vec3(0.037, -0.021, 0.29));
  const HullDistance h = hullDistance(a, b);
  ASSERT_TRUE(h.separated);
  EXPECT_LT((h.direction - q * Vec3::UnitZ()).norm(), 1e-12);
  EXPECT_NEAR(h.distance, 0.09, 1e-12);
}

}  // namespace
}  // namespace volpar
