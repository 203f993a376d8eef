// The faces a fracture opens: the particles of a clean cut through a block get the cut's normal, whether it
// runs along the lattice or across it, on cubic and HCP lattices; and over a fracture scene's whole run the
// normal cache stays within a small multiple of the particle count (the entries of particles that stop being
// surface are recycled), while every particle a break exposed keeps a normal.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "volpar/collision/normal_estimation.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

enum class Grid { Cubic, Hcp };

/// About n x n x n particles of radius r in a lattice.
std::vector<Vec3> block(Grid grid, double r, int n = 10) {
  std::vector<Vec3> xs;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        if (grid == Grid::Cubic) {
          xs.emplace_back(2.0 * r * i, 2.0 * r * j, 2.0 * r * k);
        } else {  // hexagonal close packing: ABAB layers
          const double x = r * (2.0 * i + ((j + k) % 2));
          const double y = r * std::sqrt(3.0) * (j + (k % 2) / 3.0);
          const double z = r * 2.0 * std::sqrt(6.0) / 3.0 * k;
          xs.emplace_back(x, y, z);
        }
      }
  return xs;
}

struct Cut {
  const char* name;
  Grid grid;
  Vec3 normal;  // unit
};

class CleanCut : public ::testing::TestWithParam<Cut> {};

TEST_P(CleanCut, CrackParticlesGetTheCutsNormal) {
  const Cut& cut = GetParam();
  const double r = 0.05;
  const std::vector<Vec3> xs = block(cut.grid, r);
  Vec3 centre = Vec3::Zero();
  for (const Vec3& x : xs) centre += x / static_cast<double>(xs.size());
  // the cut through the middle, shifted off any lattice plane so no centre lies on it
  const double offset = cut.normal.dot(centre) + 0.123 * r;
  const double reach = cut.grid == Grid::Cubic ? 1.5 * 2.0 * r : 1.1 * 2.0 * r;
  std::string pairs;
  std::vector<std::pair<std::size_t, std::size_t>> crossing;
  std::vector<std::size_t> face;
  for (std::size_t a = 0; a < xs.size(); ++a)
    for (std::size_t b = a + 1; b < xs.size(); ++b)
      if ((xs[a] - xs[b]).norm() < reach) {
        pairs += (pairs.empty() ? "[" : ", [") + std::to_string(a) + ", " + std::to_string(b) + "]";
        if ((cut.normal.dot(xs[a]) > offset) != (cut.normal.dot(xs[b]) > offset)) {
          crossing.emplace_back(a, b);
          // the crack's faces: the particles that lose a nearest neighbour (on a cubic lattice, not those that
          // only lose a diagonal: they lie in the grooves behind a stepped face)
          if ((xs[a] - xs[b]).norm() < 1.01 * 2.0 * r) face.insert(face.end(), {a, b});
        }
      }
  ASSERT_GT(crossing.size(), 50u);
  World w = test::worldFromString("dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\nbodies:\n"
                                  "  - kind: deformable\n    particle_mass: 0.1\n"
                                  "    connectors: {springs: {stiffness: 200, strain_limit: 0.05}}\n"
                                  "    shape:\n      particles: {radius: " + test::exactNumber(r) + ", positions: [" + test::positionList(xs) +
                                  "], connectors: [" + pairs + "]}\n");
  ASSERT_EQ(w.particles().size(), xs.size());
  // one half moved half a spacing away along the cut's normal before the first step: a spring across the cut
  // (from one half to the other, direction d with d . n > 0) is then stretched by at least sqrt(1.25) - 1 =
  // 12 %, and breaks; the springs within either half keep their length
  for (std::size_t i = 0; i < xs.size(); ++i)
    if (cut.normal.dot(xs[i]) > offset) w.editParticles().position[i] += r * cut.normal;
  // (one step: the springs' pull before they broke sets the crack faces moving towards each other, and the
  // layers behind them would break in the steps after)
  ASSERT_EQ(w.step(), StepStatus::Ok);
  const std::size_t broken = w.breakEvents().size();
  ASSERT_EQ(broken, crossing.size());  // a clean cut: every spring across it, and no other
  // each particle of a crack face faces the other half: its normal, or on an edge one of its faces, within
  // 10 degrees of the cut's (p95), inside the block and where the crack meets the block's own faces (its
  // rim: particles that were on the block's surface before the cut, now on an edge or a corner of the crack
  // face and the block's faces)
  std::vector<std::size_t> neighbours(xs.size(), 0);
  for (std::size_t a = 0; a < xs.size(); ++a)
    for (std::size_t b = 0; b < xs.size(); ++b)
      if (a != b && (xs[a] - xs[b]).norm() < reach) ++neighbours[a];
  const std::size_t full = *std::max_element(neighbours.begin(), neighbours.end());
  std::vector<std::uint8_t> onCrack(xs.size(), 0);
  for (const std::size_t i : face) onCrack[i] = 1;
  std::vector<double> inner, rim;
  std::size_t without = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    if (!onCrack[i]) continue;
    const Vec3 expected = cut.normal.dot(xs[i]) > offset ? Vec3(-cut.normal) : cut.normal;
    const std::int32_t k = w.particles().normalIndex[i];
    if (k < 0) {
      ++without;
      continue;
    }
    const BodyState& s = w.bodies().state[w.particles().body[i].index()];
    double best = std::acos(std::clamp(w.particleNormal(ParticleId(static_cast<std::uint32_t>(i))).dot(expected), -1.0, 1.0));
    for (const Vec3& f : w.normals().faces(k))
      best = std::min(best, std::acos(std::clamp((s.orientation * f).dot(expected), -1.0, 1.0)));
    (neighbours[i] == full ? inner : rim).push_back(best * 180.0 / M_PI);
  }
  EXPECT_EQ(without, 0u);  // no crack particle left without a normal
  ASSERT_GT(inner.size(), 30u);
  ASSERT_FALSE(rim.empty());
  const double p95 = test::percentile(inner, 0.95);
  std::printf("%s: %zu crack particles inside the block, median %.2f p95 %.2f max %.2f deg; %zu on its rim, median "
              "%.2f p95 %.2f deg\n",
              cut.name, inner.size(), test::percentile(inner, 0.5), p95, *std::max_element(inner.begin(), inner.end()),
              rim.size(), test::percentile(rim, 0.5), test::percentile(rim, 0.95));
  EXPECT_LE(p95, 10.0);
  EXPECT_LE(test::percentile(rim, 0.95), 10.0);
}

/// The same cuts through a rigid block of bonds: its two halves (each an explicit particle list of
/// unbreakable bonds) glued along the cut by glue that breaks at once, spun about an axis in the cut so that
/// the glue is in tension. The block splits along the cut into two rigid fragments, whose crack faces must
/// face each other as a deformable block's do.
class GluedCut : public ::testing::TestWithParam<Cut> {};

TEST_P(GluedCut, FragmentsCrackParticlesGetTheCutsNormal) {
  const Cut& cut = GetParam();
  const double r = 0.05;
  const std::vector<Vec3> xs = block(cut.grid, r, 7);  // (a frame of 343 particles, factorised in each pass)
  Vec3 centre = Vec3::Zero();
  for (const Vec3& x : xs) centre += x / static_cast<double>(xs.size());
  const double offset = cut.normal.dot(centre) + 0.123 * r;
  const double reach = cut.grid == Grid::Cubic ? 1.5 : 1.1;  // x the spacing 2r
  std::vector<Vec3> lower, upper;
  std::vector<std::size_t> index;  // block index -> particle index in the world (lower half first)
  for (const Vec3& x : xs) (cut.normal.dot(x) > offset ? upper : lower).push_back(x);
  // the crack's faces: particles with a nearest neighbour across the cut
  std::vector<std::uint8_t> face(xs.size(), 0);
  for (std::size_t a = 0; a < xs.size(); ++a)
    for (std::size_t b = 0; b < xs.size(); ++b)
      if ((xs[a] - xs[b]).norm() < 1.01 * 2.0 * r && (cut.normal.dot(xs[a]) > offset) != (cut.normal.dot(xs[b]) > offset)) face[a] = 1;
  const Vec3 axis = cut.normal.unitOrthogonal();
  const std::string list = "    connectors: bonds\n    material: rock\n    particle_mass: 0.1\n";
  World w = test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\n"
      "materials:\n  rock: {youngs_modulus: 1.0e9}\n  glue: {youngs_modulus: 1.0e9, tensile_strength: 1.0, shear_strength: 1.0}\n"
      "bodies:\n"
      "  - name: lower\n" + list + "    shape: {particles: {radius: 0.05, reach: " + test::exactNumber(reach * 2.0 * r) +
      ", positions: [" + test::positionList(lower) + "]}}\n"
      "  - name: upper\n" + list + "    shape: {particles: {radius: 0.05, reach: " + test::exactNumber(reach * 2.0 * r) +
      ", positions: [" + test::positionList(upper) + "]}}\n"
      "glue:\n  - {name: block, bodies: [lower, upper], material: glue, reach: " + test::exactNumber(reach) + "}\n");
  ASSERT_EQ(w.bodies().size(), 3u);
  const BodyId glued(std::uint32_t{2});
  w.bodyState(glued).angularVelocity = 2.0 * axis;
  w.syncParticles();
  ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_FALSE(w.breakEvents().empty());
  EXPECT_FALSE(w.bodies().info[glued.index()].alive);
  ASSERT_EQ(w.bodies().size(), 5u);  // split in two along the cut, no more
  std::vector<double> angles;
  std::size_t without = 0;
  std::size_t l = 0, u = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const bool above = cut.normal.dot(xs[i]) > offset;
    const std::size_t p = above ? lower.size() + u++ : l++;  // (each half's particles in the block's order)
    if (!face[i]) continue;
    const std::int32_t k = w.particles().normalIndex[p];
    if (k < 0) {
      ++without;
      continue;
    }
    // the cut's normal, turned with the fragment since the start
    const BodyState& s = w.bodies().state[w.particles().body[p].index()];
    const BodyInfo& info = w.bodies().info[w.particles().body[p].index()];
    const Quat turned = s.orientation * info.principalInShape.conjugate();
    const Vec3 expected = turned * (above ? Vec3(-cut.normal) : cut.normal);
    double best = std::acos(std::clamp(w.particleNormal(ParticleId(static_cast<std::uint32_t>(p))).dot(expected), -1.0, 1.0));
    for (const Vec3& f : w.normals().faces(k)) best = std::min(best, std::acos(std::clamp((s.orientation * f).dot(expected), -1.0, 1.0)));
    angles.push_back(best * 180.0 / M_PI);
  }
  EXPECT_EQ(without, 0u);
  ASSERT_GT(angles.size(), 50u);
  std::printf("%s, glued and broken: %zu crack particles, median %.2f p95 %.2f deg\n", cut.name, angles.size(),
              test::percentile(angles, 0.5), test::percentile(angles, 0.95));
  EXPECT_LE(test::percentile(angles, 0.95), 10.0);
}

const Cut kCuts[] = {
    {"cubic_along", Grid::Cubic, Vec3(1, 0, 0)},
    {"cubic_diagonal", Grid::Cubic, Vec3(1, 1, 0).normalized()},
    {"cubic_oblique", Grid::Cubic, Vec3(1, 2, 3).normalized()},
    {"hcp_along", Grid::Hcp, Vec3(0, 0, 1)},
    {"hcp_across", Grid::Hcp, Vec3(1, 0, 0)},
    {"hcp_oblique", Grid::Hcp, Vec3(2, -1, 1).normalized()},
};

TEST(Fracture, NormalCacheStaysBoundedOverTheWallBreakRun) {
  std::ifstream in(test::sourcePath("scenes/examples/wall_break.yaml"));
  World w = test::worldFromString(std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()),
                                  "wall_break.yaml");
  const std::size_t particles = w.particles().size();
  std::size_t breaks = 0, largest = 0;
  for (int i = 0; i < 480; ++i) {  // the scene's 2 s
    ASSERT_EQ(w.step(), StepStatus::Ok);
    breaks += w.breakEvents().size();
    largest = std::max(largest, w.normals().size());
    EXPECT_LE(w.normals().used(), particles);
    // a particle a break exposed is on a surface now, with a normal
    for (const BreakEvent& e : w.breakEvents()) {
      EXPECT_GE(w.particles().normalIndex[e.a.index()], 0);
      EXPECT_GE(w.particles().normalIndex[e.b.index()], 0);
    }
  }
  std::printf("wall_break: %zu particles, %zu breaks, largest normal cache %zu entries\n", particles, breaks, largest);
  EXPECT_GT(breaks, 100u);
  EXPECT_LE(largest, 2 * particles);
}

INSTANTIATE_TEST_SUITE_P(Fracture, CleanCut, ::testing::ValuesIn(kCuts),
                         [](const auto& param) { return std::string(param.param.name); });
INSTANTIATE_TEST_SUITE_P(Fracture, GluedCut, ::testing::ValuesIn(kCuts),
                         [](const auto& param) { return std::string(param.param.name); });

}  // namespace
}  // namespace volpar
