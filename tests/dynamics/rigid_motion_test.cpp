// Rigid-body time stepping against analytic motion: free fall (the discrete recurrence to round-off and the
// continuous solution to the integrator's O(dt) error) and torque-free rotation of an asymmetric body
// (conserved |L| and energy, and the intermediate-axis flip).

#include <gtest/gtest.h>

#include <cmath>

#include "volpar/dynamics/rigid_integrator.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

TEST(FreeFall, MatchesDiscreteRecurrenceAndContinuousSolution) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
gravity: [0, 0, -9.81]
bodies:
  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    position: [1, 2, 3]
    velocity: [0.5, -0.25, 4]
)");
  const Vec3 x0(1, 2, 3), v0(0.5, -0.25, 4), g(0, 0, -9.81);
  const double h = 0.01;
  const auto start = w.particles().position;
  for (int n = 1; n <= 300; ++n) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    const double t = n * h;
    // semi-implicit Euler: v_n = v0 + n h g, x_n = x0 + n h v0 + h^2 g n (n + 1) / 2
    const Vec3 discrete = x0 + n * h * v0 + h * h * g * (n * (n + 1) / 2.0);
    const Vec3 x = w.bodies().state[0].position;
    ASSERT_LT((x - discrete).norm(), 1e-12 * (1 + discrete.norm())) << "step " << n;
    ASSERT_LT((w.bodies().state[0].linearVelocity - (v0 + n * h * g)).norm(), 1e-12);
    // continuous solution: the first-order error is exactly h t g / 2
    const Vec3 exact = x0 + v0 * t + 0.5 * g * t * t;
    ASSERT_LT((x - exact).norm(), 0.5 * g.norm() * h * t * (1 + 1e-9) + 1e-12);
  }
  // the body does not turn, and its particles keep their offsets
  EXPECT_LT(w.bodies().shapeOrientation(BodyId(0u)).angularDistance(Quat::Identity()), 1e-15);
  const Vec3 shift = w.bodies().state[0].position - x0;
  for (std::size_t i = 0; i < start.size(); ++i) EXPECT_LT((w.particles().position[i] - start[i] - shift).norm(), 1e-12);
}

struct Spin {
  std::vector<double> intermediate;  ///< body-frame angular velocity about the intermediate axis
  double maxLDrift = 0.0;
  double maxEDrift = 0.0;
};

/// A box of `size` ("[x, y, z]") filled with particles of radius 0.05 m, without gravity, spun at
/// `angularVelocity` ("[x, y, z]").
World spinningBox(const std::string& size, const std::string& angularVelocity, const std::string& dt = "0.004166666666666667") {
  return test::worldFromString("dt: " + dt + R"(
steps: 1
gravity: [0, 0, 0]
bodies:
  - shape: {box: {size: )" + size + R"(}}
    fill: {radius: 0.05}
    angular_velocity: )" + angularVelocity + "\n");
}

/// A 0.2 x 0.4 x 0.6 m brick spun at `angularVelocity`, dt = 1/240 s.
World spinningBrick(const std::string& angularVelocity) { return spinningBox("[0.2, 0.4, 0.6]", angularVelocity); }

Spin spinFor(const std::string& angularVelocity, double seconds) {
  World w = spinningBrick(angularVelocity);
  const BodyInfo& info = w.bodies().info[0];
  // principal moments: x largest, y intermediate, z smallest
  EXPECT_GT(info.inertiaLocal.x(), info.inertiaLocal.y());
  EXPECT_GT(info.inertiaLocal.y(), info.inertiaLocal.z());
  const BodyState& s = w.bodies().state[0];
  const double l0 = angularMomentum(s, info.inertiaLocal).norm();
  const double e0 = rotationalEnergy(s, info.inertiaLocal);
  Spin out;
  const int steps = static_cast<int>(std::lround(seconds * 240));
  for (int i = 0; i < steps; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    out.maxLDrift = std::max(out.maxLDrift, std::abs(angularMomentum(s, info.inertiaLocal).norm() / l0 - 1));
    out.maxEDrift = std::max(out.maxEDrift, std::abs(rotationalEnergy(s, info.inertiaLocal) / e0 - 1));
    out.intermediate.push_back((s.orientation.conjugate() * s.angularVelocity).y());
  }
  return out;
}

TEST(TorqueFree, IntermediateAxisFlipsWhileMomentumAndEnergyHold) {
  const Spin spin = spinFor("[0.02, 5, 0.02]", 10.0);
  EXPECT_LT(spin.maxLDrift, 1e-3);
  EXPECT_LT(spin.maxEDrift, 1e-3);
  // the spin about the intermediate axis reverses (Dzhanibekov) and comes back
  int flips = 0;
  for (std::size_t i = 1; i < spin.intermediate.size(); ++i)
    if ((spin.intermediate[i] > 0) != (spin.intermediate[i - 1] > 0)) ++flips;
  EXPECT_GE(flips, 2);
  const auto [lo, hi] = std::minmax_element(spin.intermediate.begin(), spin.intermediate.end());
  EXPECT_LT(*lo, -4.5);  // a full reversal, not a wobble
  EXPECT_GT(*hi, 4.5);
}

TEST(TorqueFree, MajorAndMinorAxisSpinsAreStable) {
  for (const char* w : {"[5, 0.001, 0.001]", "[0.001, 0.001, 5]"}) {
    World world = spinningBrick(w);
    const BodyState& s = world.bodies().state[0];
    const Vec3 axis = s.angularVelocity.normalized();
    for (int i = 0; i < 2400; ++i) ASSERT_EQ(world.step(), StepStatus::Ok);
    EXPECT_GT(s.angularVelocity.normalized().dot(axis), 0.999) << w;
  }
}

TEST(TorqueFree, SpinAboutAPrincipalAxisRotatesAtConstantRate) {
  World w = spinningBox("[0.2, 0.4, 0.6]", "[0, 0, 2]", "0.01");
  for (int i = 0; i < 100; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  // 1 s at 2 rad/s about z
  const Quat expected(Eigen::AngleAxisd(2.0, Vec3::UnitZ()));
  EXPECT_LT(w.bodies().shapeOrientation(BodyId(0u)).angularDistance(expected), 1e-12);
  EXPECT_LT((w.bodies().state[0].angularVelocity - Vec3(0, 0, 2)).norm(), 1e-12);
}

TEST(TorqueFree, SphericalTopTurnsAboutItsConstantAngularVelocity) {
  // a cube of 3 x 3 x 3 particles has three equal principal moments: its angular velocity stays constant
  // and it turns about it by |w| t, whatever the axis (no principal axis to prefer)
  World w = spinningBox("[0.3, 0.3, 0.3]", "[1, -2, 0.5]");
  const Vec3 omega(1, -2, 0.5);
  const Vec3 m = w.bodies().info[0].inertiaLocal;
  EXPECT_LT((m.maxCoeff() - m.minCoeff()) / m.maxCoeff(), 1e-12);
  const Quat q0 = w.bodies().shapeOrientation(BodyId(0u));
  for (int i = 0; i < 480; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  // 2 s
  const Quat expected = Quat(Eigen::AngleAxisd(omega.norm() * 2.0, omega.normalized())) * q0;
  EXPECT_LT(w.bodies().shapeOrientation(BodyId(0u)).angularDistance(expected), 1e-10);
  EXPECT_LT((w.bodies().state[0].angularVelocity - omega).norm(), 1e-12);
}

}  // namespace
}  // namespace volpar
