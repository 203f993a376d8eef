// Breakage: rods that break above their strength, rigid bodies splitting into new bodies with their own mass
// properties and inherited motion, and the bounded normal-cache recomputation that follows a break.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <string>

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

/// Ten 0.1 kg particles in a row along x (spacing 0.1 m, radius 0.05 m) joined by rods of `strength`,
/// spinning at 10 rad/s about z without gravity. The middle rod carries the centripetal force of the five
/// particles beyond it: 0.1 kg * 100 s^-2 * (0.05 + 0.15 + 0.25 + 0.35 + 0.45) m = 12.5 N.
World spinningChain(double strength) {
  std::vector<Vec3> xs;
  for (int i = 0; i < 10; ++i) xs.emplace_back(-0.45 + 0.1 * i, 0.0, 0.0);
  return test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nbodies:\n"
                               "  - name: chain\n    particle_mass: 0.1\n    connectors: {rods: {strength: " +
                               test::exactNumber(strength) + "}}\n    velocity: [0.3, -0.2, 0.1]\n    angular_velocity: [0, 0, 10]\n"
                               "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) + "]}\n");
}

constexpr double kMiddleTension = 12.5;

World sceneFile(const std::string& relative) {
  std::ifstream in(test::sourcePath(relative));
  return test::worldFromString(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()),
                               relative.substr(relative.find('/') + 1));
}

/// Runs `steps` steps; returns the first step with a break (0 if none).
std::int64_t firstBreak(World& w, int steps) {
  std::int64_t first = 0;
  for (int i = 0; i < steps; ++i) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    if (!first && !w.breakEvents().empty()) first = w.breakEvents()[0].step;
  }
  return first;
}

/// Ten 0.1 kg particles stacked in a column on the floor (spacing 0.1 m, radius 0.05 m), one rigid body
/// whose rods are given `rods` (a connectors map): its bottom rod carries the weight of the nine particles
/// above, 8.829 N, in compression. Returns whether any rod broke within 0.5 s.
bool columnBreaks(const std::string& rods) {
  std::vector<Vec3> xs;
  for (int i = 0; i < 10; ++i) xs.emplace_back(0.0, 0.0, 0.05 + 0.1 * i);
  World w = test::worldFromString("dt: 0.004166666666666667\nsteps: 1\nplanes:\n  - {normal: [0, 0, 1], offset: 0}\n"
                                  "bodies:\n  - name: column\n    particle_mass: 0.1\n    connectors: {rods: " + rods +
                                  "}\n    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) + "]}\n");
  return firstBreak(w, 120) != 0;
}

TEST(Breakage, RodsBreakInCompressionAtTheirCompressiveStrengthNotTheirTensile) {
  const double load = 9 * 0.1 * 9.81;
  // far weaker in tension than the load, but it is compression
  EXPECT_FALSE(columnBreaks("{strength: 1, compressive_strength: " + test::exactNumber(1.01 * load) + "}"));
  EXPECT_TRUE(columnBreaks("{strength: 1, compressive_strength: " + test::exactNumber(0.99 * load) + "}"));
  // given only a tensile strength, rods crush at ten times it
  EXPECT_FALSE(columnBreaks("{strength: " + test::exactNumber(0.101 * load) + "}"));
  EXPECT_TRUE(columnBreaks("{strength: " + test::exactNumber(0.099 * load) + "}"));
}

TEST(Breakage, SpinningChainHoldsBelowItsStrength) {
  World w = spinningChain(1.01 * kMiddleTension);
  ASSERT_EQ(w.connectors().size(), 9u);
  for (int i = 0; i < 480; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    ASSERT_TRUE(w.breakEvents().empty()) << "step " << i;
  }
  EXPECT_EQ(w.bodies().size(), 1u);
  EXPECT_TRUE(w.bodies().info[0].alive);
}

TEST(Breakage, SpinningChainSnapsInTheMiddleAboveItsStrength) {
  World w = spinningChain(0.99 * kMiddleTension);
  const Vec3 p0 = w.linearMomentum(), l0 = w.angularMomentum();
  const double e0 = w.energy().kinetic;
  ASSERT_EQ(w.step(), StepStatus::Ok);
  // exactly the middle rod, carrying the analytic tension
  ASSERT_EQ(w.breakEvents().size(), 1u);
  const BreakEvent& e = w.breakEvents()[0];
  EXPECT_NEAR(e.value, kMiddleTension, 1e-6 * kMiddleTension);
  EXPECT_EQ(std::min(e.a.value, e.b.value), 4u);
  EXPECT_EQ(std::max(e.a.value, e.b.value), 5u);
  EXPECT_EQ(w.stats().connectorsBroken, 1u);
  // the chain is retired and two new bodies of five particles each take its place
  ASSERT_EQ(w.bodies().size(), 3u);
  EXPECT_FALSE(w.bodies().info[0].alive);
  EXPECT_EQ(w.bodies().info[0].retiredStep, 1);
  for (std::size_t b = 1; b < 3; ++b) {
    const BodyInfo& info = w.bodies().info[b];
    EXPECT_TRUE(info.alive);
    EXPECT_EQ(info.parent, BodyId(0u));
    EXPECT_EQ(info.createdStep, 1);
    EXPECT_EQ(info.particles.size(), 5u);
    EXPECT_EQ(info.name, "chain/" + std::to_string(b));
  }
  // momentum and kinetic energy carried over exactly (no impulse acts at the break)
  const double tol = 1e-9;
  EXPECT_LT((w.linearMomentum() - p0).norm(), tol * p0.norm());
  EXPECT_LT((w.angularMomentum() - l0).norm(), tol * l0.norm());
  EXPECT_NEAR(w.energy().kinetic, e0, tol * e0);
  // each half flies on, spinning about its own centre; the halves part
  for (int i = 0; i < 120; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  EXPECT_EQ(w.bodies().size(), 3u);
  EXPECT_GT((w.bodies().state[1].position - w.bodies().state[2].position).norm(), 0.5 + 0.5 * 120 / 240.0);
  EXPECT_LT((w.linearMomentum() - p0).norm(), tol * p0.norm());
  EXPECT_LT((w.angularMomentum() - l0).norm(), tol * l0.norm());
}

TEST(Breakage, FragmentMassPropertiesEqualThoseOfABodyBuiltFromItsParticles) {
  World w = spinningChain(0.99 * kMiddleTension);
  ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_EQ(w.bodies().size(), 3u);
  for (std::size_t b = 1; b < 3; ++b) {
    const BodyInfo& info = w.bodies().info[b];
    const BodyState& s = w.bodies().state[b];
    std::vector<Vec3> xs;
    for (const ParticleId p : info.particles) xs.push_back(w.particles().position[p.index()]);
    World direct = test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nbodies:\n"
                                         "  - particle_mass: 0.1\n    connectors: {rods: {strength: 1000}}\n"
                                         "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) +
                                         "]}\n");
    const BodyInfo& ref = direct.bodies().info[0];
    const BodyState& rs = direct.bodies().state[0];
    EXPECT_NEAR(info.mass, ref.mass, 1e-12);
    EXPECT_NEAR(info.mass, 0.5, 1e-12);
    EXPECT_LT((s.position - rs.position).norm(), 1e-12);
    EXPECT_LT((info.inertiaLocal - ref.inertiaLocal).norm(), 1e-12 * ref.inertiaLocal.norm());
    // the same world inertia tensor (principal axes may differ in sign and order among equal moments)
    const Mat3 i1 = s.orientation.toRotationMatrix() * info.inertiaLocal.asDiagonal() * s.orientation.toRotationMatrix().transpose();
    const Mat3 i2 = rs.orientation.toRotationMatrix() * ref.inertiaLocal.asDiagonal() * rs.orientation.toRotationMatrix().transpose();
    EXPECT_LT((i1 - i2).norm(), 1e-12 * i2.norm());
    // particles sit where they were: body frame + pose reproduce the world positions
    for (const ParticleId p : info.particles)
      EXPECT_LT((s.position + s.orientation * w.particles().local[p.index()] - w.particles().position[p.index()]).norm(), 1e-12);
  }
}

TEST(Breakage, WallStandsUnderItsOwnWeightAndBreaksIntoPiecesNotSandWhenTheBallHits) {
  World w = sceneFile("scenes/examples/wall_break.yaml");
  const std::size_t wallParticles = w.bodies().info[0].particles.size();
  // the ball (0.15 m radius, from x = -1.5 m at 9 m/s) reaches the wall's face (x = -0.1 m) after ~0.14 s
  const std::int64_t first = firstBreak(w, 90);
  EXPECT_GE(first, 30);
  EXPECT_LE(first, 40);
  for (int i = 90; i < 480; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);  // the scene's 2 s
  EXPECT_FALSE(w.bodies().info[0].alive);
  // pieces, and few particles on their own: fewer than 10 % of the wall's end as single-particle bodies
  const FragmentHistogram fragments = w.fragments();
  EXPECT_GE(fragments.count, 4u);
  EXPECT_LT(static_cast<double>(fragments.singles), 0.1 * static_cast<double>(wallParticles));
  EXPECT_EQ(fragments.particles, wallParticles);
}

TEST(Breakage, EveryConnectorBreaksOnceWhateverPieceItsEndsEndIn) {
  // a bond that breaks in a pass that also splits its body leaves the frame of the piece that keeps it, so
  // no piece's frame carries load through it and breaks it again
  World w = sceneFile("scenes/examples/wall_break.yaml");
  std::vector<int> breaks(w.connectors().size(), 0);
  for (int i = 0; i < 480; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    for (const BreakEvent& e : w.breakEvents()) ++breaks[e.connector.index()];
  }
  std::size_t events = 0, broken = 0;
  for (std::size_t c = 0; c < breaks.size(); ++c) {
    EXPECT_LE(breaks[c], 1) << "connector " << c << " broke " << breaks[c] << " times";
    events += static_cast<std::size_t>(breaks[c]);
    broken += w.connectors().broken[c] ? 1 : 0;
  }
  EXPECT_GT(broken, 100u);
  EXPECT_EQ(events, broken);
}

TEST(Breakage, BeamHoldsItsOwnWeightAndSnapsUnderTheDroppedLoad) {
  World w = sceneFile("scenes/examples/beam_break.yaml");
  // the load falls 0.1 m onto the beam: ~0.14 s
  int i = 0;
  for (; i < 120 && w.breakEvents().empty(); ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_FALSE(w.breakEvents().empty());
  EXPECT_GE(w.breakEvents()[0].step, 30);
  EXPECT_LE(w.breakEvents()[0].step, 40);
  // three-point bending: it breaks under the block (0.3 m wide, at mid-span, where the moment peaks), not
  // towards the supports (at +-0.9 m)
  for (const BreakEvent& e : w.breakEvents()) {
    const double x = 0.5 * (w.particles().position[e.a.index()].x() + w.particles().position[e.b.index()].x());
    EXPECT_LE(std::abs(x), 0.35) << "a bond broke at x = " << x;
  }
  for (; i < 240; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  EXPECT_FALSE(w.bodies().info[2].alive);
  std::size_t fragments = 0;
  for (const BodyInfo& info : w.bodies().info) fragments += info.parent.valid() && info.alive ? 1 : 0;
  EXPECT_GE(fragments, 2u);
}

TEST(Breakage, CantileverBreaksAtItsRootUnderALoadNearItsEnd) {
  World w = sceneFile("scenes/examples/cantilever.yaml");
  int i = 0;
  for (; i < 200 && w.breakEvents().empty(); ++i) ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_FALSE(w.breakEvents().empty());
  // the block's face is at x = 0 and the beam reaches to x = 0.8 m: every bond that breaks first is at the
  // root (within two of the beam's 0.05 m spacings of the face)
  for (const BreakEvent& e : w.breakEvents()) {
    const double x = 0.5 * (w.particles().position[e.a.index()].x() + w.particles().position[e.b.index()].x());
    EXPECT_LE(x, 0.11) << "a bond broke at x = " << x;
  }
  std::printf("cantilever: %zu bonds broke at step %lld\n", w.breakEvents().size(), static_cast<long long>(w.breakEvents()[0].step));
}

TEST(Breakage, PlateStruckAtItsCentreCracksRadially) {
  World w = sceneFile("scenes/examples/plate_impact.yaml");
  BodyId plate;
  for (std::size_t i = 0; i < w.bodies().size(); ++i)
    if (w.bodies().info[i].name == "plate") plate = BodyId(i);
  ASSERT_TRUE(plate.valid());
  const std::vector<ParticleId> ids = w.bodies().info[plate.index()].particles;
  std::vector<Vec3> start;
  for (const ParticleId p : ids) start.push_back(w.particles().position[p.index()]);
  for (int i = 0; i < 400; ++i) ASSERT_EQ(w.step(), StepStatus::Ok);  // the scene's 0.4 s
  // the pieces (of at least 5 % of the plate), by where their particles were: each a sector about the centre,
  // spanning less than half a turn, and at least three of them (a ring crack would leave a piece all round)
  std::map<std::uint32_t, std::vector<double>> angles;
  std::map<std::uint32_t, std::size_t> sizes;
  for (std::size_t k = 0; k < ids.size(); ++k) {
    const std::uint32_t body = w.particles().body[ids[k].index()].value;
    ++sizes[body];
    if (std::hypot(start[k].x(), start[k].y()) > 0.1) angles[body].push_back(std::atan2(start[k].y(), start[k].x()));
  }
  std::size_t sectors = 0;
  for (auto& [body, a] : angles) {
    if (sizes[body] < ids.size() / 20) continue;
    std::sort(a.begin(), a.end());
    double gap = a.front() + 2.0 * std::numbers::pi - a.back();
    for (std::size_t k = 1; k < a.size(); ++k) gap = std::max(gap, a[k] - a[k - 1]);
    const double span = 2.0 * std::numbers::pi - gap;
    EXPECT_LT(span, std::numbers::pi) << "a piece of " << sizes[body] << " particles spans " << span * 180.0 / std::numbers::pi << " deg";
    ++sectors;
  }
  EXPECT_GE(sectors, 3u);
}

TEST(Breakage, RecomputedNormalsAfterOneBreakAreBoundedByItsNeighbourhood) {
  // a deformable block of 10 x 10 x 10 particles with one extra particle hanging off a corner by a single
  // spring; the extra particle is flung away and that spring, alone, breaks
  const double s = 0.1;
  std::vector<Vec3> xs;
  for (int k = 0; k < 10; ++k)
    for (int j = 0; j < 10; ++j)
      for (int i = 0; i < 10; ++i) xs.emplace_back(s * i, s * j, s * k);
  std::string pairs;
  for (std::size_t a = 0; a < xs.size(); ++a)
    for (std::size_t b = a + 1; b < xs.size(); ++b)
      if ((xs[a] - xs[b]).norm() < 1.5 * s) pairs += (pairs.empty() ? "[" : ", [") + std::to_string(a) + ", " + std::to_string(b) + "]";
  const std::size_t tab = xs.size();
  xs.emplace_back(-s, 0.0, 0.0);
  pairs += ", [0, " + std::to_string(tab) + "]";
  World w = test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nbodies:\n"
                                  "  - kind: deformable\n    particle_mass: 0.1\n"
                                  "    connectors: {springs: {stiffness: 20000, damping: 1, strain_limit: 0.1}}\n"
                                  "    shape:\n      particles: {radius: 0.05, positions: [" + test::positionList(xs) +
                                  "], connectors: [" + pairs + "]}\n");
  ASSERT_EQ(w.particles().size(), 1001u);
  std::size_t surface = 0;
  for (std::size_t i = 0; i < w.particles().size(); ++i) surface += w.particles().normalIndex[i] >= 0 ? 1 : 0;
  ASSERT_GT(surface, 400u);
  // at rest nothing is recomputed
  ASSERT_EQ(w.step(), StepStatus::Ok);
  EXPECT_EQ(w.stats().normalsRecomputed, 0u);
  EXPECT_TRUE(w.breakEvents().empty());
  w.editParticles().velocity[tab] = Vec3(-10, 0, 0);
  bool broke = false;
  for (int i = 0; i < 10 && !broke; ++i) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    if (w.breakEvents().empty()) continue;
    broke = true;
    ASSERT_EQ(w.breakEvents().size(), 1u);
    EXPECT_EQ(std::max(w.breakEvents()[0].a.value, w.breakEvents()[0].b.value), tab);
    // only particles near the break: the faces it opened within two connector rings of the corner, and the
    // region the pull bent, within three (less than 0.45 m away); never the body
    std::size_t near = 0;
    for (std::size_t p = 0; p < xs.size(); ++p) near += (w.particles().position[p] - w.particles().position[0]).norm() < 0.45 ? 1 : 0;
    EXPECT_GT(w.stats().normalsRecomputed, 0u);
    EXPECT_LE(w.stats().normalsRecomputed, near);
    EXPECT_LT(w.stats().normalsRecomputed, surface / 10);
  }
  EXPECT_TRUE(broke);
  // the corner's normal now also faces where the extra particle was
  EXPECT_LT(w.particleNormal(ParticleId(0u)).x(), -0.3);
}

}  // namespace
}  // namespace volpar
