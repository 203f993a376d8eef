// Mass properties of filled bodies against the solid shapes' analytic ones (textbook formulas written out
// here, independently of shapes.cpp), the lattice-cell model against a box it tiles exactly, fragments that
// keep angular momentum when a body with the solid's inertia breaks, and the note for a size the lattice
// cannot fill.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>

#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDensity = 800.0;

/// A world with one body of `shape` (scene YAML) filled at radius `r` on `lattice`, no gravity.
World oneBody(const std::string& shape, double r, const std::string& lattice, const std::string& extra = "") {
  return test::worldFromString("dt: 0.004\nsteps: 1\ngravity: [0, 0, 0]\nmaterials:\n  m: {density: " +
                               test::exactNumber(kDensity) + "}\nbodies:\n  - name: b\n    material: m\n    shape: " + shape +
                               "\n    fill: {radius: " + test::exactNumber(r) + ", lattice: " + lattice + "}\n" + extra);
}

/// Sorted principal moments.
Vec3 sorted(Vec3 v) {
  std::sort(v.data(), v.data() + 3);
  return v;
}

struct Solid {
  const char* name;
  std::string shape;
  double mass;
  Vec3 moments;  ///< principal [kg m^2]
};

std::vector<Solid> solids() {
  std::vector<Solid> out;
  {  // box 0.5 x 0.3 x 0.15 (two particles thick at r = 0.05)
    const double a = 0.5, b = 0.3, c = 0.15, m = kDensity * a * b * c;
    out.push_back({"box", "{box: {size: [0.5, 0.3, 0.15]}}", m,
                   m / 12.0 * Vec3(b * b + c * c, a * a + c * c, a * a + b * b)});
  }
  {  // box 0.25 on each side: not a multiple of the spacing 0.1
    const double a = 0.25, m = kDensity * a * a * a;
    out.push_back({"box_off_lattice", "{box: {size: [0.25, 0.25, 0.25]}}", m, Vec3::Constant(m * a * a / 6.0)});
  }
  {  // sphere R = 0.3
    const double R = 0.3, m = kDensity * 4.0 / 3.0 * kPi * R * R * R;
    out.push_back({"sphere", "{sphere: {radius: 0.3}}", m, Vec3::Constant(0.4 * m * R * R)});
  }
  {  // cylinder R = 0.2, h = 0.5 along z
    const double R = 0.2, h = 0.5, m = kDensity * kPi * R * R * h;
    const double across = m * (3 * R * R + h * h) / 12.0;
    out.push_back({"cylinder", "{cylinder: {radius: 0.2, height: 0.5}}", m, Vec3(across, across, 0.5 * m * R * R)});
  }
  {  // capsule R = 0.15, segment L = 0.4: a cylinder and a sphere split in two halves at the segment's ends
    const double R = 0.15, L = 0.4;
    const double mc = kDensity * kPi * R * R * L, ms = kDensity * 4.0 / 3.0 * kPi * R * R * R;
    // a hemisphere's moment about a diameter of its flat face is that of the whole sphere's half, 2/5 (ms/2) R^2;
    // moved from that face's centre to the capsule's centre, via the hemisphere's own centroid 3R/8 from the face
    const double hm = 0.5 * ms, d = 3.0 * R / 8.0;
    const double ownAcross = 0.4 * hm * R * R - hm * d * d;
    const double across = mc * (3 * R * R + L * L) / 12.0 + 2.0 * (ownAcross + hm * (0.5 * L + d) * (0.5 * L + d));
    const double along = 0.5 * mc * R * R + 0.4 * ms * R * R;
    out.push_back({"capsule", "{capsule: {radius: 0.15, length: 0.4}}", mc + ms, Vec3(across, across, along)});
  }
  return out;
}

TEST(SolidMass, FilledBodiesTakeTheSolidsMassAndInertia) {
  for (const char* lattice : {"cubic", "hcp"})
    for (const Solid& s : solids()) {
      SCOPED_TRACE(std::string(s.name) + " " + lattice);
      const World w = oneBody(s.shape, 0.05, lattice);
      const BodyInfo& info = w.bodies().info[0];
      EXPECT_NEAR(info.mass, s.mass, 1e-9 * s.mass);
      const Vec3 got = sorted(info.inertiaLocal), want = sorted(s.moments);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(got[k], want[k], 1e-3 * want[k]) << "axis " << k;
    }
}

TEST(SolidMass, ParticlesModelIsTheLatticeCellsAndExactWhereTheyTileTheBox) {
  // the cells of a 0.4 x 0.3 x 0.2 box at spacing 0.1 tile it: the particles' own model gives the solid's inertia
  const double a = 0.4, b = 0.3, c = 0.2, m = kDensity * a * b * c;
  const World w = oneBody("{box: {size: [0.4, 0.3, 0.2]}}", 0.05, "cubic", "    mass_properties: particles\n");
  const Vec3 want = m / 12.0 * Vec3(b * b + c * c, a * a + c * c, a * a + b * b);
  EXPECT_LT((w.bodies().info[0].inertiaLocal - want).norm(), 1e-12 * want.norm());
  // where they do not (a sphere's staircase), the particles' model differs from the solid by more than 1 %
  const World sphere = oneBody("{sphere: {radius: 0.3}}", 0.05, "cubic", "    mass_properties: particles\n");
  const double solid = 0.4 * kDensity * 4.0 / 3.0 * kPi * 0.3 * 0.3 * 0.3 * 0.09;
  EXPECT_GT(std::abs(sphere.bodies().info[0].inertiaLocal.x() - solid), 0.01 * solid);
}

TEST(SolidMass, MeshTakesItsPolyhedronsCentroidAndInertia) {
  // a 0.4 x 0.3 x 0.2 box as a mesh, turned and moved: its inertia turned, its centroid moved
  const Quat turn = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const Vec3 half(0.2, 0.15, 0.1), offset(0.3, -0.2, 0.5);
  auto mesh = std::make_shared<TriangleMesh>(*test::turnedBoxMesh(turn, half));
  for (Vec3& v : mesh->vertices) v += offset;
  ASSERT_TRUE(mesh->makeSolid().ok());
  const SolidMass got = MeshShape(mesh).massProperties();
  const double v = 8.0 * half.prod();
  EXPECT_NEAR(got.volume, v, 1e-12);
  EXPECT_LT((got.centroid - offset).norm(), 1e-12);
  const Vec3 s = 2.0 * half;
  const Mat3 r = turn.toRotationMatrix();
  const Mat3 want = r * (v / 12.0 * Vec3(s.y() * s.y() + s.z() * s.z(), s.x() * s.x() + s.z() * s.z(), s.x() * s.x() + s.y() * s.y())).asDiagonal() *
                    r.transpose();
  EXPECT_LT((got.inertia - want).norm(), 1e-12);
}

TEST(SolidMass, FragmentsOfABodyWithTheSolidsInertiaKeepAngularMomentum) {
  // a 0.65 x 0.25 x 0.25 slab of weak rods spinning about z (and tumbling) breaks in its first step; its inertia
  // is the solid's, not its particles' sum (6 x 2 x 2 cells of 0.1 m), and the fragments must carry that
  // difference between them
  auto slab = [](const char* strength) {
    return oneBody("{box: {size: [0.65, 0.25, 0.25]}}", 0.05, "cubic",
                   std::string("    connectors: {rods: {strength: ") + strength +
                       "}}\n    velocity: [0.2, 0.1, 0]\n    angular_velocity: [0.5, 1, 20]\n");
  };
  World w = slab("0.5"), whole = slab("1e9");
  const Vec3 p0 = w.linearMomentum(), l0 = w.angularMomentum();
  ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_EQ(whole.step(), StepStatus::Ok);
  ASSERT_GT(w.bodies().size(), 2u);
  ASSERT_EQ(whole.bodies().size(), 1u);
  EXPECT_LT((w.linearMomentum() - p0).norm(), 1e-9 * p0.norm());
  EXPECT_LT((w.angularMomentum() - l0).norm(), 1e-9 * l0.norm());
  // the kinetic energy of the body that stayed whole through the same step (tumbling, the step's rotation
  // keeps angular momentum exactly and energy to its order)
  const double e1 = whole.energy().kinetic;
  EXPECT_NEAR(w.energy().kinetic, e1, 1e-9 * e1);
}

TEST(SolidMass, ABodyTheLatticeCannotFillIsNoted) {
  auto note = [](const std::string& shape) {
    auto desc = test::sceneFromString("dt: 0.004\nsteps: 1\nbodies:\n  - name: crate\n    shape: " + shape +
                                      "\n    fill: {radius: 0.05}\n");
    EXPECT_TRUE(desc.ok());
    auto built = buildScene(desc.value());
    EXPECT_TRUE(built.ok());
    return built.ok() ? built->notes : std::vector<std::string>{};
  };
  const auto off = note("{box: {size: [0.4, 0.4, 0.25]}}");
  ASSERT_EQ(off.size(), 1u);
  EXPECT_NE(off[0].find("body 'crate': its particles span 0.4 x 0.4 x 0.2 m of its solid's 0.4 x 0.4 x 0.25 m"), std::string::npos)
      << off[0];
  EXPECT_TRUE(note("{box: {size: [0.4, 0.4, 0.3]}}").empty());
}

}  // namespace
}  // namespace volpar
