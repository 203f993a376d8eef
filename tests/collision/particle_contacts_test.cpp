// Touching particle pairs against FCL: every pair of builder shapes over many random relative poses,
// grazing contacts at the threshold, deformable self-contact, planes and static bodies, and bad input.

#include <gtest/gtest.h>

#include <optional>
#include <random>

#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/collision/narrow_phase.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "volpar/engine/world.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

struct ShapeCase {
  std::string name;
  ParticleCloud cloud;
  double boundingRadius;
};

ParticleCloud fill(const SolidShape& shape, Lattice lattice, double r) {
  auto c = fillShape(shape, {lattice, r});
  EXPECT_TRUE(c.ok());
  return c.value();
}

std::vector<ShapeCase> shapes() {
  auto mesh = readObj(test::sourcePath("scenes/examples/meshes/l_shape.obj"));
  EXPECT_TRUE(mesh.ok() && mesh->makeSolid().ok());
  auto bound = [](const ParticleCloud& c) {
    double r = 0;
    Vec3 centre = Vec3::Zero();
    for (const Vec3& p : c.positions) centre += p / static_cast<double>(c.size());
    for (std::size_t i = 0; i < c.size(); ++i) r = std::max(r, (c.positions[i] - centre).norm() + c.radii[i]);
    return r;
  };
  std::vector<ShapeCase> out;
  auto add = [&](std::string name, ParticleCloud c) {
    const double r = bound(c);
    out.push_back({std::move(name), std::move(c), r});
  };
  add("box", fill(BoxShape(Vec3(0.4, 0.3, 0.3)), Lattice::Cubic, 0.05));
  add("sphere", fill(SphereShape(0.25), Lattice::Hcp, 0.04));
  add("cylinder", fill(CylinderShape(0.15, 0.4), Lattice::Cubic, 0.035));
  add("capsule", fill(CapsuleShape(0.1, 0.3), Lattice::Hcp, 0.03));
  add("l_mesh", fill(MeshShape(std::make_shared<const TriangleMesh>(mesh.value())), Lattice::Cubic, 0.05));
  return out;
}

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
}

Vec3 randomDirection(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Vec3(g(rng), g(rng), g(rng)).normalized();
}

/// Compares the world's current contacts with FCL's.
reference::Comparison againstFcl(World& w, reference::FclWorldReference& fcl) {
  const ContactFinder& finder = w.contactFinder();
  const auto report = fcl.collide(w.particles(), w.bodies(), w.bodyBoxes(), w.planes(),
                                  [&](ParticleId a, ParticleId b) { return !finder.connected(a, b); });
  return reference::compareContacts(report, w.bodyPairs(), w.planePairs(), w.contacts(), w.particles());
}

TEST(ParticleContacts, EveryShapePairAgreesWithFclOverRandomPoses) {
  const auto all = shapes();
  std::mt19937 rng(2026);
  for (std::size_t i = 0; i < all.size(); ++i)
    for (std::size_t j = i; j < all.size(); ++j) {
      SCOPED_TRACE(all[i].name + " vs " + all[j].name);
      World w(WorldSettings{});
      const MaterialId m = w.addMaterial(Material{"m"});
      BodyDef a, b;
      a.name = all[i].name;
      b.name = all[j].name + "_2";
      a.material = b.material = m;
      ASSERT_TRUE(w.addBody(a, all[i].cloud).ok());
      ASSERT_TRUE(w.addBody(b, all[j].cloud).ok());
      reference::FclWorldReference fcl;
      reference::Comparison total;
      int posesWithContact = 0;
      const double reach = all[i].boundingRadius + all[j].boundingRadius;
      std::uniform_real_distribution<double> distance(0.0, reach);
      for (int pose = 0; pose < 1000; ++pose) {
        BodyState& sa = w.bodyState(BodyId(0u));
        BodyState& sb = w.bodyState(BodyId(1u));
        sa.position = Vec3::Zero();
        sa.orientation = randomRotation(rng);
        sb.orientation = randomRotation(rng);
        sb.position = distance(rng) * randomDirection(rng);
        w.syncParticles();
        w.refreshContacts();
        if (!w.contacts().contacts.empty()) ++posesWithContact;
        const auto c = againstFcl(w, fcl);
        total += c;
        ASSERT_EQ(c.mismatches(), 0u) << "pose " << pose << ": " << (c.details.empty() ? "" : c.details[0]);
      }
      EXPECT_GT(posesWithContact, 300);
      EXPECT_GT(total.contactsChecked, 1000u);
    }
}

TEST(ParticleContacts, GrazingPairsAreTheOnlyOnesLeftOut) {
  // single particles placed at exactly the contact distance, and just inside and outside it
  std::mt19937 rng(1);
  World w(WorldSettings{});
  const MaterialId m = w.addMaterial(Material{"m"});
  ParticleListSettings one;
  one.positions = {Vec3::Zero()};
  one.radii = {0.05};
  auto small = buildParticleList(one);
  one.radii = {0.0731};
  auto large = buildParticleList(one);
  BodyDef d;
  d.material = m;
  d.name = "a";
  ASSERT_TRUE(w.addBody(d, small.value()).ok());
  d.name = "b";
  ASSERT_TRUE(w.addBody(d, large.value()).ok());
  reference::FclWorldReference fcl;
  const double rsum = 0.05 + 0.0731;
  std::size_t grazing = 0;
  for (int k = 0; k < 1000; ++k) {
    const Vec3 dir = randomDirection(rng);
    for (const double scale : {1.0, 1.0 - 1e-7, 1.0 + 1e-7}) {
      w.bodyState(BodyId(1u)).position = Vec3(0.3, -0.2, 0.1) + dir * rsum * scale;
      w.bodyState(BodyId(0u)).position = Vec3(0.3, -0.2, 0.1);
      w.syncParticles();
      w.refreshContacts();
      const auto c = againstFcl(w, fcl);
      ASSERT_EQ(c.mismatches(), 0u) << (c.details.empty() ? "" : c.details[0]);
      if (scale == 1.0) {
        grazing += c.grazing;
        EXPECT_EQ(c.contactsChecked, 0u);  // exact touching is always in the grazing band
      } else {
        EXPECT_EQ(c.contactsChecked, scale < 1.0 ? 1u : 0u);
        std::size_t touching = 0;
        for (const ParticleContact& pc : w.contacts().contacts) touching += pc.touching() ? 1 : 0;
        EXPECT_EQ(touching, scale < 1.0 ? 1u : 0u);
      }
    }
  }
  // FCL counts d <= r1 + r2: at exact touching it reports (most of) them; all went to the grazing band
  EXPECT_GT(grazing, 100u);
}

TEST(ParticleContacts, DeformableTouchesItselfButNotThroughConnectors) {
  // a chain wound on a tight helix: neighbours along the chain are joined, the turns touch each other
  ParticleListSettings s;
  for (int i = 0; i < 40; ++i) {
    const double t = 0.55 * i;
    s.positions.emplace_back(0.16 * std::cos(t), 0.16 * std::sin(t), 0.004 * i);
  }
  s.radii = {0.05};
  s.explicitConnectors = true;
  for (std::uint32_t i = 0; i + 1 < 40; ++i) s.connectors.push_back({i, i + 1});
  auto cloud = buildParticleList(s);
  ASSERT_TRUE(cloud.ok());
  World w(WorldSettings{});
  BodyDef d;
  d.name = "coil";
  d.kind = BodyKind::Deformable;
  d.material = w.addMaterial(Material{"m"});
  d.connectors.kind = ConnectorKind::Spring;
  d.connectors.stiffness = 100;
  ASSERT_TRUE(w.addBody(d, cloud.value()).ok());
  w.refreshContacts();
  ASSERT_EQ(w.contacts().groups.size(), 1u);
  EXPECT_EQ(w.contacts().groups[0].a, w.contacts().groups[0].b);
  for (const ParticleContact& c : w.contacts().contacts) EXPECT_GT(c.b.value - c.a.value, 1u);  // never a joined pair
  reference::FclWorldReference fcl;
  const auto c = againstFcl(w, fcl);
  EXPECT_EQ(c.mismatches(), 0u) << (c.details.empty() ? "" : c.details[0]);
  EXPECT_GT(c.contactsChecked, 20u);
}

TEST(ParticleContacts, PlanesAndStaticBodiesGoThroughTheSamePath) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
allow_initial_overlap: true
planes:
  - {normal: [0, 0, 1], offset: 0}
  - {normal: [-1, 0, 0], offset: -0.2}
bodies:
  - name: floor
    kind: static
    shape: {box: {size: [1, 1, 0.2]}}
    fill: {radius: 0.05}
  - name: crate
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
    position: [0.1, 0.05, 0.1]
    orientation: {axis: [1, 1, 0], angle_deg: 20}
  - name: wall
    kind: static
    shape: {box: {size: [0.2, 1, 1]}}
    fill: {radius: 0.05}
    position: [0.35, 0, 0.5]
)");
  int plane = 0, stat = 0;
  for (const ContactGroup& g : w.contacts().groups) {
    if (g.plane.valid()) ++plane;
    else if (w.bodies().info[g.a.index()].kind == BodyKind::Static || w.bodies().info[g.b.index()].kind == BodyKind::Static) ++stat;
    // static bodies never touch each other or planes
    EXPECT_FALSE(g.plane.valid() && w.bodies().info[g.a.index()].kind == BodyKind::Static);
    if (!g.plane.valid()) {
      EXPECT_FALSE(w.bodies().info[g.a.index()].kind == BodyKind::Static &&
                   w.bodies().info[g.b.index()].kind == BodyKind::Static);
    }
  }
  EXPECT_EQ(plane, 2);
  EXPECT_EQ(stat, 2);  // crate-floor and crate-wall
  for (const ParticleContact& c : w.contacts().contacts) {
    if (!c.plane.valid()) continue;
    const Plane& pl = w.planes()[c.plane.index()];
    // normal into the plane, depth = r - height, the point halfway between particle bottom and plane
    EXPECT_LT((c.normal + pl.normal).norm(), 1e-15);
    const Vec3& x = w.particles().position[c.a.index()];
    EXPECT_NEAR(c.depth, 0.05 - (pl.normal.dot(x) - pl.offset), 1e-15);
    EXPECT_NEAR(pl.normal.dot(c.point) - pl.offset, -0.5 * c.depth, 1e-15);
  }
  reference::FclWorldReference fcl;
  const auto c = againstFcl(w, fcl);
  EXPECT_EQ(c.mismatches(), 0u) << (c.details.empty() ? "" : c.details[0]);
  EXPECT_GT(c.contactsChecked, 10u);
}

TEST(ParticleContacts, ContactRecordGeometry) {
  World w(WorldSettings{});
  ParticleListSettings one;
  one.positions = {Vec3::Zero()};
  one.radii = {0.1};
  auto a = buildParticleList(one);
  one.radii = {0.2};
  auto b = buildParticleList(one);
  BodyDef d;
  d.material = w.addMaterial(Material{"m"});
  d.name = "a";
  ASSERT_TRUE(w.addBody(d, a.value()).ok());
  d.name = "b";
  d.position = Vec3(0.25, 0, 0);
  ASSERT_TRUE(w.addBody(d, b.value()).ok());
  w.refreshContacts();
  ASSERT_EQ(w.contacts().contacts.size(), 1u);
  const ParticleContact& c = w.contacts().contacts[0];
  EXPECT_EQ(c.a, ParticleId(0u));
  EXPECT_EQ(c.b, ParticleId(1u));
  EXPECT_NEAR(c.depth, 0.05, 1e-15);
  EXPECT_LT((c.normal - Vec3::UnitX()).norm(), 1e-15);
  // midpoint of the overlap [0.05, 0.1] on the centre line
  EXPECT_LT((c.point - Vec3(0.075, 0, 0)).norm(), 1e-15);
}

TEST(ParticleContacts, MalformedBodiesAreRejected) {
  World w(WorldSettings{});
  ParticleListSettings one;
  one.positions = {Vec3::Zero()};
  one.radii = {0.1};
  auto cloud = buildParticleList(one);
  BodyDef d;
  d.material = w.addMaterial(Material{"m"});
  d.name = "nan";
  d.position = Vec3(std::nan(""), 0, 0);
  auto r = w.addBody(d, cloud.value());
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("non-finite"), std::string::npos);
  d.position = Vec3(1e12, 0, 0);
  EXPECT_FALSE(w.addBody(d, cloud.value()).ok());
  d.position = Vec3::Zero();
  ParticleCloud huge = cloud.value();
  huge.radii[0] = std::numeric_limits<double>::infinity();
  auto h = w.addBody(d, huge);
  ASSERT_FALSE(h.ok());
  EXPECT_NE(h.error().message.find("positive, finite radius"), std::string::npos);
  EXPECT_EQ(w.bodies().size(), 0u);
}

TEST(ParticleContacts, NonFiniteStateStopsTheStepWithoutCrashing) {
  World w = test::worldFromString(R"(
dt: 0.01
steps: 1
bodies:
  - shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {radius: 0.05}
)");
  w.bodyState(BodyId(0u)).linearVelocity = Vec3(std::nan(""), 0, 0);
  EXPECT_EQ(w.step(), StepStatus::NonFinite);
}

}  // namespace
}  // namespace volpar

namespace volpar {
namespace {

/// pile-125 as built from its scene file (the tests step it themselves); empty after a failure.
std::optional<BuiltScene> pile125() {
  auto desc = loadScene(test::sourcePath("scenes/bench/pile-125.yaml"));
  if (!desc.ok()) {
    ADD_FAILURE() << desc.error().toString();
    return std::nullopt;
  }
  auto built = buildScene(*desc);
  if (!built.ok()) {
    ADD_FAILURE() << built.error().toString();
    return std::nullopt;
  }
  return std::move(*built);
}

// Temporal coherence, checked step by step on a falling and settling pile: the world's contact finder
// reuses particle candidate lists and its narrow phase reuses planes; a finder and a narrow phase of the
// test's own recompute everything from scratch on the same state.
TEST(TemporalCoherence, ReusedCandidateListsGiveExactlyTheContactsOfAFreshSearch) {
  auto built = pile125();
  ASSERT_TRUE(built);
  World& w = built->world;
  ContactFinder fresh;
  for (std::size_t i = 0; i < w.bodies().size(); ++i) fresh.addBody(BodyId(i), w.particles(), w.bodies());
  fresh.setReuse(false);
  fresh.setMargin(w.settings().contactMargin);
  fresh.setSweepTime(w.settings().dt);
  ContactSet set;
  std::size_t reused = 0, compared = 0;
  for (int step = 0; step < 600; ++step) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    reused += w.contactFinder().reusedPairs();
    fresh.find(w.particles(), w.bodies(), w.connectors(), w.bodyPairs(), w.planePairs(), w.planes(), w.bodyBoxes(), set);
    const ContactSet& got = w.contacts();
    ASSERT_EQ(got.contacts.size(), set.contacts.size()) << "step " << step;
    ASSERT_EQ(got.groups.size(), set.groups.size()) << "step " << step;
    for (std::size_t i = 0; i < set.contacts.size(); ++i) {
      const ParticleContact &x = got.contacts[i], &y = set.contacts[i];
      ASSERT_TRUE(x.a == y.a && x.b == y.b && x.plane == y.plane) << "step " << step << " contact " << i;
      ASSERT_EQ(x.depth, y.depth);
      ASSERT_EQ(x.point, y.point);
      ASSERT_EQ(x.normal, y.normal);
    }
    compared += set.contacts.size();
  }
  EXPECT_GT(compared, 100000u);
  EXPECT_GT(reused, 50000u) << "the candidate lists were hardly ever reused: nothing was tested";
}

TEST(TemporalCoherence, ReusedPlanesSeparateAsWellAsFreshOnes) {
  auto built = pile125();
  ASSERT_TRUE(built);
  World& w = built->world;
  NarrowPhase fresh;
  PlaneSettings settings = fresh.settings();
  settings.reuse = false;
  fresh.setSettings(settings);
  PatchSet patches;
  std::size_t reused = 0, compared = 0, close = 0, lostValidity = 0, depthApart = 0, touching = 0;
  double worstDepth = 0.0;
  std::size_t depthOff = 0;  // (touching patches whose depth is more than 0.3 mm from the fresh plane's)
  for (int step = 0; step < 600; ++step) {
    ASSERT_EQ(w.step(), StepStatus::Ok);
    reused += w.stats().patchesReused;
    fresh.run(w.narrowPhaseInput(), w.contacts(), patches);
    const PatchSet& got = w.patches();
    // the same patches (contact membership does not depend on reuse)
    ASSERT_EQ(got.patches.size(), patches.patches.size()) << "step " << step;
    ASSERT_EQ(got.contacts, patches.contacts) << "step " << step;
    for (std::size_t i = 0; i < patches.patches.size(); ++i) {
      const ContactPatch &x = got.patches[i], &y = patches.patches[i];
      ++compared;
      if (x.normal.dot(y.normal) > std::cos(2.0 * settings.reuseAngle)) ++close;
      if (y.validated && !x.validated) ++lostValidity;
      // what the solver sees: the deepest overlap along the normal, where the fresh plane has one
      if (y.depth > 0.0) {
        const double dd = std::abs(x.depth - y.depth);
        worstDepth = std::max(worstDepth, dd);
        if (dd > 1e-3) ++depthApart;
        if (dd > 3e-4) ++depthOff;
        ++touching;
      }
    }
  }
  EXPECT_GT(reused, compared / 2) << "planes were hardly ever reused: nothing was tested";
  EXPECT_EQ(lostValidity, 0u);
  // nearly every normal is the fresh one within the reuse tolerance (the rest: a near tie between two
  // candidates, or the centre line of a lone speculative pair that moved sideways within the tolerance)
  EXPECT_GT(static_cast<double>(close), 0.97 * static_cast<double>(compared));
  // and nearly every touching patch has the fresh plane's depth within 1 mm (2 % of the radius)
  EXPECT_GT(touching, 10000u);
  EXPECT_LT(static_cast<double>(depthApart), 0.002 * static_cast<double>(touching)) << "worst " << worstDepth << " m";
  // a normal carried in the frame of the body whose face it is (B's for a corner of A on a face of B) turns
  // with that face: 0.8 % of the touching patches are more than 0.3 mm off (2.5 % when every normal was
  // carried in A's frame, where B turning against A tilted it off B's face)
  EXPECT_LT(static_cast<double>(depthOff), 0.015 * static_cast<double>(touching)) << depthOff << " of " << touching;
}

}  // namespace
}  // namespace volpar
