// Deformable bodies (XPBD springs and rods) against analytic oscillation and boundedness.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numbers>

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

/// Two particles 0.1 m apart joined by one spring.
std::string pairScene(double k, double mass, double dt) {
  return "dt: " + std::to_string(dt) + "\nsteps: 1\ngravity: [0, 0, 0]\nsolver: {substeps: 8}\nbodies:\n"
         "  - kind: deformable\n    particle_mass: " + std::to_string(mass) +
         "\n    connectors: {springs: {stiffness: " + std::to_string(k) +
         "}}\n    shape:\n      particles: {positions: [[-0.05, 0, 0], [0.05, 0, 0]], radius: 0.05}\n";
}

TEST(Deformable, SpringPairOscillatesAtAnalyticFrequency) {
  const double k = 100.0, m = 0.1, dt = 1.0 / 240.0;
  World w = test::worldFromString(pairScene(k, m, dt));
  ASSERT_EQ(w.particles().size(), 2u);
  ASSERT_EQ(w.connectors().size(), 1u);
  // stretch the pair by 1 mm and let go
  w.editParticles().position[0] = Vec3(-0.0505, 0, 0);
  w.editParticles().position[1] = Vec3(0.0505, 0, 0);
  // relative motion: omega = sqrt(2 k / m)
  const double omega = std::sqrt(2 * k / m);
  const double period = 2 * std::numbers::pi / omega;
  std::vector<double> crossings;
  double previous = 1e-3;
  for (int i = 1; i <= static_cast<int>(5 * period / dt); ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    const double stretch = (w.particles().position[1] - w.particles().position[0]).norm() - 0.1;
    if ((stretch > 0) != (previous > 0)) {
      // linear interpolation of the zero crossing
      crossings.push_back((i - 1 + previous / (previous - stretch)) * dt);
    }
    previous = stretch;
  }
  ASSERT_GE(crossings.size(), 8u);
  const double measured = 2 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  EXPECT_NEAR(measured / period, 1.0, 0.02);
  // momentum stays zero
  EXPECT_LT(w.linearMomentum().norm(), 1e-12);
}

TEST(Deformable, StiffSpringStaysBounded) {
  // 1e6 N/m between 0.01 kg particles at dt = 1/240 s: far stiffer than the step resolves
  World w = test::worldFromString(pairScene(1e6, 0.01, 1.0 / 240.0));
  w.editParticles().velocity[0] = Vec3(-1, 0.2, 0);
  w.editParticles().velocity[1] = Vec3(1, -0.2, 0);
  const double e0 = w.energy().total();
  for (int i = 0; i < 2400; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    ASSERT_LE(w.energy().total(), e0 * (1 + 1e-9)) << "step " << i;
    ASSERT_LT((w.particles().position[1] - w.particles().position[0]).norm(), 0.2);
  }
}

TEST(Deformable, FreeFallingJellyKeepsItsShape) {
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
bodies:
  - kind: deformable
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    connectors: {springs: {stiffness: 5000, damping: 1}}
    velocity: [0, 0, 2]
)");
  const auto start = w.particles().position;
  for (int i = 0; i < 240; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  // uniform gravity: every particle moves alike, the springs stay at rest length
  const Vec3 shift = w.particles().position[0] - start[0];
  for (std::size_t i = 0; i < start.size(); ++i) EXPECT_LT((w.particles().position[i] - start[i] - shift).norm(), 1e-9);
  EXPECT_NEAR(w.bodies().state[0].linearVelocity.z(), 2 - 9.81, 1e-9);
}

}  // namespace
}  // namespace volpar

namespace volpar {
namespace {

TEST(Deformable, PinnedMassOnASpringOscillatesAtSqrtKOverM) {
  // particle 0 pinned, particle 1 (0.2 kg) hanging 0.1 m below on a 500 N/m spring, no gravity
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
gravity: [0, 0, 0]
solver: {substeps: 8}
bodies:
  - kind: deformable
    particle_mass: 0.2
    connectors: {springs: {stiffness: 500}}
    pin: {min: [-0.01, -0.01, -0.01], max: [0.01, 0.01, 0.01]}
    shape:
      particles: {positions: [[0, 0, 0], [0, 0, -0.1]], radius: 0.05}
)");
  w.editParticles().position[1] = Vec3(0, 0, -0.102);  // stretched 2 mm
  const double omega = std::sqrt(500.0 / 0.2), period = 2 * std::numbers::pi / omega;
  std::vector<double> crossings;
  double previous = -0.002;
  const double dt = 1.0 / 240.0;
  for (int i = 1; i <= static_cast<int>(6 * period / dt); ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    EXPECT_EQ(w.particles().position[0], Vec3::Zero());  // the pin holds
    const double x = w.particles().position[1].z() + 0.1;
    if ((x > 0) != (previous > 0)) crossings.push_back((i - 1 + previous / (previous - x)) * dt);
    previous = x;
  }
  ASSERT_GE(crossings.size(), 10u);
  const double measured = 2 * (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
  EXPECT_NEAR(measured / period, 1.0, 0.02);
}

TEST(Deformable, HangingChainStretchesByTheWeightBelowEachSpring) {
  // ten 0.1 kg particles hanging from a pinned one, springs of 2000 N/m: spring i (from the top) carries the
  // weight of the particles below it, so the bottom sinks by sum_i (n - i) m g / k
  std::string positions;
  for (int i = 0; i <= 10; ++i) positions += (i ? ", " : "") + std::string("[0, 0, ") + std::to_string(-0.1 * i) + "]";
  World w = test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\nsolver: {substeps: 20}\nbodies:\n  - kind: deformable\n    particle_mass: 0.1\n"
      "    connectors: {springs: {stiffness: 2000, damping: 20}}\n"
      "    pin: {min: [-0.01, -0.01, -0.01], max: [0.01, 0.01, 0.01]}\n"
      "    shape:\n      particles: {radius: 0.05, positions: [" + positions + "]}\n");
  ASSERT_EQ(w.particles().size(), 11u);
  for (int i = 0; i < 2400; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  double expected = 0.0;
  for (int i = 1; i <= 10; ++i) expected += (11 - i) * 0.1 * 9.81 / 2000.0;
  const double sag = -0.1 * 10 - w.particles().position[10].z();
  EXPECT_NEAR(sag, expected, 0.05 * expected);
  EXPECT_LT(w.energy().kinetic, 1e-6);
}

/// det of the best-fit deformation gradient of a deformable body (its volume relative to the rest shape).
double volumeRatio(const World& w, BodyId id) {
  const BodyInfo& info = w.bodies().info[id.index()];
  const Vec3 c = w.bodies().state[id.index()].position;
  Mat3 apq = Mat3::Zero(), aqq = Mat3::Zero();
  for (const ParticleId p : info.particles) {
    const double m = w.particles().mass[p.index()];
    const Vec3& q = w.particles().local[p.index()];
    apq += m * (w.particles().position[p.index()] - c) * q.transpose();
    aqq += m * q * q.transpose();
  }
  return (apq * aqq.inverse()).determinant();
}

TEST(Deformable, JellyLandsWobblesAndRecoversItsShape) {
  std::ifstream in(test::sourcePath("scenes/examples/jelly.yaml"));
  World w = test::worldFromString(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()),
                                  "examples/jelly.yaml");
  double squash = 0.0;
  double peak = 0.0;
  for (int i = 0; i < 1200; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    peak = std::max(peak, w.energy().kinetic);
    squash = std::max(squash, std::abs(volumeRatio(w, BodyId(0u)) - 1.0));
  }
  EXPECT_GT(squash, 0.02);                                 // the landing squashes it
  EXPECT_NEAR(volumeRatio(w, BodyId(0u)), 1.0, 0.05);      // and it recovers
  EXPECT_LT(w.energy().kinetic, 1e-4 * peak);              // and comes to rest
  EXPECT_LT(w.bodies().state[0].linearVelocity.norm(), 0.05);
  EXPECT_NEAR(w.bodies().state[0].position.z(), 0.2, 0.02);  // resting on the floor
}

TEST(Deformable, ClothDrapesOverTheBallWithoutPassingThrough) {
  std::ifstream in(test::sourcePath("scenes/examples/cloth.yaml"));
  World w = test::worldFromString(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()),
                                  "examples/cloth.yaml");
  const BodyInfo& ball = w.bodies().info[0];
  const BodyInfo& cloth = w.bodies().info[1];
  double worst = 0.0;
  for (int i = 0; i < 720; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    if (i % 20 != 0) continue;
    for (const ParticleContact& c : w.contacts().contacts)
      if (w.particles().body[c.a.index()] == BodyId(0u) && c.b.valid())
        worst = std::max(worst, c.depth / (w.particles().radius[c.a.index()] + w.particles().radius[c.b.index()]));
  }
  EXPECT_LT(worst, 0.15);  // no cloth particle sinks into the ball's particles
  // every cloth particle outside the ball's particle shell, and the cloth at rest on it
  for (const ParticleId p : cloth.particles) {
    double nearest = 1e9;
    for (const ParticleId q : ball.particles)
      nearest = std::min(nearest, (w.particles().position[p.index()] - w.particles().position[q.index()]).norm());
    EXPECT_GT(nearest, 0.8 * 0.05);
  }
  double top = -1e9, ballTop = -1e9;
  for (const ParticleId p : cloth.particles) top = std::max(top, w.particles().position[p.index()].z());
  for (const ParticleId q : ball.particles)
    ballTop = std::max(ballTop, w.particles().position[q.index()].z() + w.particles().radius[q.index()]);
  EXPECT_GT(ballTop, 0.55);
  EXPECT_GT(top, ballTop);  // held up by the ball, above its highest particle
  EXPECT_LT(w.energy().kinetic, 0.1);
}

TEST(Deformable, BridgeCarriesTheCrateDroppedOnIt) {
  std::ifstream in(test::sourcePath("scenes/examples/bridge.yaml"));
  World w = test::worldFromString(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()),
                                  "examples/bridge.yaml");
  const BodyInfo& plank = w.bodies().info[0];
  const auto start = w.particles().position;
  for (int i = 0; i < 960; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  // the pinned ends hold, the middle sags
  std::size_t pinned = 0;
  double lowest = 1e9;
  for (const ParticleId p : plank.particles) {
    const std::size_t i = p.index();
    if (w.particles().invMass[i] == 0.0) {
      ++pinned;
      EXPECT_EQ(w.particles().position[i], start[i]);
    }
    lowest = std::min(lowest, w.particles().position[i].z());
  }
  EXPECT_EQ(pinned, 2u * 6u * 2u);
  EXPECT_LT(lowest, 0.95 - 0.02);
  // the crate rests on the plank: above the plank particles beneath it, far above the floor
  const BodyState& crate = w.bodies().state[1];
  double below = -1e9;
  for (const ParticleId p : plank.particles) {
    const Vec3& x = w.particles().position[p.index()];
    if (std::hypot(x.x() - crate.position.x(), x.y() - crate.position.y()) < 0.1) below = std::max(below, x.z());
  }
  EXPECT_GT(below, 0.5);
  EXPECT_GT(crate.position.z(), below + 0.05 + 0.15 - 0.02);
  EXPECT_LT(std::abs(crate.position.y()), 0.3);
  EXPECT_LT(crate.linearVelocity.norm(), 0.3);
}

TEST(Deformable, SelfContactStopsTwoArmsOfOneBodyFromPassingThroughEachOther) {
  // a U of particles joined by springs along the U only: two arms 0.3 m apart joined at x = 0; the upper
  // arm is thrown at the lower one (no gravity). Only self-contact between non-neighbours can stop it.
  std::string positions, links;
  std::vector<Vec3> xs;
  for (int i = 6; i >= 1; --i) xs.emplace_back(0.1 * i, 0.3, 0.0);  // upper arm, towards the bend
  xs.emplace_back(0.0, 0.3, 0.0);
  xs.emplace_back(0.0, 0.2, 0.0);
  xs.emplace_back(0.0, 0.1, 0.0);
  xs.emplace_back(0.0, 0.0, 0.0);
  for (int i = 1; i <= 6; ++i) xs.emplace_back(0.1 * i, 0.0, 0.0);  // lower arm
  for (std::size_t i = 0; i < xs.size(); ++i) {
    positions += (i ? ", [" : "[") + std::to_string(xs[i].x()) + ", " + std::to_string(xs[i].y()) + ", 0]";
    if (i + 1 < xs.size()) links += (i ? ", [" : "[") + std::to_string(i) + ", " + std::to_string(i + 1) + "]";
  }
  World w = test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nsolver: {substeps: 8}\n"
                                  "bodies:\n  - kind: deformable\n    particle_mass: 0.05\n"
                                  "    connectors: {springs: {stiffness: 5000, damping: 1}}\n"
                                  "    shape:\n      particles: {radius: 0.05, positions: [" + positions +
                                  "], connectors: [" + links + "]}\n");
  ASSERT_EQ(w.particles().size(), 16u);
  for (std::size_t i = 0; i < 5; ++i) w.editParticles().velocity[i] = Vec3(0, -1.5, 0);  // the upper arm's free part
  double closest = 1e9;
  std::size_t selfContacts = 0;
  for (int step = 0; step < 240; ++step) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    for (std::size_t a = 0; a < 6; ++a)
      for (std::size_t b = 10; b < 16; ++b)
        closest = std::min(closest, (w.particles().position[a] - w.particles().position[b]).norm());
    for (const ParticleContact& c : w.contacts().contacts)
      if (c.b.valid() && w.particles().body[c.a.index()] == w.particles().body[c.b.index()]) ++selfContacts;
  }
  EXPECT_GT(selfContacts, 0u);           // the arms met
  EXPECT_GT(closest, 0.85 * 0.1);         // and did not pass into each other
  EXPECT_LT((w.linearMomentum() - Vec3(0, -1.5 * 0.05 * 5, 0)).norm(), 1e-9);  // momentum conserved
}

TEST(Deformable, JellyThrownAtAFreeBoxKeepsMomentumAndAngularMomentum) {
  // without gravity a spinning jelly strikes a free crate off its centre, slides along it and flies on: the
  // contact's impulses act on one line for both (the line through the jelly's particle), the springs pull
  // along the line between their particles, and what a position correction moves without momentum is
  // settled with the crate, so linear and angular momentum are those of the start to round-off
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
gravity: [0, 0, 0]
solver: {substeps: 8}
materials:
  gel: {density: 1100, restitution: 0.0, friction: 0.6}
  wood: {density: 700, restitution: 0.0, friction: 0.6}
bodies:
  - kind: deformable
    shape: {box: {size: [0.4, 0.4, 0.4]}}
    fill: {radius: 0.05}
    connectors: {springs: {stiffness: 20000, damping: 5}}
    material: gel
    position: [-0.6, 0.15, 0.1]
    velocity: [4, 0, 0.5]
    angular_velocity: [0, 1, 2]
  - shape: {box: {size: [0.4, 0.6, 0.4]}}
    fill: {radius: 0.05}
    material: wood
    position: [0, 0, 0]
)");
  const Vec3 p0 = w.linearMomentum(), l0 = w.angularMomentum();
  double worstL = 0.0, worstP = 0.0;
  std::size_t touched = 0;
  for (int i = 0; i < 240; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    touched += w.stats().contactPoints;
    worstL = std::max(worstL, (w.angularMomentum() - l0).norm() / l0.norm());
    worstP = std::max(worstP, (w.linearMomentum() - p0).norm() / p0.norm());
  }
  EXPECT_GT(touched, 50u) << "the jelly never struck the crate";
  EXPECT_GT(w.bodies().state[1].angularVelocity.norm(), 0.1) << "the crate was not set turning";
  std::printf("jelly on a free crate: worst relative change of momentum %.2e, of angular momentum %.2e\n", worstP, worstL);
  EXPECT_LT(worstP, 1e-9);
  EXPECT_LT(worstL, 1e-9);
}

TEST(Deformable, JellyRestsOnJelly) {
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
solver: {substeps: 8}
materials:
  gel: {density: 1100, restitution: 0.0, friction: 0.6}
planes:
  - {normal: [0, 0, 1], offset: 0, material: gel}
bodies:
  - name: lower
    kind: deformable
    shape: {box: {size: [0.4, 0.4, 0.4]}}
    fill: {radius: 0.05}
    connectors: {springs: {stiffness: 40000, damping: 20}}
    material: gel
    position: [0, 0, 0.2]
  - name: upper
    kind: deformable
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    connectors: {springs: {stiffness: 40000, damping: 20}}
    material: gel
    position: [0.05, 0, 0.8]
)");
  const BodyInfo& lower = w.bodies().info[0];
  const BodyInfo& upper = w.bodies().info[1];
  double closest = 1e9, peak = 0.0;
  for (int step = 0; step < 720; ++step) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    peak = std::max(peak, w.energy().kinetic);
    for (const ParticleId a : lower.particles)
      for (const ParticleId b : upper.particles)
        closest = std::min(closest, (w.particles().position[a.index()] - w.particles().position[b.index()]).norm());
  }
  EXPECT_GT(closest, 0.85 * 0.1);  // never pressed into each other
  // stacked and at rest: the upper cube's centre one half-height above the lower one's top
  EXPECT_NEAR(w.bodies().state[0].position.z(), 0.2, 0.02);
  EXPECT_NEAR(w.bodies().state[1].position.z(), 0.4 + 0.15, 0.03);
  EXPECT_LT(w.energy().kinetic, 1e-3 * peak);  // what is left is a slow, decaying rocking of the top cube
  EXPECT_LT(w.bodies().state[1].linearVelocity.norm(), 0.02);
}

}  // namespace
}  // namespace volpar
