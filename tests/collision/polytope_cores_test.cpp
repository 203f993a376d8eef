// Whole polytope cores (collision/polytope_cores.hpp): which bodies' particles fill a convex polytope exactly,
// and the plane of two such bodies' contacts against FCL's closest points between their cores.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "volpar/collision/polytope_cores.hpp"
#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "volpar/engine/world.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

ParticleCloud filled(const SolidShape& solid, double r, Lattice lattice = Lattice::Cubic, bool estimated = false) {
  auto c = fillShape(solid, {lattice, r});
  EXPECT_TRUE(c.ok());
  ParticleCloud cloud = c.ok() ? std::move(c.value()) : ParticleCloud{};
  if (estimated) useEstimatedNormals(cloud);
  return cloud;
}

ParticleCloud meshCloud(const std::string& file, double r) {
  auto m = readObj(test::sourcePath("scenes/examples/meshes/" + file));
  EXPECT_TRUE(m.ok() && m->makeSolid().ok());
  return filled(MeshShape(std::make_shared<const TriangleMesh>(m.value())), r);
}

/// A world of one body made from `cloud` (rigid unless said), and its core's vertices.
struct OneBody {
  World world{WorldSettings{}};
  BodyId id;
  explicit OneBody(const ParticleCloud& cloud, BodyKind kind = BodyKind::Rigid) {
    BodyDef d;
    d.name = "body";
    d.kind = kind;
    d.material = world.addMaterial(Material{"m"});
    id = world.addBody(d, cloud).value();
  }
  [[nodiscard]] std::span<const Vec3> core() const { return world.polytopeCores().vertices(id); }
};

TEST(PolytopeCores, ABoxLatticeHasTheBoxOfItsCornerCentres) {
  for (const bool estimated : {false, true}) {
    // 3 x 5 x 7 particles: the centres span 0.2 x 0.4 x 0.6 m about the centre of mass
    const OneBody b(filled(BoxShape(Vec3(0.3, 0.5, 0.7)), 0.05, Lattice::Cubic, estimated));
    const std::span<const Vec3> v = b.core();
    ASSERT_EQ(v.size(), 8u) << (estimated ? "estimated normals" : "the builder's normals");
    for (const Vec3& x : v) {
      EXPECT_NEAR(std::abs(x.x()), 0.1, 1e-12);
      EXPECT_NEAR(std::abs(x.y()), 0.2, 1e-12);
      EXPECT_NEAR(std::abs(x.z()), 0.3, 1e-12);
    }
    // every vertex is a particle centre
    for (const Vec3& x : v) {
      bool atCentre = false;
      for (const ParticleId q : b.world.bodies().info[b.id.index()].particles)
        atCentre = atCentre || (b.world.particles().local[q.index()] - x).norm() < 1e-12;
      EXPECT_TRUE(atCentre);
    }
  }
}

TEST(PolytopeCores, CurvedConcaveSteppedThinAndSoftBodiesHaveNone) {
  EXPECT_TRUE(OneBody(filled(SphereShape(0.25), 0.025)).core().empty()) << "sphere";
  EXPECT_TRUE(OneBody(filled(CylinderShape(0.15, 0.4), 0.025)).core().empty()) << "cylinder";
  EXPECT_TRUE(OneBody(filled(CapsuleShape(0.12, 0.3), 0.02)).core().empty()) << "capsule";
  EXPECT_TRUE(OneBody(meshCloud("l_shape.obj", 0.05)).core().empty()) << "L-shaped mesh";
  EXPECT_TRUE(OneBody(meshCloud("u_shape.obj", 0.05)).core().empty()) << "U-shaped mesh";
  // a box turned against the lattice: its faces step along the lattice, the hull of the centres is not the box
  const Quat turn = (Quat(Eigen::AngleAxisd(0.35, Vec3::UnitZ())) * Quat(Eigen::AngleAxisd(0.6, Vec3::UnitX()))).normalized();
  const auto mesh = test::turnedBoxMesh(turn, Vec3(0.2, 0.15, 0.125));
  ASSERT_TRUE(mesh->makeSolid().ok());
  EXPECT_TRUE(OneBody(filled(MeshShape(mesh), 0.025)).core().empty()) << "turned box";
  EXPECT_TRUE(OneBody(filled(BoxShape(Vec3(0.5, 0.4, 0.05)), 0.025)).core().empty()) << "plate one particle thick";
  EXPECT_TRUE(OneBody(filled(BoxShape(Vec3(0.3, 0.3, 0.3)), 0.05), BodyKind::Deformable).core().empty()) << "deformable";
  // a static box has one, as a rigid one does
  EXPECT_EQ(OneBody(filled(BoxShape(Vec3(0.3, 0.3, 0.3)), 0.05), BodyKind::Static).core().size(), 8u) << "static box";
}

TEST(PolytopeCores, AParticleOffItsFacesPlaneDisqualifies) {
  // the builder's box, with one face particle moved a tenth of a radius inwards along its normal: the hull of
  // the centres is still the box, but that particle's face is no longer a plane through its particles
  ParticleCloud cloud = filled(BoxShape(Vec3(0.5, 0.5, 0.5)), 0.05);
  std::size_t face = cloud.positions.size();
  for (std::size_t i = 0; i < cloud.positions.size(); ++i)
    if (cloud.flags[i] && cloud.features[i] <= 1 && cloud.normals[i].z() > 0.99) face = i;
  ASSERT_LT(face, cloud.positions.size());
  EXPECT_EQ(OneBody(cloud).core().size(), 8u);
  cloud.positions[face].z() -= 0.005;
  EXPECT_TRUE(OneBody(cloud).core().empty());
}

/// Every body's core as the world keeps it is the one its particles give now.
void keptCoresAgree(const World& w, const std::string& when) {
  std::vector<Vec3> now;
  for (std::size_t i = 0; i < w.bodies().size(); ++i) {
    const BodyInfo& info = w.bodies().info[i];
    const bool has = info.alive && info.kind != BodyKind::Deformable &&
                     PolytopeCores::find(info.particles, w.particles(), w.normals(), now);
    const std::span<const Vec3> kept = w.polytopeCores().vertices(BodyId(static_cast<std::uint32_t>(i)));
    ASSERT_EQ(kept.size(), has ? now.size() : 0u) << when << ", body " << i;
    for (std::size_t v = 0; v < kept.size(); ++v) EXPECT_EQ(kept[v], now[v]) << when << ", body " << i;
  }
}

// Two crates of particles with estimated normals, glued into one block by glue that breaks at once and spun
// so that it does: the block, whose glued faces lie inside it, has no core; the fragments' crack faces are
// estimated afresh and each fragment has its own box again. Every body's core, kept by the world, is the one
// its particles give now.
TEST(PolytopeCores, GluedAndBrokenBodiesFollowTheirParticles) {
  std::vector<Vec3> lower, upper;
  for (int k = 0; k < 5; ++k)
    for (int j = 0; j < 5; ++j)
      for (int i = 0; i < 5; ++i) {
        lower.emplace_back(0.1 * i, 0.1 * j, 0.1 * k);
        upper.emplace_back(0.5 + 0.1 * i, 0.1 * j, 0.1 * k);
      }
  const std::string list = "    connectors: bonds\n    material: rock\n    particle_mass: 0.1\n";
  World w = test::worldFromString(
      "dt: 0.004166666666666667\nsteps: 1\ngravity: [0, 0, 0]\n"
      "materials:\n  rock: {youngs_modulus: 1.0e9}\n  glue: {youngs_modulus: 1.0e9, tensile_strength: 1.0, shear_strength: 1.0}\n"
      "bodies:\n"
      "  - name: lower\n" + list + "    shape: {particles: {radius: 0.05, reach: 0.15, positions: [" + test::positionList(lower) + "]}}\n"
      "  - name: upper\n" + list + "    shape: {particles: {radius: 0.05, reach: 0.15, positions: [" + test::positionList(upper) + "]}}\n"
      "glue:\n  - {name: block, bodies: [lower, upper], material: glue, reach: 1.5}\n");
  const PolytopeCores& cores = w.polytopeCores();
  ASSERT_EQ(w.bodies().size(), 3u);
  const BodyId glued(std::uint32_t{2});
  EXPECT_TRUE(cores.vertices(glued).empty());
  keptCoresAgree(w, "glued");
  w.bodyState(glued).angularVelocity = Vec3(0, 0, 4);
  w.syncParticles();
  ASSERT_EQ(w.step(), StepStatus::Ok);
  ASSERT_FALSE(w.bodies().info[glued.index()].alive);
  ASSERT_EQ(w.bodies().size(), 5u);
  EXPECT_EQ(cores.vertices(BodyId(std::uint32_t{3})).size(), 8u);
  EXPECT_EQ(cores.vertices(BodyId(std::uint32_t{4})).size(), 8u);
  keptCoresAgree(w, "broken");
}

// A wall of bonds smashed by a ball: as bonds break and pieces fly off, each body's kept core is its particles'
// (the wall and its pieces, whose crack faces come and go; the ball, a sphere, has none).
TEST(PolytopeCores, KeptCoresFollowAFractureRun) {
  auto desc = loadScene(test::sourcePath("scenes/examples/wall_break.yaml"));
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  World& w = built->world;
  EXPECT_EQ(w.polytopeCores().bodiesWithCore(), 1u);  // the wall: a box of bonds
  std::size_t withCore = 0;
  for (int step = 1; step <= 160; ++step) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    keptCoresAgree(w, "step " + std::to_string(step));
    if (::testing::Test::HasFatalFailure()) return;
    withCore = std::max(withCore, w.polytopeCores().bodiesWithCore());
  }
  EXPECT_GT(w.bodies().size(), 10u);  // it broke
  std::printf("%zu bodies, at most %zu with a core at once\n", w.bodies().size(), withCore);
}

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
}

// Two boxes of particles in random poses whose rounded cores overlap by 5 to 75 % of the sum of the radii: the
// body pair's contacts make one patch whose normal is the direction between the closest points of the two
// cores as FCL finds them (to rounding), except where the cores' closest features are two corners or the
// particles make parallel edges, which the particle method decides with its look-ahead.
TEST(PolytopeCores, ThePlaneOfTwoCoresIsFclsClosestPointDirection) {
  WorldSettings ws;
  ws.gravity = Vec3::Zero();
  World w(ws);
  const MaterialId m = w.addMaterial(Material{"m"});
  BodyDef da, db;
  da.name = "a";
  db.name = "b";
  da.material = db.material = m;
  da.source = SourceShape{SourceShape::Kind::Box, Vec3(0.4, 0.3, 0.3), 0, 0, Vec3::Zero(), {}};
  db.source = SourceShape{SourceShape::Kind::Box, Vec3(0.3, 0.3, 0.5), 0, 0, Vec3::Zero(), {}};
  db.position = Vec3(10, 0, 0);
  const BodyId a = w.addBody(da, filled(BoxShape(da.source.size), 0.05)).value();
  const BodyId b = w.addBody(db, filled(BoxShape(db.source.size), 0.05)).value();
  ASSERT_EQ(w.polytopeCores().vertices(a).size(), 8u);
  ASSERT_EQ(w.polytopeCores().vertices(b).size(), 8u);
  const SourceShape& coreA = w.bodies().info[a.index()].core;
  const SourceShape& coreB = w.bodies().info[b.index()].core;
  const double rsum = 0.1;

  std::mt19937 rng(11);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int poses = 0, byCores = 0;
  double worst = 0.0;
  for (int attempt = 0; attempt < 2000 && poses < 300; ++attempt) {
    const Quat qa = randomRotation(rng), qb = randomRotation(rng);
    const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
    const double gap = rsum * (1.0 - (0.05 + 0.7 * u(rng)));
    // B slid along `dir` until the cores are `gap` apart (their distance is convex along a line)
    double lo = 0.0, hi = 2.0;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      const reference::CoreContact c = reference::coreContact(coreA, Vec3::Zero(), qa, coreB, dir * mid, qb);
      (c.overlap || c.distance < gap ? lo : hi) = mid;
    }
    const reference::CoreContact ref = reference::coreContact(coreA, Vec3::Zero(), qa, coreB, dir * hi, qb);
    if (!ref.valid) continue;
    for (const auto& [id, q, at] : {std::tuple{a, qa, Vec3(Vec3::Zero())}, std::tuple{b, qb, Vec3(dir * hi)}}) {
      BodyState& s = w.bodyState(id);
      const BodyInfo& info = w.bodies().info[id.index()];
      s.orientation = (q * info.principalInShape).normalized();
      s.position = at + q * info.comInShape;
    }
    w.syncParticles();
    w.refreshContacts();
    const PatchSet& ps = w.patches();
    if (ps.patches.empty()) continue;
    ++poses;
    if (ps.patches.front().source != NormalSource::Cores) continue;
    ++byCores;
    ASSERT_EQ(ps.patches.size(), 1u) << "pose " << attempt;
    const ContactPatch& p = ps.patches.front();
    EXPECT_EQ(p.count, w.contacts().contacts.size());
    EXPECT_TRUE(p.validated);
    const double angle = std::acos(std::clamp(p.normal.dot(ref.normal), -1.0, 1.0));
    worst = std::max(worst, angle);
    EXPECT_LT(angle, 1e-6) << "pose " << attempt << ": normal " << p.normal.transpose() << ", FCL " << ref.normal.transpose();
    // each contact's depth is measured along the plane's normal
    for (std::uint32_t i = p.first; i < p.first + p.count; ++i) {
      const ParticleContact& c = w.contacts().contacts[ps.contacts[i]];
      const Vec3 d = w.particles().position[c.b.index()] - w.particles().position[c.a.index()];
      EXPECT_NEAR(ps.depthAlongNormal[ps.contacts[i]], rsum - p.normal.dot(d), 1e-12);
    }
  }
  EXPECT_EQ(poses, 300);
  // corners on corners and parallel edges are rare in random poses: nearly all are decided by the cores
  EXPECT_GT(byCores, 270) << "of " << poses;
  std::printf("%d poses, %d by the cores, largest angle to FCL %.3g rad\n", poses, byCores, worst);
}

// A corner closing on a corner: the cores leave the normal open, and the particle method's look-ahead decides
// (the patch is not the cores'); with the whole cores switched off every patch is the particle method's.
TEST(PolytopeCores, CornerOnCornerIsLeftToTheLookAhead) {
  WorldSettings ws;
  ws.gravity = Vec3::Zero();
  World w(ws);
  const MaterialId m = w.addMaterial(Material{"m"});
  const Quat down = Quat::FromTwoVectors(Vec3(-1, -1, -1).normalized(), Vec3(0, 0, -1));
  BodyDef da, db;
  da.name = "a";
  db.name = "b";
  da.material = db.material = m;
  da.orientation = down;
  db.orientation = Quat::FromTwoVectors(Vec3(1, 1, 1).normalized(), Vec3(0, 0, 1));
  const ParticleCloud crate = filled(BoxShape(Vec3(0.3, 0.3, 0.3)), 0.05);
  const double corner = 0.1 * std::sqrt(3.0);  // the corner particle's centre from the crate's centre
  da.position = Vec3(0, 0, 2 * corner + 0.095);
  db.position = Vec3::Zero();
  da.linearVelocity = Vec3(0.3, 0, -1.0);
  const BodyId a = w.addBody(da, crate).value();
  w.addBody(db, crate).value();
  w.refreshContacts();
  ASSERT_EQ(w.contacts().contacts.size(), 1u);
  ASSERT_EQ(w.patches().patches.size(), 1u);
  EXPECT_NE(w.patches().patches.front().source, NormalSource::Cores);
  EXPECT_GT(w.stats().lookAheads, 0u);
  (void)a;
}

}  // namespace
}  // namespace volpar
