// Builders against analytic counts, masses, centres, inertias and surface normals.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "volpar/dynamics/mass_properties.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

MassProperties massOf(const ParticleCloud& c, double density) {
  std::vector<double> m;
  for (const double v : c.volumes) m.push_back(density * v);
  std::vector<double> own;
  for (std::size_t i = 0; i < m.size(); ++i) own.push_back(sphereMoment(m[i], c.radii[i]));
  return computeMassProperties(c.positions, m, own);
}

ParticleCloud fillOrFail(const SolidShape& shape, FillSettings f) {
  auto c = fillShape(shape, f);
  EXPECT_TRUE(c.ok()) << (c.ok() ? "" : c.error().toString());
  return c.ok() ? c.value() : ParticleCloud{};
}

TEST(BoxFill, CountMassAndExactLatticeInertia) {
  const Vec3 size(0.4, 0.3, 0.2);
  const double r = 0.05, s = 0.1, rho = 700.0;
  const ParticleCloud c = fillOrFail(BoxShape(size), {Lattice::Cubic, r});
  ASSERT_EQ(c.size(), 4u * 3u * 2u);
  const MassProperties mp = massOf(c, rho);
  const double m = rho * size.prod();  // the cells tile the box exactly
  EXPECT_NEAR(mp.mass, m, 1e-12 * m);
  EXPECT_LT(mp.centre.norm(), 1e-15);
  // discrete lattice: I_xx = M ((b^2 + c^2) / 12 - s^2 / 15) (lattice second moment plus sphere terms)
  const double a = size.x(), b = size.y(), h = size.z();
  EXPECT_NEAR(mp.inertia(0, 0), m * ((b * b + h * h) / 12 - s * s / 15), 1e-12);
  EXPECT_NEAR(mp.inertia(1, 1), m * ((a * a + h * h) / 12 - s * s / 15), 1e-12);
  EXPECT_NEAR(mp.inertia(2, 2), m * ((a * a + b * b) / 12 - s * s / 15), 1e-12);
  EXPECT_NEAR(mp.inertia(0, 1), 0.0, 1e-15);
}

TEST(BoxFill, InertiaTendsToContinuum) {
  // M (a^2 + b^2) / 12 as the lattice refines
  const Vec3 size(1.0, 0.6, 0.4);
  double previous = 1.0;
  for (const double r : {0.05, 0.025, 0.0125}) {
    const MassProperties mp = massOf(fillOrFail(BoxShape(size), {Lattice::Cubic, r}), 1000.0);
    const double exact = mp.mass * (size.x() * size.x() + size.y() * size.y()) / 12;
    const double err = std::abs(mp.inertia(2, 2) / exact - 1.0);
    EXPECT_LT(err, previous);
    previous = err;
  }
  EXPECT_LT(previous, 1e-3);
}

TEST(BoxFill, SidesNotMultipleOfSpacingFitInside) {
  const ParticleCloud c = fillOrFail(BoxShape(Vec3(0.35, 0.35, 0.35)), {Lattice::Cubic, 0.05});
  EXPECT_EQ(c.size(), 27u);
  for (const Vec3& p : c.positions) EXPECT_LE(p.cwiseAbs().maxCoeff() + 0.05, 0.175 + 1e-12);
}

TEST(BoxFill, SurfaceParticlesGetFaceEdgeAndCornerNormals) {
  const ParticleCloud c = fillOrFail(BoxShape(Vec3(0.3, 0.3, 0.3)), {Lattice::Cubic, 0.05});
  ASSERT_EQ(c.size(), 27u);
  int surface = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3& p = c.positions[i];
    const Vec3 outer(std::abs(p.x()) > 0.05 ? (p.x() > 0 ? 1 : -1) : 0, std::abs(p.y()) > 0.05 ? (p.y() > 0 ? 1 : -1) : 0,
                     std::abs(p.z()) > 0.05 ? (p.z() > 0 ? 1 : -1) : 0);
    if (outer.isZero()) {
      EXPECT_FALSE(c.flags[i]);
      EXPECT_TRUE(c.normals[i].isZero());
      continue;
    }
    ++surface;
    EXPECT_TRUE(c.flags[i]);
    // face particles: the face normal; edges and corners: the mean of the faces they lie on
    EXPECT_LT((c.normals[i] - outer.normalized()).norm(), 1e-12) << p.transpose();
  }
  EXPECT_EQ(surface, 26);
}

TEST(BoxFill, RodsJoinNeighboursWithinReach) {
  // 3x3x3 cubic with reach 1.5 s: face (distance s) and face-diagonal (sqrt 2 s) neighbours
  const ParticleCloud c = fillOrFail(BoxShape(Vec3(0.3, 0.3, 0.3)), {Lattice::Cubic, 0.05});
  const std::size_t faceNeighbours = 3 * 3 * 3 * 2;       // 3 axes x 9 lines x 2 pairs
  const std::size_t faceDiagonals = 3 * 3 * (2 * 2) * 2;  // 3 planes-orientations x 3 layers x 4 squares x 2
  EXPECT_EQ(c.connectors.size(), faceNeighbours + faceDiagonals);
  for (const auto& [i, j] : c.connectors) EXPECT_LT((c.positions[i] - c.positions[j]).norm(), 0.15);
}

/// Relative errors of a quantity at successive refinements: each at most `bound` x (r / size), and falling.
void expectConverges(const std::vector<double>& errors, const std::vector<double>& relativeRadii, double bound) {
  for (std::size_t i = 0; i < errors.size(); ++i) {
    EXPECT_LT(errors[i], bound * relativeRadii[i]) << "refinement " << i;
    if (i > 0) {
      EXPECT_LT(errors[i], 0.75 * errors[i - 1]) << "refinement " << i;
    }
  }
}

TEST(SphereFill, MassIsExactAndInertiaTendsToTwoFifthsMR2) {
  const double radius = 1.0;
  std::vector<double> errors, rel;
  for (const double r : {0.1, 0.05, 0.025}) {
    const SphereShape shape(radius);
    const ParticleCloud c = fillOrFail(shape, {Lattice::Cubic, r});
    const MassProperties mp = massOf(c, 1.0);
    EXPECT_NEAR(mp.mass, shape.volume(), 1e-12 * shape.volume());
    EXPECT_LT(mp.centre.norm(), 1e-12);
    const double exact = 0.4 * mp.mass * radius * radius;
    // cubic symmetry: equal moments, no products
    EXPECT_NEAR(mp.inertia(0, 0), mp.inertia(2, 2), 1e-9 * exact);
    EXPECT_NEAR(mp.inertia(0, 1), 0.0, 1e-9 * exact);
    errors.push_back(std::abs(mp.inertia(0, 0) / exact - 1.0));
    rel.push_back(r / radius);
  }
  // the particles' spheres lie inside the sphere, so the error is first order in r / R
  expectConverges(errors, rel, 2.5);
}

TEST(SphereFill, SurfaceNormalsAreRadial) {
  const ParticleCloud c = fillOrFail(SphereShape(0.5), {Lattice::Hcp, 0.05});
  int surface = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (!c.flags[i]) continue;
    ++surface;
    EXPECT_NEAR(c.normals[i].dot(c.positions[i].normalized()), 1.0, 1e-12);
    EXPECT_GT(c.positions[i].norm(), 0.5 - 0.05 - 2 * 0.1);  // within two layers of the surface
  }
  EXPECT_GT(surface, 50);
}

TEST(HcpFill, PacksDenserThanCubic) {
  const SphereShape shape(0.6);
  const ParticleCloud cubic = fillOrFail(shape, {Lattice::Cubic, 0.03});
  const ParticleCloud hcp = fillOrFail(shape, {Lattice::Hcp, 0.03});
  // close packing: sqrt(2) times the sites per volume
  EXPECT_NEAR(static_cast<double>(hcp.size()) / static_cast<double>(cubic.size()), std::numbers::sqrt2, 0.06);
  // every HCP site has at most 12 neighbours at distance s, and interior ones exactly 12
  std::vector<int> nearest(hcp.size(), 0);
  for (const auto& [i, j] : connectWithin(hcp.positions, 1.01 * 0.06)) {
    ++nearest[i];
    ++nearest[j];
  }
  int full = 0;
  for (std::size_t i = 0; i < hcp.size(); ++i) {
    EXPECT_LE(nearest[i], 12);
    if (!hcp.flags[i]) {
      EXPECT_EQ(nearest[i], 12);
      ++full;
    }
  }
  EXPECT_GT(full, 100);
  EXPECT_NEAR(massOf(hcp, 1.0).mass, shape.volume(), 1e-12 * shape.volume());
}

TEST(CylinderFill, InertiaTendsToAnalytic) {
  const double radius = 0.5, height = 1.2;
  const CylinderShape shape(radius, height);
  std::vector<double> axial, transverse, rel;
  ParticleCloud c;
  for (const double r : {0.05, 0.025, 0.0125}) {
    c = fillOrFail(shape, {Lattice::Cubic, r});
    const MassProperties mp = massOf(c, 1.0);
    const double m = mp.mass;
    EXPECT_NEAR(m, shape.volume(), 1e-12 * m);
    axial.push_back(std::abs(mp.inertia(2, 2) / (0.5 * m * radius * radius) - 1.0));
    transverse.push_back(std::abs(mp.inertia(0, 0) / (m * (3 * radius * radius + height * height) / 12) - 1.0));
    rel.push_back(r / radius);
  }
  expectConverges(axial, rel, 2.5);
  expectConverges(transverse, rel, 2.5);
  // side particles point radially, cap particles along the axis
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (!c.flags[i]) continue;
    const Vec3& p = c.positions[i];
    const Vec3& n = c.normals[i];
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    if (std::abs(p.z()) < 0.4) {
      EXPECT_NEAR(n.z(), 0.0, 1e-12) << p.transpose();
    }
    if (std::hypot(p.x(), p.y()) < 0.3) {
      EXPECT_NEAR(std::abs(n.z()), 1.0, 1e-12) << p.transpose();
    }
  }
}

TEST(CapsuleFill, MassAndAxisInertia) {
  const double radius = 0.3, length = 0.8;
  const CapsuleShape shape(radius, length);
  // about the axis: cylinder part 1/2 m r^2 plus two hemispheres 2/5 m r^2
  const double mc = std::numbers::pi * radius * radius * length;
  const double mh = 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  const double izz = 0.5 * mc * radius * radius + 0.4 * mh * radius * radius;
  EXPECT_NEAR(shape.volume(), mc + mh, 1e-15);
  std::vector<double> errors, rel;
  ParticleCloud c;
  for (const double r : {0.03, 0.015, 0.0075}) {
    c = fillOrFail(shape, {Lattice::Cubic, r});
    const MassProperties mp = massOf(c, 1.0);
    EXPECT_NEAR(mp.mass, mc + mh, 1e-11 * mp.mass);
    EXPECT_LT(mp.centre.norm(), 1e-12);
    errors.push_back(std::abs(mp.inertia(2, 2) / izz - 1.0));
    rel.push_back(r / radius);
  }
  expectConverges(errors, rel, 2.5);
  for (std::size_t i = 0; i < c.size(); ++i)
    if (c.flags[i]) {
      const Vec3& p = c.positions[i];
      const Vec3 axis(0, 0, std::clamp(p.z(), -0.4, 0.4));
      EXPECT_NEAR(c.normals[i].dot((p - axis).normalized()), 1.0, 1e-12);
    }
}

TEST(MeshFill, LShapeMatchesAnalyticMassAndCentre) {
  auto mesh = readObj(test::sourcePath("scenes/examples/meshes/l_shape.obj"));
  ASSERT_TRUE(mesh.ok()) << mesh.error().toString();
  ASSERT_TRUE(mesh->makeSolid().ok());
  EXPECT_NEAR(mesh->volume(), 0.04, 1e-12);
  const MeshShape shape(std::make_shared<const TriangleMesh>(mesh.value()));
  const ParticleCloud c = fillOrFail(shape, {Lattice::Cubic, 0.05});
  ASSERT_EQ(c.size(), 40u);  // 20 cells per layer (12 + 8), two layers
  const MassProperties mp = massOf(c, 500.0);
  EXPECT_NEAR(mp.mass, 500.0 * 0.04, 1e-9);
  EXPECT_LT((mp.centre - Vec3(0.22, 0.22, 0.1)).norm(), 1e-12);
  // the particle in the inner corner of the L lies on the top and bottom faces only
  for (std::size_t i = 0; i < c.size(); ++i) {
    EXPECT_TRUE(c.flags[i]);  // two layers thick: every particle touches a face
    if ((c.positions[i] - Vec3(0.15, 0.15, 0.05)).norm() < 1e-9) {
      EXPECT_LT((c.normals[i] - Vec3(0, 0, -1)).norm(), 1e-12) << c.normals[i].transpose();
    }
    if ((c.positions[i] - Vec3(0.55, 0.05, 0.15)).norm() < 1e-9) {
      EXPECT_LT((c.normals[i] - Vec3(1, -1, 1).normalized()).norm(), 1e-12) << c.normals[i].transpose();
    }
  }
}

TEST(Fill, TooSmallShapeIsAnError) {
  auto c = fillShape(SphereShape(0.01), {Lattice::Cubic, 0.05});
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("no particle of radius 0.05 m fits inside the sphere of radius 0.01 m"),
            std::string::npos)
      << c.error().message;
}

TEST(ParticleList, ExplicitConnectorsAreKeptAndChecked) {
  ParticleListSettings s;
  s.positions = {Vec3(0, 0, 0), Vec3(0.1, 0, 0), Vec3(0.2, 0, 0)};
  s.radii = {0.05};
  s.explicitConnectors = true;
  s.connectors = {{2, 0}};
  auto c = buildParticleList(s);
  ASSERT_TRUE(c.ok());
  ASSERT_EQ(c->connectors.size(), 1u);
  EXPECT_EQ(c->connectors[0], (std::array<std::uint32_t, 2>{0, 2}));
  EXPECT_NEAR(c->volumes[0], 4.0 / 3.0 * std::numbers::pi * 0.05 * 0.05 * 0.05, 1e-15);

  s.connectors = {{0, 1}, {1, 0}};
  auto dup = buildParticleList(s);
  ASSERT_FALSE(dup.ok());
  EXPECT_NE(dup.error().message.find("repeats the pair (0, 1)"), std::string::npos);

  s.connectors = {{0, 3}};
  auto range = buildParticleList(s);
  ASSERT_FALSE(range.ok());
  EXPECT_NE(range.error().message.find("expected indices below 3"), std::string::npos);
}

TEST(ParticleList, ReachConnectsNeighboursAndMakesAChainALine) {
  ParticleListSettings s;
  for (int i = 0; i < 5; ++i) s.positions.emplace_back(0.1 * i, 0, 0);
  s.radii = {0.05};
  auto c = buildParticleList(s);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->connectors.size(), 4u);  // default reach 1.5 diameters: nearest neighbours only
  // a chain one particle thick: every particle is on the surface all round, its "normal" the chain's direction
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(c->flags[i], kParticleSurface | kParticleLine) << i;
    EXPECT_LT(std::abs(std::abs(c->normals[i].x()) - 1.0), 1e-12) << i;
  }
}

}  // namespace
}  // namespace volpar
