// Separating-plane normals against the exact reference over thousands of random poses (plane_sweep.hpp):
// box-box, box-sphere, sphere-sphere, capsule-box, cylinder-box, mesh-box (a box mesh tilted against the
// lattice) and a one-particle-thick plate against a box (touched from either side), in three variants: the
// builders' exact shape normals, normals estimated from the particles alone, and HCP lattices. Each pose's
// rounded solids overlap by 5 to 75 % of the sum of the particle radii; the normal of the pose's largest
// patch is compared with the direction of the closest points between the two cores (FCL).
//
// Bounds, by the patch's case: face_face median <= 0.5 deg, p95 <= 2 deg; every other case median <= 2 deg,
// p95 <= 8 deg; fewer than 0.5 % of the patches unvalidated; and the paper's convex property: every
// validated plane between two convex bodies separates all their particle centres. Where a pair and variant
// does not meet them yet (kShortfalls, listed in docs/narrow-phase.md), its measured level rounded up is
// the bound instead, so that the sweep still catches a change for the worse there.

#include <gtest/gtest.h>

#include <cstdlib>
#include <functional>
#include <string>

#include "tests/collision/plane_sweep.hpp"

namespace volpar {
namespace {

struct Variant {
  const char* name;
  Lattice lattice;
  bool estimated;
};

using Maker = std::function<test::SweepShape(Lattice, bool)>;

struct Pair {
  const char* name;
  Maker a, b;
};

int posesFromEnvironment() {
  const char* v = std::getenv("VOLPAR_SWEEP_POSES");
  return v ? std::max(1, std::atoi(v)) : 2000;
}

/// Largest medians and 95th percentiles [deg] (face_face; every other case) and share of validated planes
/// that do not separate the two bodies' particles.
struct Bounds {
  double faceMedian = 0.5, faceP95 = 2.0, otherMedian = 2.0, otherP95 = 8.0, convexShare = 0.0;
};

/// The pairs and variants that do not meet the targets yet, at their measured level (2000 and 6000 poses)
/// rounded up:
/// HCP edges and corners, whose outermost particles stand back from the solid's edge (an HCP plate's planes
/// do not all separate); estimated normals on a tilted mesh box five to eight particles a side, whose faces
/// the particles fix only to within a few degrees (NormalEstimation.TiltedMeshFacesAreFixedOnlyWithinTheLattice)
/// and whose edges and corners are a band of steps; and the few planes on curved or stepped bodies that do
/// not separate every particle.
struct Shortfall {
  const char* pair;
  const char* variant;
  Bounds bounds;
};
const Shortfall kShortfalls[] = {
    {"box_box", "hcp", {0.5, 2.0, 2.0, 8.0, 0.01}},
    {"capsule_box", "shape", {0.5, 2.0, 2.0, 8.0, 0.002}},
    {"capsule_box", "estimated", {0.5, 2.0, 2.0, 8.0, 0.003}},
    {"capsule_box", "hcp", {0.5, 2.0, 2.0, 8.0, 0.01}},
    {"cylinder_box", "shape", {0.5, 2.0, 2.0, 8.0, 0.002}},
    {"cylinder_box", "estimated", {0.5, 2.0, 2.0, 8.0, 0.002}},
    {"cylinder_box", "hcp", {0.5, 2.0, 2.0, 8.0, 0.01}},
    {"mesh_box", "shape", {0.5, 2.0, 2.0, 8.0, 0.003}},
    {"mesh_box", "estimated", {1.0, 3.0, 2.0, 11.0, 0.003}},
    {"mesh_box", "hcp", {0.5, 2.0, 2.0, 8.0, 0.01}},
    {"plate_box", "hcp", {0.5, 2.0, 2.0, 8.0, 0.01}},
};

class PlaneAccuracy : public ::testing::TestWithParam<std::tuple<Pair, Variant>> {};

TEST_P(PlaneAccuracy, AgreesWithTheCoresClosestPoints) {
  const auto& [pair, variant] = GetParam();
  const test::SweepShape a = pair.a(variant.lattice, variant.estimated);
  const test::SweepShape b = pair.b(variant.lattice, variant.estimated);
  test::SweepSettings settings;
  settings.poses = posesFromEnvironment();
  const test::SweepStats s = test::sweepPlanes(a, b, settings);
  test::printSweep(std::string(pair.name) + "/" + variant.name, s);
  EXPECT_EQ(static_cast<int>(s.all.size()), settings.poses);
  Bounds bounds;
  for (const Shortfall& f : kShortfalls)
    if (std::string(f.pair) == pair.name && std::string(f.variant) == variant.name) bounds = f.bounds;
  EXPECT_LT(static_cast<double>(s.unvalidated), 0.005 * static_cast<double>(s.patches));
  EXPECT_LE(static_cast<double>(s.convexViolations), bounds.convexShare * static_cast<double>(s.patches));
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) {
    const std::vector<double>& v = s.byCase[k];
    if (v.size() < 20) continue;  // too few poses of this case for a percentile
    const bool face = static_cast<PlaneCase>(k) == PlaneCase::FaceFace;
    EXPECT_LE(test::percentile(v, 0.5), face ? bounds.faceMedian : bounds.otherMedian) << planeCaseName(static_cast<PlaneCase>(k));
    EXPECT_LE(test::percentile(v, 0.95), face ? bounds.faceP95 : bounds.otherP95) << planeCaseName(static_cast<PlaneCase>(k));
  }
}

const Pair kPairs[] = {
    {"box_box", test::sweepBox, test::sweepBox},
    {"box_sphere", test::sweepBox, test::sweepSphere},
    {"sphere_sphere", test::sweepSphere, test::sweepSphere},
    {"capsule_box", test::sweepCapsule, test::sweepBox},
    {"cylinder_box", test::sweepCylinder, test::sweepBox},
    {"mesh_box", test::sweepMesh, test::sweepBox},
    {"plate_box", test::sweepPlate, test::sweepBox},
};
const Variant kVariants[] = {
    {"shape", Lattice::Cubic, false},
    {"estimated", Lattice::Cubic, true},
    {"hcp", Lattice::Hcp, false},
};

INSTANTIATE_TEST_SUITE_P(Sweep, PlaneAccuracy, ::testing::Combine(::testing::ValuesIn(kPairs), ::testing::ValuesIn(kVariants)),
                         [](const auto& param) {
                           return std::string(std::get<0>(param.param).name) + "_" + std::get<1>(param.param).name;
                         });

}  // namespace
}  // namespace volpar
