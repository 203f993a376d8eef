// Bonds: rigid bodies whose connectors carry forces and moments like elastic beams and break by their tensile
// or shear stress; strengths drawn from a Weibull distribution; bodies glued into one. Every load below is
// worked out by statics from the particles' weights, so the breaking load is known in advance.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string>
#include <vector>

#include "tests/support/test_support.hpp"
#include "volpar/dynamics/bond_loads.hpp"

namespace volpar {
namespace {

constexpr double kRadius = 0.05;   // every particle here [m]
constexpr double kMass = 0.1;      // [kg]
constexpr double kG = 9.81;
const double kArea = std::numbers::pi * kRadius * kRadius;
const double kBendingPerMoment = kRadius / (0.25 * kArea * kRadius * kRadius);  // R / I [1/m^3]

std::string num(double v) { return test::exactNumber(v); }

/// The first step with a break within `steps` steps (0 if none), and that step's events.
std::pair<std::int64_t, std::vector<BreakEvent>> firstBreak(World& w, int steps) {
  for (int i = 0; i < steps; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    if (!w.breakEvents().empty()) return {w.breakEvents()[0].step, w.breakEvents()};
  }
  return {0, {}};
}

/// Ten particles in a row along x spinning at 10 rad/s about z without gravity; the middle bond carries the
/// centripetal force of the five particles beyond it, 0.1 kg * 100 s^-2 * (0.05 + ... + 0.45) m = 12.5 N.
World spinningChain(const std::string& strengths) {
  std::vector<Vec3> xs;
  for (int i = 0; i < 10; ++i) xs.emplace_back(-0.45 + 0.1 * i, 0.0, 0.0);
  return test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\n"
                               "materials:\n  rock: {youngs_modulus: 1.0e9, " + strengths + "}\n"
                               "bodies:\n  - name: chain\n    particle_mass: 0.1\n    material: rock\n    connectors: bonds\n"
                               "    angular_velocity: [0, 0, 10]\n"
                               "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) + "]}\n");
}

TEST(Bonds, BarInTensionBreaksAtTheTensileStrengthTimesTheBondArea) {
  const double stress = 12.5 / kArea;
  {
    World w = spinningChain("tensile_strength: " + num(1.01 * stress));
    EXPECT_EQ(firstBreak(w, 480).first, 0);
  }
  World w = spinningChain("tensile_strength: " + num(0.99 * stress));
  const auto [step, events] = firstBreak(w, 480);
  ASSERT_GT(step, 0);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].mode, BreakMode::Tension);
  EXPECT_EQ(events[0].kind, ConnectorKind::Bond);
  EXPECT_NEAR(events[0].value, stress, 0.01 * stress);  // the stress that broke it
  // the middle bond: between particles 4 and 5
  EXPECT_EQ(std::min(events[0].a.value, events[0].b.value), 4u);
  EXPECT_EQ(std::max(events[0].a.value, events[0].b.value), 5u);
}

/// Ten particles stacked on the floor, bonded: the bottom bond carries the nine above, 8.829 N, in compression.
std::int64_t columnBreak(double tensile, double shear, BreakMode* mode) {
  std::vector<Vec3> xs;
  for (int i = 0; i < 10; ++i) xs.emplace_back(0.0, 0.0, 0.05 + 0.1 * i);
  World w = test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\nplanes:\n  - {normal: [0, 0, 1], offset: 0}\n"
      "materials:\n  rock: {youngs_modulus: 1.0e9, tensile_strength: " + num(tensile) + ", shear_strength: " + num(shear) + "}\n"
      "bodies:\n  - name: column\n    particle_mass: 0.1\n    material: rock\n    connectors: bonds\n"
      "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) + "]}\n");
  const auto [step, events] = firstBreak(w, 120);
  if (step && mode) *mode = events[0].mode;
  return step;
}

TEST(Bonds, PureCompressionBreaksOnlyByShearWhereItsShearStressReachesTheShearStrength) {
  const double compression = 9 * kMass * kG / kArea;
  // far weaker in tension than the compression, and the shear strength above the compression: it holds
  EXPECT_EQ(columnBreak(1.0, 1.02 * compression, nullptr), 0);
  // pure compression sigma has a largest shear stress of sigma / 2 (Mohr's circle)
  EXPECT_EQ(columnBreak(1.0, 0.51 * compression, nullptr), 0);
  BreakMode mode = BreakMode::Tension;
  EXPECT_GT(columnBreak(1.0, 0.49 * compression, &mode), 0);
  EXPECT_EQ(mode, BreakMode::Shear);
}

/// A cantilever: six particles in a row along x glued (one bond: reach 1.1) to the side of a 4 x 4 x 4 block
/// of bonded particles resting on the floor. The block's bonds never break; the chain's and the glue's have
/// the tensile strength `strength`.
World cantilever(double strength) {
  std::vector<Vec3> xs;
  for (int i = 0; i < 6; ++i) xs.emplace_back(0.25 + 0.1 * i, 0.05, 0.25);
  return test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\nplanes:\n  - {normal: [0, 0, 1], offset: 0}\n"
      "materials:\n  steel: {youngs_modulus: 2.0e11}\n  rock: {youngs_modulus: 1.0e9, tensile_strength: " + num(strength) + "}\n"
      "bodies:\n"
      "  - {name: block, shape: {box: {size: [0.4, 0.4, 0.4]}}, fill: {radius: 0.05}, particle_mass: 0.1, material: steel,\n"
      "     connectors: bonds, position: [0, 0, 0.2]}\n"
      "  - name: arm\n    particle_mass: 0.1\n    material: rock\n    connectors: bonds\n"
      "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) + "]}\n"
      "glue:\n  - {name: cantilever, bodies: [block, arm], material: rock, reach: 1.1}\n");
}

TEST(Bonds, CantileverBreaksAtTheRootWhereTheRootMomentReachesTheBendingStrength) {
  // the root bond joins the block's particle at x = 0.15 to the arm's first; the moment there is the arm's
  // weight times its distance from that particle
  double moment = 0.0;
  for (int i = 0; i < 6; ++i) moment += kMass * kG * (0.25 + 0.1 * i - 0.15);
  const double stress = moment * kBendingPerMoment;
  {
    World w = cantilever(1.03 * stress);
    ASSERT_EQ(w.bodies().size(), 3u);  // block and arm retired into the glued body
    EXPECT_FALSE(w.bodies().info[0].alive);
    EXPECT_EQ(w.bodies().info[2].name, "cantilever");
    EXPECT_EQ(firstBreak(w, 240).first, 0);
  }
  World w = cantilever(0.97 * stress);
  const auto [step, events] = firstBreak(w, 240);
  ASSERT_GT(step, 0);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].mode, BreakMode::Tension);
  // the root: one end on the block (particles 0..63), the other the arm's first particle (64)
  EXPECT_LT(std::min(events[0].a.value, events[0].b.value), 64u);
  EXPECT_EQ(std::max(events[0].a.value, events[0].b.value), 64u);
  EXPECT_NEAR(events[0].value, stress, 0.03 * stress);
}

/// Three-point bending: eleven particles in a row on two fixed particles under its ends (a span of 1 m),
/// loaded at mid-span by a column of three 1 kg particles glued on top of the middle one.
World threePoint(double strength) {
  std::vector<Vec3> beam, column;
  for (int i = 0; i < 11; ++i) beam.emplace_back(-0.5 + 0.1 * i, 0.0, 0.15);
  for (int i = 0; i < 3; ++i) column.emplace_back(0.0, 0.0, 0.25 + 0.1 * i);
  return test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\n"
      "materials:\n  rock: {youngs_modulus: 1.0e9, tensile_strength: " + num(strength) + "}\n"
      "bodies:\n"
      "  - {name: left, kind: static, shape: {particles: {radius: 0.05, positions: [[-0.5, 0, 0.05]]}}}\n"
      "  - {name: right, kind: static, shape: {particles: {radius: 0.05, positions: [[0.5, 0, 0.05]]}}}\n"
      "  - {name: beam, particle_mass: 0.1, material: rock, connectors: bonds,\n"
      "     shape: {particles: {radius: 0.05, positions: [" + test::positionList(beam) + "]}}}\n"
      "  - {name: load, particle_mass: 1.0, material: rock, connectors: bonds,\n"
      "     shape: {particles: {radius: 0.05, positions: [" + test::positionList(column) + "]}}}\n"
      "glue:\n  - {name: loaded_beam, bodies: [beam, load], material: rock, reach: 1.1}\n");
}

TEST(Bonds, ThreePointBeamBreaksAtMidSpanWhereTheMomentReachesTheBendingStrength) {
  // each support carries half the weight; the moment at mid-span is that reaction's about the middle
  // particle less the weights of the half-beam's particles about it
  const double weight = 11 * kMass * kG + 3 * 1.0 * kG;
  double moment = 0.5 * weight * 0.5;
  for (int i = 0; i < 5; ++i) moment -= kMass * kG * (0.5 - 0.1 * i);
  const double stress = moment * kBendingPerMoment;
  {
    World w = threePoint(1.03 * stress);
    EXPECT_EQ(firstBreak(w, 240).first, 0);
  }
  World w = threePoint(0.97 * stress);
  const auto [step, events] = firstBreak(w, 240);
  ASSERT_GT(step, 0);
  // the beam's particles are 2..12 (after the two supports); its middle one is 7
  for (const BreakEvent& e : events) {
    EXPECT_TRUE(e.a.value == 7u || e.b.value == 7u) << e.a.value << "-" << e.b.value;
    EXPECT_EQ(e.mode, BreakMode::Tension);
    EXPECT_NEAR(e.value, stress, 0.03 * stress);
  }
}

/// A 10 x 5 x 5 block of bonded particles whose bonds' strengths are drawn with Weibull modulus 5 and `seed`.
World weibullBlock(int seed) {
  return test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nseed: " + std::to_string(seed) + "\n"
      "materials:\n  rock: {youngs_modulus: 1.0e9, tensile_strength: 1.0e6, shear_strength: 3.0e6, weibull_modulus: 5}\n"
      "bodies:\n  - {name: block, shape: {box: {size: [1.0, 0.5, 0.5]}}, fill: {radius: 0.05}, material: rock, connectors: bonds}\n");
}

TEST(Bonds, WeibullStrengthsFollowTheDistributionAndTheSeed) {
  const World w = weibullBlock(7);
  const ConnectorStore& c = w.connectors();
  std::vector<double> s = c.tensileStrength;
  ASSERT_GT(s.size(), 1500u);
  for (std::size_t k = 0; k < s.size(); ++k) EXPECT_DOUBLE_EQ(c.shearStrength[k] / s[k], 3.0);  // one draw per bond
  std::sort(s.begin(), s.end());
  // Kolmogorov-Smirnov against F(s) = 1 - exp(-(s / 1e6)^5): the 1 % critical distance is 1.63 / sqrt(n)
  double ks = 0.0;
  const double n = static_cast<double>(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double f = 1.0 - std::exp(-std::pow(s[i] / 1.0e6, 5.0));
    ks = std::max({ks, std::abs(f - static_cast<double>(i) / n), std::abs(f - static_cast<double>(i + 1) / n)});
  }
  EXPECT_LT(ks, 1.63 / std::sqrt(n));
  double mean = 0.0;
  for (const double v : s) mean += v / n;
  EXPECT_NEAR(mean, 1.0e6 * std::tgamma(1.0 + 1.0 / 5.0), 0.02e6);
  // the same seed draws the same strengths, another seed others
  EXPECT_EQ(weibullBlock(7).connectors().tensileStrength, c.tensileStrength);
  const std::vector<double> other = weibullBlock(8).connectors().tensileStrength;
  std::size_t same = 0;
  for (std::size_t k = 0; k < other.size(); ++k) same += other[k] == c.tensileStrength[k];
  EXPECT_LT(same, other.size() / 100);
}

TEST(Bonds, GluedBodiesBecomeOneBodyWithTheMassPropertiesOfTheWhole) {
  // two 0.2 m cubes (2 x 2 x 2 particles) face to face glued: one 0.4 x 0.2 x 0.2 m box
  const World w = test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\n"
      "materials:\n  brick: {density: 2000, youngs_modulus: 1.0e9}\n  mortar: {youngs_modulus: 1.0e8, tensile_strength: 1.0e5}\n"
      "bodies:\n"
      "  - {name: a, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: brick, connectors: bonds,\n"
      "     position: [-0.1, 0, 0], velocity: [1, 0, 0]}\n"
      "  - {name: b, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: brick, connectors: bonds,\n"
      "     position: [0.1, 0, 0], velocity: [0, 1, 0]}\n"
      "glue:\n  - {name: pair, bodies: [a, b], material: mortar}\n");
  ASSERT_EQ(w.bodies().size(), 3u);
  const BodyInfo& info = w.bodies().info[2];
  EXPECT_TRUE(info.alive);
  EXPECT_EQ(info.particles.size(), 16u);
  const double mass = 2000.0 * 0.4 * 0.2 * 0.2;
  EXPECT_NEAR(info.mass, mass, 1e-9 * mass);
  // principal moments of the solid box: m (b^2 + c^2) / 12
  std::vector<double> moments{info.inertiaLocal.x(), info.inertiaLocal.y(), info.inertiaLocal.z()};
  std::sort(moments.begin(), moments.end());
  EXPECT_NEAR(moments[0], mass * (0.04 + 0.04) / 12.0, 1e-9);
  EXPECT_NEAR(moments[1], mass * (0.16 + 0.04) / 12.0, 1e-9);
  EXPECT_NEAR(moments[2], mass * (0.16 + 0.04) / 12.0, 1e-9);
  // momentum kept: (m/2) (1, 0, 0) + (m/2) (0, 1, 0)
  EXPECT_LT((w.bodies().state[2].linearVelocity - Vec3(0.5, 0.5, 0.0)).norm(), 1e-12);
  // glue bonds across the touching faces: four face to face, eight diagonal (1.41 < 1.5 spacings)
  std::size_t glue = 0;
  for (std::size_t k = 0; k < w.connectors().size(); ++k)
    if (w.connectors().youngsModulus[k] == 1.0e8) {
      ++glue;
      EXPECT_EQ(w.connectors().tensileStrength[k], 1.0e5);
      EXPECT_NE(w.particles().local[w.connectors().a[k].index()].x() > 0.0,
                w.particles().local[w.connectors().b[k].index()].x() > 0.0);
    }
  EXPECT_EQ(glue, 12u);
}

TEST(Bonds, GlueRefusesBodiesThatDoNotTouchAndBodiesWithoutBonds) {
  const std::string head =
      "dt: 0.01\nsteps: 1\nmaterials:\n  brick: {youngs_modulus: 1.0e9}\nbodies:\n"
      "  - {name: a, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: brick, connectors: bonds}\n";
  auto far = test::sceneFromString(head +
      "  - {name: b, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: brick, connectors: bonds,"
      " position: [0.5, 0, 0]}\nglue:\n  - {bodies: [a, b], material: brick}\n");
  ASSERT_TRUE(far);
  const auto farBuilt = buildScene(*far);
  ASSERT_FALSE(farBuilt);
  EXPECT_NE(farBuilt.error().message.find("'b' does not touch the others"), std::string::npos) << farBuilt.error().message;
  EXPECT_EQ(farBuilt.error().line, 9);
  auto rods = test::sceneFromString(head +
      "  - {name: b, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: brick, position: [0.2, 0, 0]}\n"
      "glue:\n  - {bodies: [a, b], material: brick}\n");
  ASSERT_TRUE(rods);
  const auto rodsBuilt = buildScene(*rods);
  ASSERT_FALSE(rodsBuilt);
  EXPECT_NE(rodsBuilt.error().message.find("joined by rods"), std::string::npos) << rodsBuilt.error().message;
  auto noModulus = test::sceneFromString(
      "dt: 0.01\nsteps: 1\nbodies:\n  - {name: a, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, connectors: bonds}\n");
  ASSERT_TRUE(noModulus);
  const auto noModulusBuilt = buildScene(*noModulus);
  ASSERT_FALSE(noModulusBuilt);
  EXPECT_NE(noModulusBuilt.error().message.find("youngs_modulus"), std::string::npos) << noModulusBuilt.error().message;
}

/// The brick-wall example with its seed replaced by `seed`.
World brickWall(int seed) {
  std::ifstream in(test::sourcePath("scenes/examples/brick_wall.yaml"));
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::size_t at = text.find("\nseed: 1\n");
  EXPECT_NE(at, std::string::npos);
  text.replace(at, 9, "\nseed: " + std::to_string(seed) + "\n");
  return test::worldFromString(text, "examples/brick_wall.yaml");
}

TEST(Bonds, BrickWallBreaksAlongItsMortarIntoBricks) {
  World w = brickWall(1);
  // the glued wall: bricks of 2 x 4 x 2 particles
  BodyId wall;
  for (std::size_t i = 0; i < w.bodies().size(); ++i)
    if (w.bodies().info[i].name == "wall") wall = BodyId(i);
  ASSERT_TRUE(wall.valid());
  const std::vector<ParticleId> wallParticles = w.bodies().info[wall.index()].particles;
  constexpr std::size_t kBrick = 16;
  ASSERT_EQ(wallParticles.size(), 33 * kBrick);
  for (int i = 0; i < 750; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);  // the scene's 1.5 s
  EXPECT_FALSE(w.bodies().info[wall.index()].alive);
  // at least 80 % of the wall's mass ends in pieces of at least a brick's particle count
  double mass = 0.0, inBricks = 0.0;
  std::size_t pieces = 0;
  for (const ParticleId p : wallParticles) {
    const BodyInfo& piece = w.bodies().info[w.particles().body[p.index()].index()];
    mass += w.particles().mass[p.index()];
    if (piece.particles.size() >= kBrick) inBricks += w.particles().mass[p.index()];
  }
  for (const BodyInfo& info : w.bodies().info) pieces += info.alive && info.breakable ? 1 : 0;
  std::printf("brick wall: %zu pieces, %.1f %% of its mass in pieces of a brick or more\n", pieces, 100.0 * inBricks / mass);
  EXPECT_GE(inBricks, 0.8 * mass);
  EXPECT_GE(pieces, 10u);  // it broke
}

TEST(Bonds, BrickWallRunsTheSameWithTheSameSeedAndDifferentlyWithAnother) {
  World a = brickWall(1), b = brickWall(1), c = brickWall(2);
  for (int i = 0; i < 120; ++i) {  // the ball strikes at ~0.09 s (step 45)
    ASSERT_EQ(a.step(), StepStatus::Ok);
    ASSERT_EQ(b.step(), StepStatus::Ok);
    ASSERT_EQ(c.step(), StepStatus::Ok);
  }
  EXPECT_TRUE(a.particles().position == b.particles().position);
  EXPECT_EQ(a.bodies().size(), b.bodies().size());
  EXPECT_FALSE(a.particles().position == c.particles().position);
}

/// A bonded block of rock, 0.6 m a side, filled at 0.05 m (216 particles).
World bondedBlock() {
  return test::worldFromString("dt: 0.004\nsteps: 1\nmaterials:\n  rock: {youngs_modulus: 1.0e9}\n"
                               "bodies:\n  - name: block\n    shape: {box: {size: [0.6, 0.6, 0.6]}}\n"
                               "    fill: {radius: 0.05}\n    connectors: bonds\n    material: rock\n");
}

// A bonded body's frame changes in place while bonds come out (its multigrid hierarchy with it), and each
// solve starts from the displacements of the last. A checkpoint keeps the frame's history and its
// displacements instead of the matrices: replayed, it must solve bit for bit as the frame it replays.
TEST(Bonds, AFrameReplayedFromItsHistorySolvesBitForBitAsTheFrameItReplays) {
  World w = bondedBlock();
  const BodyInfo& info = w.bodies().info[0];
  const BodyState& state = w.bodies().state[0];
  const std::span<const ConnectorId> ids = w.bodyConnectors(BodyId(0u));
  const std::vector<ConnectorId> bonds(ids.begin(), ids.end());
  ASSERT_GT(bonds.size(), 200u);
  std::vector<Vec3> loads(w.particles().size());
  for (std::size_t i = 0; i < loads.size(); ++i) {
    const double x = static_cast<double>(i);
    loads[i] = Vec3(std::sin(x), std::cos(2.0 * x), 0.3 * std::sin(3.0 * x));
  }
  BondLoads live;
  ASSERT_TRUE(live.build(info, w.particles(), w.connectors(), bonds));
  std::vector<BondLoad> out;
  // bonds out a few at a time, solving in between under loads that change a little
  std::size_t next = 0;
  for (int round = 0; round < 40; ++round) {
    std::vector<std::size_t> entries;
    for (int k = 0; k < 4; ++k, next = (next + 37) % bonds.size()) entries.push_back(next);
    live.remove(entries);
    for (Vec3& l : loads) l *= 1.01;
    live.solve(state, info, w.particles(), loads, out);
  }
  BondLoads replayed;
  ASSERT_TRUE(replayed.replay(info, w.connectors(), live.nodes(), live.nodePositions(), live.axes(), bonds, live.removed(), live.displacements()));
  for (Vec3& l : loads) l = Vec3(l.y(), -l.x(), l.z());
  std::vector<BondLoad> a, b;
  live.solve(state, info, w.particles(), loads, a);
  replayed.solve(state, info, w.particles(), loads, b);
  ASSERT_GT(live.iterations(), 0);
  ASSERT_EQ(live.iterations(), replayed.iterations());
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_EQ(test::exactNumber(a[k].axial), test::exactNumber(b[k].axial)) << "bond " << k;
    ASSERT_EQ(test::exactNumber(a[k].shear), test::exactNumber(b[k].shear)) << "bond " << k;
    ASSERT_EQ(test::exactNumber(a[k].bending), test::exactNumber(b[k].bending)) << "bond " << k;
    ASSERT_EQ(test::exactNumber(a[k].torsion), test::exactNumber(b[k].torsion)) << "bond " << k;
  }
  // without the displacements it started from, the same frame takes another path to the loads
  BondLoads cold;
  ASSERT_TRUE(cold.replay(info, w.connectors(), live.nodes(), live.nodePositions(), live.axes(), bonds, live.removed(),
                          std::vector<double>(live.displacements().size(), 0.0)));
  std::vector<BondLoad> c;
  cold.solve(state, info, w.particles(), loads, c);
  bool differs = false;
  for (std::size_t k = 0; k < a.size(); ++k) differs = differs || a[k].axial != c[k].axial;
  EXPECT_TRUE(differs);
  // a history that does not fit the frame is refused
  const std::vector<std::uint32_t> outOfRange{static_cast<std::uint32_t>(bonds.size())};
  const std::vector<double> fits(live.displacements().size(), 0.0);
  EXPECT_FALSE(BondLoads().replay(info, w.connectors(), live.nodes(), live.nodePositions(), live.axes(), bonds, outOfRange, fits));
  const std::vector<std::uint32_t> twice{3, 3};
  EXPECT_FALSE(BondLoads().replay(info, w.connectors(), live.nodes(), live.nodePositions(), live.axes(), bonds, twice, fits));
  const std::vector<double> tooFew(fits.size() - 6, 0.0);
  EXPECT_FALSE(BondLoads().replay(info, w.connectors(), live.nodes(), live.nodePositions(), live.axes(), bonds, {}, tooFew));
}

// A split's largest piece keeps its parent's frame: the other pieces' bonds leave it, their nodes rest, and
// the loads come into the frame's axes from the piece's (turned from the parent's). Its bonds' loads must be
// those of a frame built for the piece alone, to the solver's agreement (each within 1e-3 of the largest).
TEST(Bonds, AFrameKeptForTheLargestPieceGivesTheLoadsOfAFrameBuiltForIt) {
  World w = bondedBlock();
  const BodyInfo& info = w.bodies().info[0];
  const BodyState& state = w.bodies().state[0];
  const ConnectorStore& con = w.connectors();
  const std::span<const ConnectorId> ids = w.bodyConnectors(BodyId(0u));
  const std::vector<ConnectorId> bonds(ids.begin(), ids.end());
  // the piece: the particles on one side of a plane across the block (about two thirds of them)
  const ParticleStore& p = w.particles();
  std::vector<std::uint8_t> inPiece(p.size(), 0);
  BodyInfo piece = info;
  piece.particles.clear();
  std::vector<std::uint32_t> parentIndex;
  for (std::size_t i = 0; i < info.particles.size(); ++i)
    if (p.local[info.particles[i].index()].x() < 0.1) {
      inPiece[info.particles[i].index()] = 1;
      piece.particles.push_back(info.particles[i]);
      parentIndex.push_back(static_cast<std::uint32_t>(i));
    }
  ASSERT_GT(2 * piece.particles.size(), info.particles.size());
  ASSERT_LT(piece.particles.size(), info.particles.size());
  std::vector<std::size_t> crossing;
  std::vector<ConnectorId> pieceBonds;
  std::vector<std::size_t> pieceEntry;  // each of the piece's bonds' entry in the parent's frame
  for (std::size_t k = 0; k < bonds.size(); ++k) {
    const bool a = inPiece[con.a[bonds[k].index()].index()] != 0, b = inPiece[con.b[bonds[k].index()].index()] != 0;
    if (a != b) crossing.push_back(k);
    if (a && b) {
      pieceBonds.push_back(bonds[k]);
      pieceEntry.push_back(k);
    }
  }
  // the piece's own axes: the parent's turned by `turn`; its particles' local positions with them
  const Mat3 turn = Eigen::AngleAxisd(0.7, Vec3(1.0, 2.0, -0.5).normalized()).toRotationMatrix();
  ParticleStore turned = p;
  for (const ParticleId q : piece.particles) turned.local[q.index()] = turn * p.local[q.index()];
  BodyState pieceState = state;
  pieceState.orientation = Quat(state.orientation.toRotationMatrix() * turn.transpose());
  // self-equilibrated loads on the piece: opposite forces along its bonds
  std::vector<Vec3> loads(p.size(), Vec3::Zero());
  for (std::size_t k = 0; k < pieceBonds.size(); ++k) {
    const std::size_t c = pieceBonds[k].index();
    const Vec3 d = (p.position[con.b[c].index()] - p.position[con.a[c].index()]).normalized();
    const double f = 100.0 * std::sin(1.7 * static_cast<double>(k));
    loads[con.a[c].index()] -= f * d;
    loads[con.b[c].index()] += f * d;
  }
  BondLoads kept;
  ASSERT_TRUE(kept.build(info, p, con, bonds));
  std::vector<BondLoad> before;
  kept.solve(state, info, p, loads, before);  // (displacements to start from, as a parent's)
  kept.remove(crossing);
  kept.keepFor(parentIndex, turn);
  EXPECT_EQ(kept.nodes().size(), info.particles.size());
  BondLoads fresh;
  ASSERT_TRUE(fresh.build(piece, turned, con, pieceBonds));
  std::vector<BondLoad> a, b;
  kept.solve(pieceState, piece, turned, loads, a);
  fresh.solve(pieceState, piece, turned, loads, b);
  double largest = 0.0;
  for (const BondLoad& l : b) largest = std::max(largest, std::abs(l.axial));
  ASSERT_GT(largest, 1.0);
  for (std::size_t k = 0; k < pieceBonds.size(); ++k) {
    EXPECT_NEAR(a[pieceEntry[k]].axial, b[k].axial, 2e-3 * largest) << "bond " << k;
    EXPECT_NEAR(a[pieceEntry[k]].shear, b[k].shear, 2e-3 * largest) << "bond " << k;
  }
  // the bonds that left carry nothing
  for (std::size_t k = 0; k < bonds.size(); ++k)
    if (!inPiece[con.a[bonds[k].index()].index()] || !inPiece[con.b[bonds[k].index()].index()]) {
      EXPECT_EQ(a[k].axial, 0.0) << "bond " << k;
    }
  // a piece whose particles are not all nodes of a checkpoint's frame is refused
  std::vector<std::uint32_t> fewer(kept.nodes().begin(), kept.nodes().end() - 1);
  std::vector<Vec3> fewerAt(kept.nodePositions().begin(), kept.nodePositions().end() - 1);
  EXPECT_FALSE(BondLoads().replay(info, con, fewer, fewerAt, Mat3::Identity(), bonds, {},
                                  std::vector<double>(6 * fewer.size(), 0.0)));
}

}  // namespace
}  // namespace volpar
