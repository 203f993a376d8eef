// Scenes turned into worlds: placement, orientation, repeats, masses and body kinds.

#include <gtest/gtest.h>

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
  // pile-N's body: 27 spheres of 0.1 kg; per axis the lattice's mean square offset is s^2 (n^2 - 1) / 12,
  // so I_xx = 2.7 (2/5 r^2 + 2 * 0.01 * 8 / 12)
  EXPECT_NEAR(w.bodies().info[1].inertiaLocal.x(), 2.7 * (0.4 * 0.0025 + 2.0 * 0.01 * 8.0 / 12.0), 1e-12);
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
  const std::vector<Vec3> before = w.particles().position;
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
  const std::vector<Vec3> before = w.particles().position;
  for (int i = 0; i < 50; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  for (std::size_t i = 0; i < w.particles().size(); ++i)
    if (w.particles().invMass[i] == 0.0) EXPECT_EQ(w.particles().position[i], before[i]);
    else EXPECT_LT(w.particles().position[i].z(), before[i].z() - 1e-3);  // the rest sags
}

}  // namespace
}  // namespace volpar
