// Scenes turned into worlds: placement, orientation, repeats, masses, body kinds and surface normals.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

TEST(SceneBuild, PlacementAndOrientationOfTheShapeFrame) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - name: brick
    shape: {box: {size: [0.4, 0.2, 0.2]}}
    fill: {radius: 0.05}
    position: [1, 2, 3]
    orientation: {axis: [0, 0, 1], angle_deg: 90}
)");
  ASSERT_EQ(w.bodies().size(), 1u);
  const Quat q(Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()));
  EXPECT_LT(w.bodies().shapeOrientation(BodyId(0u)).angularDistance(q), 1e-12);
  EXPECT_LT((w.bodies().shapeOrigin(BodyId(0u)) - Vec3(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT((w.bodies().state[0].position - Vec3(1, 2, 3)).norm(), 1e-12);
  // the particle at shape (0.15, 0.05, 0.05) sits at (1, 2, 3) + Rz(90) (0.15, 0.05, 0.05)
  bool found = false;
  for (const Vec3& p : w.particles().position) found = found || (p - Vec3(1 - 0.05, 2 + 0.15, 3.05)).norm() < 1e-12;
  EXPECT_TRUE(found);
  // surface normals follow the body: the +x face of the shape now faces +y
  for (std::size_t i = 0; i < w.particles().size(); ++i) {
    const Vec3 rel = w.particles().position[i] - Vec3(1, 2, 3);
    if (rel.y() > 0.14 && std::abs(rel.x()) < 0.01 && std::abs(rel.z()) < 0.01) {
      EXPECT_LT((w.particleNormal(ParticleId(i)) - Vec3::UnitY()).norm(), 1e-12);
    }
  }
}

TEST(SceneBuild, OrientationListAppliesRotationsInOrder) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - shape: {box: {size: [0.3, 0.1, 0.1]}}
    fill: {radius: 0.05}
    orientation: [{axis: [0, 0, 1], angle_deg: 90}, {axis: [1, 0, 0], angle: 1.5707963267948966}]
)");
  // x -> y (about z), then y -> z (about x): the long axis ends up along z
  const Quat q = w.bodies().shapeOrientation(BodyId(0u));
  EXPECT_LT((q * Vec3::UnitX() - Vec3::UnitZ()).norm(), 1e-12);
}

TEST(SceneBuild, RepeatGridNamesAndPositions) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - name: crate
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
    position: [0, 0, 1]
    repeat: {count: [2, 3, 1], spacing: [0.5, 0.25, 0]}
)");
  ASSERT_EQ(w.bodies().size(), 6u);
  EXPECT_EQ(w.bodies().info[5].name, "crate[1,2,0]");
  EXPECT_LT((w.bodies().state[5].position - Vec3(0.5, 0.5, 1)).norm(), 1e-12);
  EXPECT_EQ(w.particles().size(), 6u * 8u);
}

TEST(SceneBuild, MassFromDensityParticleMassOrTotal) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
materials:
  wood: {density: 700}
bodies:
  - name: by_density
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    material: wood
  - name: per_particle
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    particle_mass: 0.1
    position: [1, 0, 0]
  - name: total
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    mass: 5.4
    position: [2, 0, 0]
)");
  ASSERT_EQ(w.bodies().size(), 3u);
  EXPECT_NEAR(w.bodies().info[0].mass, 700 * 0.027, 1e-12);
  EXPECT_NEAR(w.bodies().info[1].mass, 2.7, 1e-12);
  EXPECT_NEAR(w.bodies().info[2].mass, 5.4, 1e-12);
  // pile-N's body: 27 particles of 0.1 kg standing for a solid 0.3 m cube, I_xx = 2.7 (0.3^2 + 0.3^2) / 12
  EXPECT_NEAR(w.bodies().info[1].inertiaLocal.x(), 2.7 * 0.18 / 12.0, 1e-12);
}

TEST(SceneBuild, StaticBodiesNeverMove) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - name: floor
    kind: static
    shape: {box: {size: [2, 2, 0.2]}}
    fill: {radius: 0.05}
)");
  const auto before = w.particles().position;
  for (int i = 0; i < 100; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  EXPECT_EQ(w.particles().position, before);
  EXPECT_EQ(w.bodies().state[0].invMass, 0.0);
  EXPECT_EQ(w.energy().kinetic, 0.0);
}

TEST(SceneBuild, DeformableBodyParticlesAreIndependentPointMasses) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - name: jelly
    kind: deformable
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    connectors: {springs: {stiffness: 1000, damping: 1}}
    velocity: [1, 0, 0]
)");
  ASSERT_EQ(w.bodies().info[0].kind, BodyKind::Deformable);
  EXPECT_EQ(w.connectors().size(), 54u + 72u);
  EXPECT_EQ(w.connectors().kind[0], ConnectorKind::Spring);
  for (const Vec3& v : w.particles().velocity) EXPECT_EQ(v, Vec3(1, 0, 0));
}

TEST(SceneBuild, BreakLimitsComeFromTheBodyOrElseItsMaterial) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
materials:
  brick: {rod_strength: 250, strain_limit: 0.3}
bodies:
  - name: from_material
    material: brick
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
  - name: own
    material: brick
    connectors: {rods: {strength: 40}}
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
    position: [1, 0, 0]
  - name: soft
    kind: deformable
    material: brick
    connectors: {springs: {stiffness: 100}}
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
    position: [2, 0, 0]
  - name: plain
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
    position: [3, 0, 0]
)");
  const double expected[] = {250.0, 40.0, 0.3, std::numeric_limits<double>::infinity()};
  for (std::size_t b = 0; b < 4; ++b) {
    SCOPED_TRACE(w.bodies().info[b].name);
    ASSERT_FALSE(w.bodyConnectors(BodyId(b)).empty());
    for (const ConnectorId c : w.bodyConnectors(BodyId(b))) EXPECT_EQ(w.connectors().breakLimit[c.index()], expected[b]);
  }
}

/// The surface data of two clouds are the same, bit for bit: flags, normals, feature counts and the
/// feature normals each count says are set.
void expectSameSurface(const ParticleCloud& got, const ParticleCloud& want) {
  ASSERT_EQ(got.size(), want.size());
  EXPECT_EQ(got.positions, want.positions);
  EXPECT_EQ(got.flags, want.flags);
  EXPECT_EQ(got.normals, want.normals);
  ASSERT_EQ(got.features, want.features);
  for (std::size_t i = 0; i < got.size(); ++i)
    for (std::size_t k = 0; k < std::min<std::size_t>(got.features[i], 3); ++k)
      EXPECT_EQ(got.featureNormals[i][k], want.featureNormals[i][k]) << "particle " << i << ", feature " << k;
}

/// The largest angle [rad] between the normals two clouds give the same surface particle.
double largestNormalAngle(const ParticleCloud& a, const ParticleCloud& b) {
  double worst = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a.flags[i] && b.flags[i]) worst = std::max(worst, std::acos(std::clamp(a.normals[i].dot(b.normals[i]), -1.0, 1.0)));
  return worst;
}

TEST(SceneBuild, EstimatedNormalsAreThoseOfTheParticlesAlone) {
  auto desc = test::sceneFromString(R"(
dt: 0.01
steps: 1
bodies:
  - name: exact
    shape: {sphere: {radius: 0.25}}
    fill: {radius: 0.05}
  - name: estimated
    shape: {sphere: {radius: 0.25}}
    fill: {radius: 0.05}
    position: [1, 0, 0]
    normals: estimated
)");
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  ASSERT_EQ(desc->bodies.size(), 2u);
  EXPECT_EQ(desc->normalsOf(desc->bodies[0]), SurfaceNormals::Shape);
  EXPECT_EQ(desc->normalsOf(desc->bodies[1]), SurfaceNormals::Estimated);

  // the same fill with the solid's normals, and with the estimated ones in their place
  auto solid = fillShape(SphereShape(0.25), desc->bodies[0].fill);
  ASSERT_TRUE(solid.ok()) << solid.error().toString();
  ParticleCloud reestimated = *solid;
  useEstimatedNormals(reestimated);
  // a sphere's lattice surface is not its exact one: the two kinds differ, so the comparisons below tell them apart
  ASSERT_GT(largestNormalAngle(*solid, reestimated), 1e-3);

  SourceShape exactSource, estimatedSource;
  auto exact = buildCloud(*desc, desc->bodies[0], &exactSource);
  auto estimated = buildCloud(*desc, desc->bodies[1], &estimatedSource);
  ASSERT_TRUE(exact.ok() && estimated.ok());
  {
    SCOPED_TRACE("normals: shape (default)");
    expectSameSurface(*exact, *solid);
  }
  {
    SCOPED_TRACE("normals: estimated");
    expectSameSurface(*estimated, reestimated);
  }
  EXPECT_FALSE(exactSource.estimatedNormals);
  EXPECT_TRUE(estimatedSource.estimatedNormals);
  EXPECT_EQ(estimatedSource.kind, SourceShape::Kind::Sphere);  // the solid is still known (for `volpar check`)

  // the world's bodies carry them: surface flags, normals (unrotated bodies) and which kind they are
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  const World& w = built->world;
  for (std::size_t b = 0; b < 2; ++b) {
    SCOPED_TRACE(w.bodies().info[b].name);
    const ParticleCloud& cloud = b == 0 ? *solid : reestimated;
    EXPECT_EQ(w.bodies().info[b].source.estimatedNormals, b == 1);
    EXPECT_EQ(w.bodies().info[b].core.estimatedNormals, b == 1);
    const auto& ids = w.bodies().info[b].particles;
    ASSERT_EQ(ids.size(), cloud.size());
    for (std::size_t i = 0; i < ids.size(); ++i) {
      EXPECT_EQ(w.particles().flags[ids[i].index()] != 0, cloud.flags[i] != 0) << i;
      if (cloud.flags[i]) {
        EXPECT_LT((w.particleNormal(ids[i]) - cloud.normals[i]).norm(), 1e-12) << i;
      }
    }
  }
}

TEST(SceneBuild, TopLevelNormalsAreTheDefaultOfBodiesWithoutTheirOwn) {
  const std::string bodies = R"(
bodies:
  - name: plain
    shape: {cylinder: {radius: 0.15, height: 0.3}}
    fill: {radius: 0.05}
  - name: own
    shape: {cylinder: {radius: 0.15, height: 0.3}}
    fill: {radius: 0.05}
    position: [1, 0, 0]
    normals: shape
  - name: list
    shape:
      particles: {positions: [[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], radius: 0.05}
    position: [2, 0, 0]
)";
  // a particle list keeps its estimated normals under a top-level `shape`: it has no solid
  const struct {
    const char* top;
    SurfaceNormals plain, own, list;
  } cases[] = {{"", SurfaceNormals::Shape, SurfaceNormals::Shape, SurfaceNormals::Estimated},
               {"normals: shape\n", SurfaceNormals::Shape, SurfaceNormals::Shape, SurfaceNormals::Estimated},
               {"normals: estimated\n", SurfaceNormals::Estimated, SurfaceNormals::Shape, SurfaceNormals::Estimated}};
  for (const auto& c : cases) {
    SCOPED_TRACE(c.top[0] ? c.top : "no top-level normals");
    auto desc = test::sceneFromString("dt: 0.01\nsteps: 1\n" + std::string(c.top) + bodies);
    ASSERT_TRUE(desc.ok()) << desc.error().toString();
    const SurfaceNormals want[] = {c.plain, c.own, c.list};
    auto built = buildScene(*desc);
    ASSERT_TRUE(built.ok()) << built.error().toString();
    for (std::size_t b = 0; b < 3; ++b) {
      SCOPED_TRACE(desc->bodies[b].name);
      EXPECT_EQ(desc->normalsOf(desc->bodies[b]), want[b]);
      EXPECT_EQ(built->world.bodies().info[b].source.estimatedNormals, want[b] == SurfaceNormals::Estimated);
    }
    // the body without its own key has the normals of the default: those of the fill, or estimated from it
    auto solid = fillShape(CylinderShape(0.15, 0.3), desc->bodies[0].fill);
    ASSERT_TRUE(solid.ok()) << solid.error().toString();
    if (c.plain == SurfaceNormals::Estimated) useEstimatedNormals(*solid);
    auto plain = buildCloud(*desc, desc->bodies[0]);
    ASSERT_TRUE(plain.ok()) << plain.error().toString();
    expectSameSurface(*plain, *solid);
  }
}

TEST(SceneBuild, PinBoxesHoldTheParticlesInsideThem) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - kind: deformable
    connectors: {springs: {stiffness: 100}}
    shape: {box: {size: [0.4, 0.2, 0.1]}}
    fill: {radius: 0.05}
    position: [0, 0, 1]
    pin: [{min: [-0.2, -1, -1], max: [-0.14, 1, 1]}, {min: [0.14, -1, -1], max: [0.2, 1, 1]}]
)");
  std::size_t pinned = 0;
  for (std::size_t i = 0; i < w.particles().size(); ++i) {
    const bool end = std::abs(std::abs(w.particles().position[i].x()) - 0.15) < 1e-9;
    EXPECT_EQ(w.particles().invMass[i] == 0.0, end) << i;
    pinned += end ? 1 : 0;
  }
  EXPECT_EQ(pinned, 4u);
  const auto before = w.particles().position;
  for (int i = 0; i < 50; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  for (std::size_t i = 0; i < w.particles().size(); ++i)
    if (w.particles().invMass[i] == 0.0) EXPECT_EQ(w.particles().position[i], before[i]);
    else EXPECT_LT(w.particles().position[i].z(), before[i].z() - 1e-3);  // the rest sags
}

}  // namespace
}  // namespace volpar
