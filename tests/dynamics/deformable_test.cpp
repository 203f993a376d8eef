// Deformable bodies (XPBD springs and rods) against analytic oscillation and boundedness.

#include <gtest/gtest.h>

#include <cmath>
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
  const std::vector<Vec3> start = w.particles().position;
  for (int i = 0; i < 240; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  // uniform gravity: every particle moves alike, the springs stay at rest length
  const Vec3 shift = w.particles().position[0] - start[0];
  for (std::size_t i = 0; i < start.size(); ++i) EXPECT_LT((w.particles().position[i] - start[i] - shift).norm(), 1e-9);
  EXPECT_NEAR(w.bodies().state[0].linearVelocity.z(), 2 - 9.81, 1e-9);
}

}  // namespace
}  // namespace volpar
