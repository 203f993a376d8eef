// Contact response against textbook physics: bounce heights, friction distances, inclines, stacks,
// smooth sliding over a particle floor (and the bumps without separating planes), energy, settling piles,
// and bit-identical reruns.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <initializer_list>
#include <numbers>
#include <string>

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

constexpr double kG = 9.81;

World sceneWorld(const std::string& file, const std::string& replaceFrom = "", const std::string& replaceTo = "") {
  std::ifstream in(test::sourcePath("scenes/" + file));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (!replaceFrom.empty()) {
    const std::size_t at = text.find(replaceFrom);
    EXPECT_NE(at, std::string::npos) << replaceFrom;
    if (at != std::string::npos) text.replace(at, replaceFrom.size(), replaceTo);
  }
  return test::worldFromString(text, file);
}

void steps(World& w, int n) {
  for (int i = 0; i < n; ++i) ASSERT_EQ(w.step(), StepStatus::Ok) << "step " << i;
}

TEST(ContactPhysics, BallBouncesToRestitutionSquaredTimesDropHeight) {
  World w = sceneWorld("examples/bounce.yaml");
  const BodyState& s = w.bodies().state[0];
  // resting height: the lowest particle sphere just touching the floor
  double lowest = 1e9;
  for (std::size_t i = 0; i < w.particles().size(); ++i)
    lowest = std::min(lowest, w.particles().position[i].z() - w.particles().radius[i]);
  const double rest = s.position.z() - lowest;
  const double drop = s.position.z() - rest;
  double peak = 0.0;
  bool bounced = false;
  for (int i = 0; i < 720; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    if (!bounced && s.linearVelocity.z() > 0.0) bounced = true;
    if (bounced) {
      peak = std::max(peak, s.position.z());
      if (s.linearVelocity.z() < 0.0) break;  // past the first peak
    }
  }
  const double e = 0.5;
  EXPECT_NEAR((peak - rest) / drop, e * e, 0.05 * e * e);
}

TEST(ContactPhysics, SlidingBoxStopsAfterVSquaredOverTwoMuG) {
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
materials:
  m: {density: 700, restitution: 0.0, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: 0, material: m}
bodies:
  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    material: m
    position: [0, 0, 0.15]
    velocity: [2, 0, 0]
)");
  const double x0 = w.bodies().state[0].position.x();
  steps(w, 360);
  const double v = 2.0, mu = 0.5;
  EXPECT_LT(w.bodies().state[0].linearVelocity.norm(), 1e-6);
  std::printf("sliding distance %.5f m, analytic %.5f m\n", w.bodies().state[0].position.x() - x0, v * v / (2 * mu * kG));
  EXPECT_NEAR(w.bodies().state[0].position.x() - x0, v * v / (2 * mu * kG), 0.02 * v * v / (2 * mu * kG));
}

/// A crate of `side` x `side` x 0.3 m (friction 0.5) spinning at 10 rad/s about the vertical on its face, on
/// the floor plane or on a static slab of particles: its angular deceleration over the first half of the
/// analytic spin-down [rad/s^2].
double spinDeceleration(double side, bool onSlab) {
  const std::string floor = onSlab ? R"(
  - shape: {box: {size: [1.0, 1.0, 0.2]}}
    fill: {radius: 0.05}
    material: m
    kind: static
    position: [0, 0, -0.1])"
                                   : "";
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
materials:
  m: {density: 700, restitution: 0.0, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: )" + std::string(onSlab ? "-0.2" : "0") + R"(, material: m}
bodies:)" + floor + R"(
  - shape: {box: {size: [)" + test::exactNumber(side) + ", " + test::exactNumber(side) + R"(, 0.3]}}
    fill: {radius: 0.05}
    material: m
    position: [0, 0, 0.15]
    angular_velocity: [0, 0, 10]
)");
  const BodyState& s = w.bodies().state[onSlab ? 1 : 0];
  const int n = 48;  // 0.2 s, about half the spin-down
  steps(w, n);
  return (10.0 - s.angularVelocity.z()) / (n * w.settings().dt);
}

TEST(ContactPhysics, SpinningBoxDeceleratesAsUniformPressureOverItsFace) {
  // friction torque mu m g D over the moment m a^2 / 6, with D = a (sqrt 2 + ln(1 + sqrt 2)) / 6 the mean
  // distance of a square's points from its centre
  for (const double side : {0.5, 0.3}) {
    const double d = side * (std::numbers::sqrt2 + std::log(1.0 + std::numbers::sqrt2)) / 6.0;
    const double alpha = 0.5 * kG * d * 6.0 / (side * side);
    for (const bool onSlab : {false, true}) {
      SCOPED_TRACE(testing::Message() << "side " << side << (onSlab ? " on a particle slab" : " on the floor plane"));
      const double got = spinDeceleration(side, onSlab);
      std::printf("spin-down: side %.2f %s: %.3f rad/s^2, analytic %.3f\n", side, onSlab ? "slab" : "plane", got, alpha);
      EXPECT_NEAR(got, alpha, 0.05 * alpha);
    }
  }
}

TEST(ContactPhysics, BallRollsToAStopAgainstRollingResistance) {
  // a ball of one particle rolling at 1 m/s on a plane with rolling resistance 0.05: the couple mu_r R m g
  // slows it at a = 5/7 mu_r g (its friction turning the couple into deceleration), so it stops after
  // v^2 / (2 a)
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
materials:
  m: {density: 700, restitution: 0.0, friction: 0.5, rolling_resistance: 0.05}
planes:
  - {normal: [0, 0, 1], offset: 0, material: m}
bodies:
  - shape: {particles: {positions: [[0, 0, 0]], radius: 0.1}}
    material: m
    position: [0, 0, 0.1]
    velocity: [1, 0, 0]
    angular_velocity: [0, 10, 0]
)");
  const double a = 5.0 / 7.0 * 0.05 * kG;
  steps(w, 840);  // 3.5 s; it stops at 2.85 s
  const BodyState& s = w.bodies().state[0];
  std::printf("rolling distance %.4f m, analytic %.4f m\n", s.position.x(), 1.0 / (2.0 * a));
  EXPECT_LT(s.linearVelocity.norm(), 1e-6);
  EXPECT_LT(s.angularVelocity.norm(), 1e-5);
  EXPECT_NEAR(s.position.x(), 1.0 / (2.0 * a), 0.01 / (2.0 * a));
}

/// A projectile (one particle, or a 0.2 m box of eight) fired at `speed` along x at a wall one particle thick
/// (1.2 m square, static or free), starting `start` m before it, off the wall's lattice lines: whether it
/// ever got past the wall, and the deepest overlap [m] of its particles with the wall's at the end, at rest.
struct Shot {
  bool passed = false;
  double overlap = 0.0;
};
Shot fireAtWall(double speed, bool box, bool freeWall, double start) {
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
gravity: [0, 0, 0]
materials:
  m: {density: 1000, restitution: 0.0, friction: 0.3}
bodies:
  - shape: {box: {size: [0.1, 1.2, 1.2]}}
    fill: {radius: 0.05}
    material: m
    position: [0, 0, 0]
)" + std::string(freeWall ? "" : "    kind: static\n") +
                                  "  - shape: " +
                                  (box ? "{box: {size: [0.2, 0.2, 0.2]}}\n    fill: {radius: 0.05}\n"
                                       : "{particles: {positions: [[0, 0, 0]], radius: 0.05}}\n") +
                                  R"(    material: m
    position: [)" + test::exactNumber(-start) +
                                  R"(, 0.013, 0.021]
    velocity: [)" + test::exactNumber(speed) + R"(, 0, 0]
)");
  Shot shot;
  for (int i = 0; i < 240; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    shot.passed = shot.passed || w.bodies().state[1].position.x() > w.bodies().state[0].position.x();
  }
  const ParticleStore& p = w.particles();
  for (std::size_t a = 0; a < p.size(); ++a)
    for (std::size_t b = 0; b < p.size(); ++b)
      if (p.body[a].index() == 0 && p.body[b].index() == 1)
        shot.overlap = std::max(shot.overlap, p.radius[a] + p.radius[b] - (p.position[b] - p.position[a]).norm());
  return shot;
}

TEST(ContactPhysics, FastProjectilesNeitherPassNorLodgeInAWallOneParticleThick) {
  // a particle at 100 m/s moves 0.42 m, eight diameters, in a step: the speculative contacts reach as far
  // as the pair can close within the step, so the wall is seen before it can be jumped, whatever the phase
  // of the steps at which it is reached
  for (const double speed : {20.0, 40.0, 100.0})
    for (const bool box : {false, true})
      for (const bool freeWall : {false, true})
        for (int phase = 0; phase < 4; ++phase) {
          const double start = 1.0 + phase * speed / 240.0 / 4.0;
          SCOPED_TRACE(testing::Message() << (box ? "box" : "particle") << " at " << speed << " m/s, "
                                          << (freeWall ? "free" : "static") << " wall, phase " << phase);
          const Shot shot = fireAtWall(speed, box, freeWall, start);
          EXPECT_FALSE(shot.passed);
          EXPECT_LT(shot.overlap, 0.1 * 0.05);
        }
}

/// Two crates 3 mm apart in free space (within the speculative reach), the second approaching the first at
/// `speed`: the gap between their particles' surfaces after each of `n` steps.
std::vector<double> approachGaps(double speed, int n, std::vector<std::size_t>& points) {
  World w = test::worldFromString(R"(
dt: 0.004166666666666667
steps: 1
gravity: [0, 0, 0]
materials:
  m: {density: 700, restitution: 0.0, friction: 0.5}
bodies:
  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    material: m
    position: [0, 0, 1]
  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    material: m
    position: [0.303, 0, 1]
    velocity: [)" + std::to_string(-speed) + R"(, 0, 0]
)");
  std::vector<double> gaps;
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    points.push_back(w.stats().contactPoints);
    gaps.push_back(w.bodies().state[1].position.x() - w.bodies().state[0].position.x() - 0.3);
  }
  return gaps;
}

TEST(ContactPhysics, SpeculativeContactsSolvedWhereTheGapCanCloseWithinTheStep) {
  // at rest, a 3 mm gap cannot close: its speculative contacts give the solver no points
  std::vector<std::size_t> points;
  const std::vector<double> resting = approachGaps(0.0, 3, points);
  EXPECT_EQ(points, (std::vector<std::size_t>{0, 0, 0}));
  EXPECT_NEAR(resting.back(), 0.003, 1e-12);
  // at 2 m/s the gap closes in one step (8.3 mm): the points are solved, and the crates meet without
  // overlapping (restitution 0: they go on together at half the speed, momentum conserved)
  points.clear();
  const std::vector<double> fast = approachGaps(2.0, 3, points);
  EXPECT_GT(points.front(), 0u);
  for (const double g : fast) EXPECT_GT(g, -1e-3);
  // at 0.5 m/s (2.1 mm per step) the first step leaves it open with no points, the second closes it
  points.clear();
  const std::vector<double> slow = approachGaps(0.5, 3, points);
  EXPECT_EQ(points.front(), 0u);
  EXPECT_NEAR(slow.front(), 0.003 - 0.5 / 240.0, 1e-9);
  EXPECT_GT(points[1], 0u);
  for (const double g : slow) EXPECT_GT(g, -1e-3);
}

/// A crate on an incline of `degrees` (friction 0.5): its displacement along the slope over time.
std::vector<double> inclineRun(double degrees, double seconds) {
  const double t = degrees * std::numbers::pi / 180.0;
  const std::string scene = "dt: 0.004166666666666667\nsteps: 1\nmaterials:\n  wood: {density: 700, restitution: 0.0, friction: 0.5}\n"
                            "planes:\n  - {normal: [0, " + std::to_string(-std::sin(t)) + ", " + std::to_string(std::cos(t)) +
                            "], offset: 0, material: wood}\nbodies:\n  - shape: {box: {size: [0.3, 0.3, 0.3]}}\n"
                            "    fill: {radius: 0.05}\n    material: wood\n    orientation: {axis: [1, 0, 0], angle_deg: " +
                            std::to_string(degrees) + "}\n    position: [0, " + std::to_string(-0.1501 * std::sin(t)) + ", " +
                            std::to_string(0.1501 * std::cos(t)) + "]\n";
  World w = test::worldFromString(scene);
  const Vec3 down(0, -std::cos(t), -std::sin(t));  // down the slope
  const Vec3 x0 = w.bodies().state[0].position;
  std::vector<double> s;
  for (int i = 0; i < static_cast<int>(seconds * 240); ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    s.push_back((w.bodies().state[0].position - x0).dot(down));
  }
  return s;
}

TEST(ContactPhysics, BoxOnInclineBelowFrictionAngleStays) {
  const std::vector<double> s = inclineRun(20.0, 5.0);
  double drift = 0.0;
  for (const double x : s) drift = std::max(drift, std::abs(x));
  EXPECT_LT(drift, 1e-3);
}

TEST(ContactPhysics, BoxOnInclineAboveFrictionAngleSlidesWithTheoreticalAcceleration) {
  const double t = 35.0 * std::numbers::pi / 180.0;
  const std::vector<double> s = inclineRun(35.0, 1.5);
  // fit s = s0 + v0 t + a t^2 / 2 over the second half (the settling of the first contact is over)
  const std::size_t n = s.size(), from = n / 2;
  Eigen::MatrixXd a(n - from, 3);
  Eigen::VectorXd b(n - from);
  for (std::size_t i = from; i < n; ++i) {
    const double ti = static_cast<double>(i + 1) / 240.0;
    a.row(static_cast<Eigen::Index>(i - from)) << 1.0, ti, 0.5 * ti * ti;
    b[static_cast<Eigen::Index>(i - from)] = s[i];
  }
  const Eigen::Vector3d fit = a.colPivHouseholderQr().solve(b);
  const double expected = kG * (std::sin(t) - 0.5 * std::cos(t));
  EXPECT_NEAR(fit[2], expected, 0.05 * expected);
}

TEST(ContactPhysics, TenCrateTowerStandsForTenSeconds) {
  World w = sceneWorld("examples/tower.yaml");
  ASSERT_EQ(w.bodies().size(), 10u);
  const Vec3 top0 = w.bodies().state[9].position;
  double drift = 0.0;
  for (int i = 0; i < 2400; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    drift = std::max(drift, (w.bodies().state[9].position - top0).norm());
  }
  EXPECT_LT(drift, 0.01);
  EXPECT_LT(w.energy().kinetic, 1e-3);
}

/// A scene of bodies made of a light material and a heavy one `ratio` times denser (neither bouncing) over a
/// ground plane; `bodies` are the entries of its body list.
std::string massRatioScene(double ratio, const std::string& bodies) {
  char head[512];
  std::snprintf(head, sizeof head, R"(
dt: 0.004166666666666667
steps: 1
materials:
  light: {density: 100, restitution: 0.0, friction: 0.5}
  heavy: {density: %g, restitution: 0.0, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: 0, material: light}
bodies:
)", 100.0 * ratio);
  return head + bodies;
}

struct Drift {
  double largest = 0.0;          ///< [m] the largest distance any body moved from its start
  std::size_t heavyIslands = 0;  ///< islands solved exactly, summed over the steps
};

/// Steps `scene` for 5 s.
Drift driftOverFiveSeconds(const std::string& scene) {
  World w = test::worldFromString(scene);
  std::vector<Vec3> start;
  for (const BodyState& s : w.bodies().state) start.push_back(s.position);
  Drift d;
  for (int i = 0; i < 1200; ++i) {
    if (w.step() != StepStatus::Ok) {
      ADD_FAILURE() << "step " << i << " failed";
      break;
    }
    d.heavyIslands += w.stats().heavyIslands;
    for (std::size_t b = 0; b < start.size(); ++b) d.largest = std::max(d.largest, (w.bodies().state[b].position - start[b]).norm());
  }
  return d;
}

/// The largest distance any body of a stack moves from where it starts over 5 s: the bottom body (light)
/// on the ground, then `middle` of density `ratio` times the light one's, then, with `lightOnTop`, another
/// light box. The bodies start just touching.
double stackDrift(double ratio, const std::string& middle, double middleHalfHeight, bool lightOnTop) {
  char text[1024];
  std::snprintf(text, sizeof text, R"(  - shape: {box: {size: [0.4, 0.4, 0.2]}}
    fill: {radius: 0.05}
    material: light
    position: [0, 0, 0.1]
  - shape: {%s}
    fill: {radius: 0.05}
    material: heavy
    position: [0, 0, %g]
)", middle.c_str(), 0.2 + middleHalfHeight);
  std::string bodies = text;
  if (lightOnTop) {
    std::snprintf(text, sizeof text, R"(  - shape: {box: {size: [0.4, 0.4, 0.2]}}
    fill: {radius: 0.05}
    material: light
    position: [0, 0, %g]
)", 0.3 + 2.0 * middleHalfHeight);
    bodies += text;
  }
  return driftOverFiveSeconds(massRatioScene(ratio, bodies)).largest;
}

// Stacks whose masses differ by 100 and 1000 times, at the default settings: iterations alone left a heavy
// box on a light one sinking and rocking (3 mm at 100, crushed through at 1000); the exact normal solve of
// such islands keeps every body within 1 mm of where it started, over 5 s
TEST(ContactPhysics, StacksOfMassRatios100And1000HoldStill) {
  for (const double ratio : {100.0, 1000.0}) {
    EXPECT_LT(stackDrift(ratio, "box: {size: [0.4, 0.4, 0.2]}", 0.1, false), 1e-3) << "heavy box on light, ratio " << ratio;
    EXPECT_LT(stackDrift(ratio, "box: {size: [0.4, 0.4, 0.2]}", 0.1, true), 1e-3) << "light/heavy/light, ratio " << ratio;
    EXPECT_LT(stackDrift(ratio, "box: {size: [0.2, 0.2, 0.2]}", 0.1, true), 1e-3) << "light/small heavy/light, ratio " << ratio;
    EXPECT_LT(stackDrift(ratio, "cylinder: {radius: 0.15, height: 0.2}", 0.1, false), 1e-3)
        << "heavy cylinder on light box, ratio " << ratio;
  }
}

// A plate 100 and 1000 times denser than the 16 crates it rests on (4 x 4, about 110 solver points in one
// island): every body within 1 mm of its start over 5 s
TEST(ContactPhysics, HeavyPlateOnSixteenLightCratesHoldsStill) {
  const std::string bodies = R"(  - name: crate
    shape: {box: {size: [0.2, 0.2, 0.2]}}
    fill: {radius: 0.05}
    material: light
    position: [0, 0, 0.1]
    repeat: {count: [4, 4, 1], spacing: [0.3, 0.3, 0]}
  - name: plate
    shape: {box: {size: [1.1, 1.1, 0.1]}}
    fill: {radius: 0.05}
    material: heavy
    position: [0.45, 0.45, 0.25]
)";
  for (const double ratio : {100.0, 1000.0}) {
    const Drift d = driftOverFiveSeconds(massRatioScene(ratio, bodies));
    EXPECT_LT(d.largest, 1e-3) << "ratio " << ratio;
    EXPECT_GT(d.heavyIslands, 0u) << "ratio " << ratio;
  }
}

TEST(ContactPhysics, PyramidStands) {
  World w = sceneWorld("examples/pyramid.yaml");
  ASSERT_EQ(w.bodies().size(), 21u);
  std::vector<Vec3> start;
  for (const BodyState& s : w.bodies().state) start.push_back(s.position);
  steps(w, 1200);
  for (std::size_t b = 0; b < start.size(); ++b) {
    const Vec3 d = w.bodies().state[b].position - start[b];
    EXPECT_LT(std::abs(d.z()), 0.06) << w.bodies().info[b].name;  // settles a few centimetres, never falls
    EXPECT_LT(d.head<2>().norm(), 0.1) << w.bodies().info[b].name;
  }
  EXPECT_LT(w.energy().kinetic, 1e-3);
}

/// Standard deviation of the sliding crate's vertical velocity while it slides over the particle floor.
double verticalNoise(bool raw) {
  World w = sceneWorld("examples/slide.yaml", "output: {every: 2}",
                       raw ? "output: {every: 2}\nsolver: {raw_normals: true}" : "output: {every: 2}");
  const BodyState& s = w.bodies().state[1];
  std::vector<double> vz;
  for (int i = 0; i < 360; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    if (i >= 24 && s.linearVelocity.x() > 0.2) vz.push_back(s.linearVelocity.z());  // landed, still sliding
  }
  EXPECT_GT(vz.size(), 20u);
  double mean = 0.0, var = 0.0;
  for (const double v : vz) mean += v / static_cast<double>(vz.size());
  for (const double v : vz) var += (v - mean) * (v - mean) / static_cast<double>(vz.size());
  return std::sqrt(var);
}

TEST(ContactPhysics, SeparatingPlanesSlideSmoothlyWhereCentreLinesBump) {
  const double planes = verticalNoise(false);
  const double raw = verticalNoise(true);
  EXPECT_LT(planes, 1e-3);
  EXPECT_GT(raw, 10.0 * planes);
  EXPECT_GT(raw, 1e-3);
  std::printf("vertical velocity noise: separating planes %.3g m/s, centre-line normals %.3g m/s\n", planes, raw);
}

/// Crates of 27 spheres (radius 5 cm) on the ground, their centres at the heights given, allowed to start
/// overlapping (no restitution, friction 0.5).
World cratesOnTheGround(std::initializer_list<double> heights) {
  std::string scene = R"(
dt: 0.004166666666666667
steps: 1
allow_initial_overlap: true
materials:
  crate: {density: 1000, restitution: 0.0, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: 0, material: crate}
bodies:
)";
  for (const double z : heights)
    scene += R"(  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {lattice: cubic, radius: 0.05, spacing: 0.1}
    material: crate
    position: [0, 0, )" + std::to_string(z) + "]\n";
  return test::worldFromString(scene);
}

// Position correction: a crate started 3 mm into the ground (its bottom layer's spheres, radius 5 cm, at
// 4.7 cm) is pushed out by pseudo velocities that carry no momentum; the overlap beyond the slop (the default
// WorldSettings::slop of the radius against a plane) shrinks each step by the default
// SolverSettings::baumgarte (0.6, docs/architecture.md), to 0.4 of itself
TEST(ContactPhysics, OverlapBeyondTheSlopShrinksByTheCorrectionFractionEachStep) {
  World w = cratesOnTheGround({0.147});
  const double slop = WorldSettings{}.slop * 0.05;
  const auto excess = [&] { return (0.15 - w.bodies().state[0].position.z()) - slop; };
  double before = excess();
  ASSERT_NEAR(before, 0.003 - slop, 1e-9);
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    const double after = excess();
    EXPECT_NEAR(after / before, 0.4, 0.02) << "step " << i << ": " << before << " m -> " << after << " m";
    before = after;
  }
  // the correction moved the crate without momentum: it does not fly off the ground
  EXPECT_LT(std::abs(w.bodies().state[0].linearVelocity.z()), 1e-6);
}

// Position correction stops at the slop (WorldSettings::slop of r_a + r_b; of r against a plane): two
// crates of 5 cm spheres stacked on the ground, each started 3 mm deep (in the ground, in the lower crate),
// are pushed out to the slop and no farther: after 2 s the lower crate rests slop * r deep in the ground
// and the upper one slop * 2 r deep in the lower, both within a tenth of that, and at rest
TEST(ContactPhysics, OverlapsAreCorrectedDownToTheSlopAndNoFurther) {
  World w = cratesOnTheGround({0.147, 0.444});
  for (int i = 0; i < 480; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  const double slop = WorldSettings{}.slop;
  const double lower = w.bodies().state[0].position.z(), upper = w.bodies().state[1].position.z();
  EXPECT_NEAR(0.15 - lower, slop * 0.05, 0.1 * slop * 0.05) << "into the ground";
  EXPECT_NEAR(0.3 - (upper - lower), slop * 0.1, 0.1 * slop * 0.1) << "into the lower crate";
  EXPECT_NEAR(w.stats().maxPenetration, slop * 0.1, 0.1 * slop * 0.1);
  EXPECT_LT(w.energy().kinetic, 1e-8);
}

TEST(ContactPhysics, RestingContactNeverGainsEnergy) {
  World w = sceneWorld("examples/tower.yaml");
  const double e0 = w.energy().total();
  double previous = e0;
  for (int i = 0; i < 1200; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    const double e = w.energy().total();
    EXPECT_LE(e, e0 + 1e-9 * std::abs(e0)) << "step " << i;
    previous = e;
  }
  EXPECT_LT(previous, e0);
}

TEST(ContactPhysics, PileSettlesInsideItsWalls) {
  World w = sceneWorld("bench/pile-125.yaml");
  ASSERT_EQ(w.bodies().size(), 125u);
  double deepestLate = 0.0;
  for (int i = 0; i < 2000; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    if (i >= 1800) deepestLate = std::max(deepestLate, w.stats().maxPenetration);
  }
  const double wall = 0.45 * 5 / 2 + 0.3;
  for (const BodyState& s : w.bodies().state) {
    EXPECT_LT(std::abs(s.position.x()), wall);
    EXPECT_LT(std::abs(s.position.y()), wall);
    EXPECT_GT(s.position.z(), 0.0);
  }
  EXPECT_LT(w.energy().kinetic, 0.05 * 125 * 2.7);  // well under 0.05 J per kg
  EXPECT_LT(deepestLate, 0.1 * 0.05);               // under 10 % of a particle radius
}

// A deep pile comes to rest and stays there. A resting face's contacts are all about as deep, so the plain
// choice of its manifold of four changed its points from step to step with rounding; a new point has no
// warm start, the ten iterations rebuild only part of the load it carries, and pile-1000 crept on for good
// (its mean height falling 0.2 to 0.3 mm every 100 steps, 1.6 % of its points new in each step, kinetic
// energy 0.02 to 0.04 J at step 2000). Kept among near-equals (WorldSettings::manifoldDepthTies,
// manifoldScoreTies), the points keep their warm start and the pile is still after 8 s.
TEST(ContactPhysics, DeepPileComesToRestWithItsContactPointsKept) {
  World w = sceneWorld("bench/pile-1000.yaml");
  ASSERT_EQ(w.bodies().size(), 1000u);
  w.setThreads(2);
  steps(w, 2000);
  const auto meanHeight = [&] {
    double z = 0.0;
    for (const BodyState& s : w.bodies().state) z += s.position.z();
    return z / static_cast<double>(w.bodies().size());
  };
  const double z0 = meanHeight();
  std::size_t points = 0, warm = 0;
  double kinetic = 0.0;
  for (int i = 0; i < 400; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok) << "step " << 2000 + i;
    points += w.stats().contactPoints;
    warm += w.stats().warmStarted;
    kinetic = std::max(kinetic, w.energy().kinetic);
  }
  EXPECT_LT(z0 - meanHeight(), 2e-5) << "the pile's mean height fell over steps 2000-2400 [m]";
  EXPECT_LT(kinetic, 1e-3) << "the most kinetic energy over steps 2000-2400 [J]";
  EXPECT_GT(static_cast<double>(warm), 0.999 * static_cast<double>(points)) << warm << " of " << points << " points warm started";
}

TEST(ContactPhysics, SameSceneTwiceGivesBitIdenticalTrajectories) {
  const std::string dir = test::tempDir();
  for (const char* name : {"a.h5", "b.h5"}) {
    const auto r = test::runCommand(test::volparBinary() + " run " + test::sourcePath("scenes/examples/pyramid.yaml") +
                                    " --steps 400 -o " + dir + "/" + name);
    ASSERT_EQ(r.exitCode, 0) << r.output;
  }
  std::ifstream a(dir + "/a.h5", std::ios::binary), b(dir + "/b.h5", std::ios::binary);
  const std::string x((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
  const std::string y((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
  ASSERT_GT(x.size(), 10000u);
  EXPECT_TRUE(x == y);
}

}  // namespace
}  // namespace volpar
