// The separating-plane narrow phase on real volpar bodies (the particle method, which decides every patch here:
// PlaneSettings::polytopeCores off): one test per configuration of the paper's section 5, concave bodies (a
// peg in a U-shaped slot, a box on an L), patch grouping, look-ahead leaving the world untouched, and partial
// normal recomputation.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/engine/world.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

ParticleCloud boxCloud(const Vec3& size, double r = 0.05, Lattice lattice = Lattice::Cubic, double spacing = 0.0) {
  auto c = fillShape(BoxShape(size), {lattice, r, spacing});
  EXPECT_TRUE(c.ok());
  return c.value();
}

ParticleCloud meshCloud(const std::string& file, double r) {
  auto m = readObj(test::sourcePath("scenes/examples/meshes/" + file));
  EXPECT_TRUE(m.ok() && m->makeSolid().ok());
  auto c = fillShape(MeshShape(std::make_shared<const TriangleMesh>(m.value())), {Lattice::Cubic, r});
  EXPECT_TRUE(c.ok());
  return c.value();
}

Quat about(const Vec3& axis, double degrees) {
  return Quat(Eigen::AngleAxisd(degrees * std::numbers::pi / 180.0, axis.normalized()));
}

double angleDeg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

/// Two bodies without gravity: A (added first, the lower id) above B. The particle method decides every patch:
/// two boxes would otherwise be decided by their whole polytope cores (polytope_cores_test.cpp).
struct Pair {
  World world{[] {
    WorldSettings s;
    s.gravity = Vec3::Zero();
    s.planes.polytopeCores = false;
    return s;
  }()};
  BodyId a, b;

  Pair(const ParticleCloud& ca, const Quat& qa, const ParticleCloud& cb, const Quat& qb) {
    const MaterialId m = world.addMaterial(Material{"m"});
    BodyDef da;
    da.name = "a";
    da.material = m;
    da.orientation = qa;
    da.position = Vec3(0, 0, 5);  // out of the way until placed
    BodyDef db = da;
    db.name = "b";
    db.orientation = qb;
    db.position = Vec3::Zero();
    a = world.addBody(da, ca).value();
    b = world.addBody(db, cb).value();
  }

  const Vec3& x(ParticleId p) const { return world.particles().position[p.index()]; }

  /// The particle of `body` that is lowest (highest when `up`), ties broken towards `near` in xy.
  ParticleId extreme(BodyId body, bool up, const Vec3& near = Vec3::Zero()) const {
    ParticleId best;
    double bestKey = std::numeric_limits<double>::infinity();
    for (const ParticleId p : world.bodies().info[body.index()].particles) {
      const double z = up ? -x(p).z() : x(p).z();
      const double key = std::round(z * 1e6) + 1e-3 * (x(p) - near).head<2>().norm();
      if (key < bestKey) {
        bestKey = key;
        best = p;
      }
    }
    return best;
  }

  /// Moves body A rigidly so that its particle p lands on `target`, then detects collisions.
  void place(ParticleId p, const Vec3& target) {
    world.bodyState(a).position += target - x(p);
    world.syncParticles();
    world.refreshContacts();
  }

  const ContactPatch& onlyPatch() const {
    EXPECT_EQ(world.patches().patches.size(), 1u);
    return world.patches().patches.at(0);
  }
};

void expectPlane(const ContactPatch& p, PlaneCase expectedCase, const Vec3& expectedNormal, double toleranceDeg = 1e-6) {
  EXPECT_EQ(p.planeCase, expectedCase) << planeCaseName(p.planeCase);
  EXPECT_LT(angleDeg(p.normal, expectedNormal), toleranceDeg) << p.normal.transpose();
  EXPECT_TRUE(p.validated) << "margin " << p.margin;
}

const Quat kCornerDown = Quat::FromTwoVectors(Vec3(-1, -1, -1).normalized(), Vec3(0, 0, -1));

// a cube's corner particle on a face: exactly one contact, nothing new within the look-ahead
TEST(SeparatingPlane, VertexFace11) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerDown, boxCloud(Vec3(0.5, 0.5, 0.2)), Quat::Identity());
  const ParticleId corner = s.extreme(s.a, false);
  EXPECT_TRUE(s.world.particles().flags[corner.index()] & kParticleCorner);
  s.place(corner, Vec3(0, 0, 0.05 + 0.095));
  ASSERT_EQ(s.world.contacts().contacts.size(), 1u);
  expectPlane(s.onlyPatch(), PlaneCase::VertexFace11, -Vec3::UnitZ());
  // at rest there is no motion to follow: the face's plane is the geometry's own
  EXPECT_EQ(s.world.stats().lookAheads, 0u);
  EXPECT_FALSE(s.onlyPatch().lookAhead);
}

// the corner in the groove between two face particles
TEST(SeparatingPlane, VertexFace12) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerDown, boxCloud(Vec3(0.5, 0.5, 0.2)), Quat::Identity());
  s.place(s.extreme(s.a, false), Vec3(0.05, 0, 0.05 + std::sqrt(0.095 * 0.095 - 0.05 * 0.05)));
  ASSERT_EQ(s.world.contacts().contacts.size(), 2u);
  expectPlane(s.onlyPatch(), PlaneCase::VertexFace12, -Vec3::UnitZ());
}

// the corner in the hollow between three particles of a close-packed face
TEST(SeparatingPlane, VertexFace13) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerDown, boxCloud(Vec3(0.6, 0.6, 0.3), 0.05, Lattice::Hcp), Quat::Identity());
  // three mutually touching particles of B's top layer near the middle
  const ParticleId p0 = s.extreme(s.b, true);
  std::vector<ParticleId> top;
  for (const ParticleId p : s.world.bodies().info[s.b.index()].particles)
    if (std::abs(s.x(p).z() - s.x(p0).z()) < 1e-9 && (s.x(p) - s.x(p0)).norm() < 0.1 + 1e-9) top.push_back(p);
  ParticleId p1 = top.at(1), p2;
  for (const ParticleId p : top)
    if (p != p0 && p != p1 && (s.x(p) - s.x(p1)).norm() < 0.1 + 1e-9) p2 = p;
  ASSERT_TRUE(p2.valid());
  const Vec3 hollow = (s.x(p0) + s.x(p1) + s.x(p2)) / 3.0;
  const double h = std::sqrt(0.09 * 0.09 - (s.x(p0) - hollow).squaredNorm());
  s.place(s.extreme(s.a, false), hollow + Vec3(0, 0, h));
  ASSERT_EQ(s.world.contacts().contacts.size(), 3u);
  expectPlane(s.onlyPatch(), PlaneCase::VertexFace13, -Vec3::UnitZ());
  EXPECT_EQ(s.onlyPatch().source, NormalSource::Surface);  // B's face
}

// crossing edges: one particle of A's edge between two of B's
TEST(SeparatingPlane, EdgeEdge12) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitX(), 45), boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitY(), 45));
  const ParticleId mid = s.extreme(s.a, false);  // the middle particle of A's lower edge (nearest the axis)
  EXPECT_TRUE(s.world.particles().flags[mid.index()] & kParticleEdge);
  s.place(mid, Vec3(0, 0, s.x(s.extreme(s.b, true)).z() + 0.08));
  ASSERT_EQ(s.world.contacts().contacts.size(), 2u);
  expectPlane(s.onlyPatch(), PlaneCase::EdgeEdge12, -Vec3::UnitZ());
}

// crossing edges, two particles each
TEST(SeparatingPlane, EdgeEdge22) {
  Pair s(boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitX(), 45), boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitY(), 45));
  const ParticleId low = s.extreme(s.a, false, Vec3(0.05, 0, 0));
  s.place(low, Vec3(0.05, 0, s.x(s.extreme(s.b, true)).z() + 0.06));
  ASSERT_EQ(s.world.contacts().contacts.size(), 4u);
  expectPlane(s.onlyPatch(), PlaneCase::EdgeEdge22, -Vec3::UnitZ());
  EXPECT_EQ(s.onlyPatch().source, NormalSource::Surface);  // across both edges
}

// parallel edges: two particles above three collinear ones
TEST(SeparatingPlane, EdgeEdge23Collinear) {
  Pair s(boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitY(), 45), boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitY(), 45));
  const ParticleId low = s.extreme(s.a, false, Vec3(0, 0.05, 0));
  s.place(low, Vec3(0, 0.05, s.x(s.extreme(s.b, true)).z() + 0.08));
  ASSERT_EQ(s.world.contacts().contacts.size(), 4u);
  expectPlane(s.onlyPatch(), PlaneCase::EdgeEdge23, -Vec3::UnitZ());
}

// an edge of two particles on a face
TEST(SeparatingPlane, EdgeFace23) {
  Pair s(boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitX(), 45), boxCloud(Vec3(0.6, 0.6, 0.2)), Quat::Identity());
  s.place(s.extreme(s.a, false, Vec3(0.05, 0, 0)), Vec3(0.05, 0, 0.05 + 0.08));
  ASSERT_EQ(s.world.contacts().contacts.size(), 4u);  // each edge particle in a groove of the face
  expectPlane(s.onlyPatch(), PlaneCase::EdgeFace23, -Vec3::UnitZ());
  EXPECT_EQ(s.onlyPatch().source, NormalSource::Surface);  // B's face
}

// an edge of three collinear particles on a face
TEST(SeparatingPlane, EdgeFace33Collinear) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitX(), 45), boxCloud(Vec3(0.6, 0.6, 0.2)), Quat::Identity());
  s.place(s.extreme(s.a, false), Vec3(0, 0, 0.05 + 0.06));
  ASSERT_EQ(s.world.contacts().contacts.size(), 12u);
  expectPlane(s.onlyPatch(), PlaneCase::EdgeFace33, -Vec3::UnitZ());
}

// face on face
TEST(SeparatingPlane, FaceFace) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitZ(), 0), boxCloud(Vec3(0.5, 0.5, 0.2)), Quat::Identity());
  s.place(s.extreme(s.a, false), Vec3(0, 0, 0.05 + 0.095));
  ASSERT_EQ(s.world.contacts().contacts.size(), 9u);
  expectPlane(s.onlyPatch(), PlaneCase::FaceFace, -Vec3::UnitZ());
  for (std::uint32_t i = 0; i < 9; ++i) EXPECT_NEAR(s.world.patches().depthAlongNormal[i], 0.005, 1e-12);
}

// a peg pressed into a U-shaped slot touches both walls: two patches with the walls' normals, where the
// bodies' centre-to-centre direction points straight up
TEST(SeparatingPlane, PegInSlotGetsOnePlanePerWall) {
  const ParticleCloud u = meshCloud("u_shape.obj", 0.05);
  const ParticleCloud peg = boxCloud(Vec3(0.22, 0.22, 0.33), 0.055, Lattice::Cubic, 0.11);
  Pair s(u, Quat::Identity(), peg, Quat::Identity());
  // the U (A) back to its file's coordinates, the peg (B) into the slot
  s.world.bodyState(s.a).position -= Vec3(0, 0, 5);
  s.world.bodyState(s.b).position = Vec3(0.3, 0.1, 0.375);
  s.world.syncParticles();
  s.world.refreshContacts();
  // patches with touching contacts: one per wall; the peg's near-contacts with the slot's floor (within the
  // speculative margin) make a third, facing up
  std::vector<ContactPatch> patches, near;
  for (const ContactPatch& p : s.world.patches().patches) {
    bool touching = false;
    for (std::uint32_t k = p.first; k < p.first + p.count; ++k)
      touching = touching || s.world.contacts().contacts[s.world.patches().contacts[k]].touching();
    (touching ? patches : near).push_back(p);
  }
  ASSERT_EQ(patches.size(), 2u);
  ASSERT_EQ(near.size(), 1u);
  EXPECT_LT(angleDeg(near[0].normal, Vec3::UnitZ()), 1e-6);
  const Vec3 centres = s.world.bodies().state[s.b.index()].position - s.world.bodies().state[s.a.index()].position;
  EXPECT_LT(angleDeg(centres, Vec3::UnitZ()), 1e-9);  // the bodies' centres: straight up
  std::vector<Vec3> normals{patches[0].normal, patches[1].normal};
  std::sort(normals.begin(), normals.end(), [](const Vec3& x, const Vec3& y) { return x.x() < y.x(); });
  // from the U into the peg: the right wall pushes towards -x, the left wall towards +x
  EXPECT_LT(angleDeg(normals[0], -Vec3::UnitX()), 1.0) << normals[0].transpose();
  EXPECT_LT(angleDeg(normals[1], Vec3::UnitX()), 1.0) << normals[1].transpose();
  for (const ContactPatch& p : patches) EXPECT_TRUE(p.validated);
}

// a box on the far end of an L's long leg: the plane is the leg's face, the centre line is 40 degrees off
TEST(SeparatingPlane, BoxOnAnLGetsTheFaceNormal) {
  const ParticleCloud l = meshCloud("l_shape.obj", 0.05);
  Pair s(boxCloud(Vec3(0.2, 0.2, 0.2)), Quat::Identity(), l, Quat::Identity());
  // the L lies in the xy plane (z in [0, 0.2]); the box sits on its top face over the end of the x leg
  s.place(s.extreme(s.a, false, Vec3(0.45, 0.05, 0)), Vec3(0.45, 0.05, 0.15 + 0.095));
  ASSERT_EQ(s.world.patches().patches.size(), 1u);
  const ContactPatch& p = s.onlyPatch();
  EXPECT_LT(angleDeg(p.normal, -Vec3::UnitZ()), 1e-6);
  const Vec3 centres = s.world.bodies().state[s.b.index()].position - s.world.bodies().state[s.a.index()].position;
  EXPECT_GT(angleDeg(centres, -Vec3::UnitZ()), 30.0);
}

// parallel edges (A's lowest edge resting on B's upper edge, a little to its right; A's bottom face rises
// 25 degrees from level to the left), A toppling to the left about its edge: the look-ahead follows the
// motion to the contacts that face makes with B's edge (when it is about level) and takes its plane
TEST(SeparatingPlane, LookAheadTurnsParallelEdgesIntoAnEdgeOnAFace) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitY(), 25), boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitY(), 45));
  const ParticleId low = s.extreme(s.a, false, Vec3(0, 0.0, 0));
  const ParticleId top = s.extreme(s.b, true, Vec3(0, 0.0, 0));
  // A toppling about its edge particle (which stays put): v = -w x (edge - centre), set before it is placed
  // (placing moves A rigidly)
  const double spin = 20.0;  // [rad/s] about -y: its left side comes down
  BodyState& state = s.world.bodyState(s.a);
  state.angularVelocity = Vec3(0, -spin, 0);
  state.linearVelocity = -state.angularVelocity.cross(s.x(low) - state.position);
  const Vec3 offset(0.05, 0.0, 0.0866);  // touching, 30 degrees off vertical
  s.place(low, s.x(top) + offset);
  ASSERT_EQ(s.world.patches().patches.size(), 1u);
  const ContactPatch& p = s.onlyPatch();
  EXPECT_EQ(p.planeCase, PlaneCase::EdgeEdge23) << planeCaseName(p.planeCase);
  EXPECT_EQ(s.world.stats().lookAheads, 1u);
  ASSERT_TRUE(p.lookAhead);
  EXPECT_TRUE(p.lookAheadCase == PlaneCase::EdgeFace23 || p.lookAheadCase == PlaneCase::EdgeFace33) << planeCaseName(p.lookAheadCase);
  EXPECT_TRUE(p.validated);
  // the face that lands: A's bottom face (outward normal 25 degrees off straight down now), turned towards
  // level until it meets B's edge. The motion followed is each particle's velocity in a straight line, which
  // turns a face through the pivot by atan(w t) within the horizon of 8 steps.
  const Vec3 face = about(Vec3::UnitY(), 25) * Vec3(0, 0, -1);
  EXPECT_LT(std::abs(p.normal.y()), 1e-9);
  EXPECT_GT(angleDeg(p.normal, face), 15.0) << p.normal.transpose();
  EXPECT_LT(angleDeg(p.normal, face), std::atan(spin * 8.0 * s.world.settings().dt) * 180.0 / std::numbers::pi);
  EXPECT_LT(angleDeg(p.normal, -Vec3::UnitZ()), 10.0);
  EXPECT_GT(angleDeg(p.normal, -offset), 10.0);  // not the edges' perpendicular
}

// the same edges at rest: nothing to foresee, the perpendicular between them
TEST(SeparatingPlane, ParallelEdgesAtRestKeepTheirPerpendicular) {
  Pair s(boxCloud(Vec3(0.2, 0.2, 0.2)), about(Vec3::UnitY(), 45), boxCloud(Vec3(0.3, 0.3, 0.3)), about(Vec3::UnitY(), 45));
  const ParticleId low = s.extreme(s.a, false, Vec3(0, 0.05, 0));
  s.place(low, Vec3(0, 0.05, s.x(s.extreme(s.b, true)).z() + 0.1));
  expectPlane(s.onlyPatch(), PlaneCase::EdgeEdge23, -Vec3::UnitZ());
  EXPECT_FALSE(s.onlyPatch().lookAhead);
}

const Quat kCornerUp = Quat::FromTwoVectors(Vec3(1, 1, 1).normalized(), Vec3(0, 0, 1));

// corner on corner (a single contact whose geometry says nothing but the line between the corners), A's
// corner 4 cm along x from B's and 3 mm into it, A moving on across B's corner and down: the look-ahead
// finds the next contacts, the second of which has a plane, before the corners sink into each other
TEST(SeparatingPlane, LookAheadDecidesACornerOnACorner) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerDown, boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerUp);
  s.world.bodyState(s.a).linearVelocity = Vec3(3.0, 0.0, -3.5);
  const ParticleId bottom = s.extreme(s.a, false), top = s.extreme(s.b, true);
  s.place(bottom, s.x(top) + Vec3(0.04, 0.0, std::sqrt(0.097 * 0.097 - 0.04 * 0.04)));
  ASSERT_EQ(s.world.contacts().contacts.size(), 1u);
  const ContactPatch& p = s.onlyPatch();
  EXPECT_EQ(p.planeCase, PlaneCase::VertexFace11);
  EXPECT_EQ(s.world.stats().lookAheads, 1u);
  ASSERT_TRUE(p.lookAhead);
  EXPECT_NE(p.lookAheadCase, PlaneCase::VertexFace11);
  EXPECT_TRUE(p.validated);
  EXPECT_GT(angleDeg(p.normal, s.x(top) - s.x(bottom)), 10.0);  // not the corners' line
}

// corner on corner again, 3 mm into each other, A closing fast along the corners' line and a little
// sideways. Followed in straight lines, the corners would pass a centimetre into each other within the step
// and meet their next contacts (whose plane lies 54 degrees off that line) only a step later; the motion is
// not followed past the validation tolerance of sinking, so the corners' line stays the normal and the
// solver holds the approach. (Taking the plane of those next contacts, the corners sank 26 mm into each
// other over the next steps.)
TEST(SeparatingPlane, LookAheadStopsWhereTheContactWouldSinkIn) {
  Pair s(boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerDown, boxCloud(Vec3(0.3, 0.3, 0.3)), kCornerUp);
  s.world.bodyState(s.a).linearVelocity = Vec3(3.0, 0.0, -3.5);
  s.place(s.extreme(s.a, false), s.x(s.extreme(s.b, true)) + Vec3(0, 0, 0.097));
  ASSERT_EQ(s.world.contacts().contacts.size(), 1u);
  const ContactPatch& p = s.onlyPatch();
  EXPECT_EQ(p.planeCase, PlaneCase::VertexFace11);
  EXPECT_EQ(s.world.stats().lookAheads, 1u);  // followed, and not decided
  EXPECT_FALSE(p.lookAhead);
  EXPECT_LT(angleDeg(p.normal, -Vec3::UnitZ()), 1e-6) << p.normal.transpose();
  double deepest = 0.0;
  for (int k = 0; k < 12; ++k) {
    s.world.step();
    deepest = std::max(deepest, s.world.stats().maxPenetration);
  }
  EXPECT_LT(deepest, 0.003 + 0.001) << "the corners sank in";
}

TEST(SeparatingPlane, PatchesGroupByConnectorAdjacency) {
  // two separate touching regions between the same pair of bodies (an upside-down U over a bar)
  const ParticleCloud u = meshCloud("u_shape.obj", 0.05);
  Pair s(u, about(Vec3::UnitX(), 180), boxCloud(Vec3(0.8, 0.2, 0.2)), Quat::Identity());
  // the U's legs (pointing down, x in [0, 0.2] and [0.4, 0.6]) stand on the bar, centred over it
  s.place(s.extreme(s.a, false, Vec3(0, 0, 0)), Vec3(0.05 - 0.3, 0.05, 0.05 + 0.095));
  EXPECT_EQ(s.world.contacts().groups.size(), 1u);
  EXPECT_EQ(s.world.patches().patches.size(), 2u);
  for (const ContactPatch& p : s.world.patches().patches) EXPECT_LT(angleDeg(p.normal, -Vec3::UnitZ()), 1e-6);
}

/// A scene without gravity, to which block() adds bodies.
const std::string kBlocks = "dt: 0.01\nsteps: 1\ngravity: [0, 0, 0]\nbodies:\n";

/// A 6 x 5 x 4 block (0.6 x 0.5 x 0.4 m filled at r = 0.05 m) of `kind` at `at`, turned by `angleDeg` about
/// `axis` (a deformable one with springs).
std::string block(const char* kind, const char* at, const char* axis, int angleDeg = 40) {
  const std::string springs = std::string(kind) == "deformable" ? "    connectors: {springs: {stiffness: 20000}}\n" : "";
  return std::string("  - shape: {box: {size: [0.6, 0.5, 0.4]}}\n    fill: {radius: 0.05}\n    kind: ") + kind +
         "\n    position: " + at + "\n    orientation: {axis: " + axis + ", angle_deg: " + std::to_string(angleDeg) + "}\n" +
         springs;
}

/// Every entry of the normal cache in use is held by as many particles as point to it, and no particle
/// points to a free one.
void expectEntriesCounted(const World& w) {
  std::vector<std::uint32_t> holders(w.normals().size(), 0);
  for (std::size_t i = 0; i < w.particles().size(); ++i)
    if (const std::int32_t k = w.particles().normalIndex[i]; k >= 0) ++holders[static_cast<std::size_t>(k)];
  std::size_t inUse = 0;
  for (std::size_t k = 0; k < holders.size(); ++k) {
    EXPECT_EQ(w.normals().users(static_cast<std::int32_t>(k)), holders[k]) << k;
    inUse += holders[k] > 0;
  }
  EXPECT_EQ(w.normals().used(), inUse);
}

TEST(NormalCache, PartialRecomputationReproducesTheBuildersNormalsAndFlags) {
  // a 6 x 5 x 4 block: re-estimating particles from their neighbourhood gives exactly the builder's normals,
  // faces and flags (face, edge, corner, interior), and the cache counts its entries' particles
  World w = test::worldFromString(kBlocks + block("rigid", "[0, 0, 0]", "[1, 2, 3]"));
  w.refreshContacts();
  const std::size_t n = w.particles().size();
  std::vector<Vec3> normals;
  std::vector<std::uint8_t> flags;
  std::vector<std::vector<Vec3>> faces;
  for (std::size_t i = 0; i < n; ++i) {
    normals.push_back(w.particleNormal(ParticleId(i)));
    flags.push_back(w.particles().flags[i]);
    const std::int32_t k = w.particles().normalIndex[i];
    faces.emplace_back();
    if (k >= 0)
      for (const Vec3& f : w.normals().faces(k)) faces.back().push_back(f);
  }
  std::vector<ParticleId> all;
  for (std::size_t i = 0; i < n; ++i) all.emplace_back(i);
  w.recomputeNormals(all);
  expectEntriesCounted(w);
  int edges = 0, corners = 0;
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_EQ(w.particles().flags[i], flags[i]) << i;
    EXPECT_LT((w.particleNormal(ParticleId(i)) - normals[i]).norm(), 1e-9) << i;
    const std::int32_t k = w.particles().normalIndex[i];
    if (k < 0) continue;
    ASSERT_EQ(w.normals().faces(k).size(), faces[i].size()) << i;
    for (const Vec3& f : w.normals().faces(k)) {
      double best = 2.0;
      for (const Vec3& g : faces[i]) best = std::min(best, (f - g).norm());
      EXPECT_LT(best, 1e-9) << i;
    }
    edges += (flags[i] & kParticleEdge) != 0;
    corners += (flags[i] & kParticleCorner) != 0;
  }
  EXPECT_EQ(corners, 8);
  EXPECT_EQ(edges, 4 * (4 + 3 + 2));
}

TEST(NormalCache, RigidBodiesOfOneShapeHoldItsNormalsOnceAndReadWhatTheyWouldAlone) {
  // three blocks of one shape, turned differently: rigid ones share entries (a face's particles one, each
  // edge and corner its own), a deformable one keeps its own, and every particle reads the normal and faces it
  // reads in a world of its body alone, bit for bit
  const std::array<std::string, 3> bodies{block("rigid", "[0, 0, 0]", "[1, 2, 3]"), block("rigid", "[3, 0, 0]", "[3, -1, 2]"),
                                          block("deformable", "[6, 0, 0]", "[0, 1, 1]")};
  World all = test::worldFromString(kBlocks + bodies[0] + bodies[1] + bodies[2]);
  ASSERT_EQ(all.particles().size() % 3, 0u);
  const std::size_t perBody = all.particles().size() / 3, surface = 6 * 5 * 4 - 4 * 3 * 2;
  // 6 faces, 12 edges and 8 corners for the two rigid blocks, and an entry per surface particle of the third
  EXPECT_EQ(all.normals().used(), 26u + surface);
  expectEntriesCounted(all);
  for (std::size_t b = 0; b < 3; ++b) {
    World alone = test::worldFromString(kBlocks + bodies[b]);
    ASSERT_EQ(alone.particles().size(), perBody);
    for (std::size_t i = 0; i < perBody; ++i) {
      const std::int32_t k = all.particles().normalIndex[b * perBody + i], ka = alone.particles().normalIndex[i];
      ASSERT_EQ(k < 0, ka < 0) << b << " " << i;
      if (k < 0) continue;
      EXPECT_EQ(std::memcmp(all.normals()[k].data(), alone.normals()[ka].data(), sizeof(Vec3)), 0) << b << " " << i;
      const std::span<const Vec3> f = all.normals().faces(k), fa = alone.normals().faces(ka);
      ASSERT_EQ(f.size(), fa.size());
      for (std::size_t j = 0; j < f.size(); ++j) EXPECT_EQ(std::memcmp(f[j].data(), fa[j].data(), sizeof(Vec3)), 0);
    }
  }
}

TEST(NormalCache, RewritingAnEntryOneBodySharesLeavesTheOthersNormalsAsTheyWere) {
  // two blocks of one shape share their entries; re-estimating the first block's normals (as a break does)
  // changes its entries alone, never what the second block reads
  World w = test::worldFromString(kBlocks + block("rigid", "[0, 0, 0]", "[1, 2, 3]") + block("rigid", "[3, 0, 0]", "[0, 0, 1]", 0));
  const std::size_t n = w.particles().size() / 2;
  std::vector<Vec3> second;
  for (std::size_t i = n; i < 2 * n; ++i) second.push_back(w.particleNormal(ParticleId(i)));
  std::vector<ParticleId> first;
  for (std::size_t i = 0; i < n; ++i) first.emplace_back(i);
  w.recomputeNormals(first);
  // (the estimates differ from the builder's in the last bits, so the first block's entries are rewritten)
  std::size_t own = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (const std::int32_t k = w.particles().normalIndex[i]; k >= 0) own += w.normals().users(k) == 1;
  EXPECT_GT(own, 0u);
  for (std::size_t i = n; i < 2 * n; ++i)
    EXPECT_EQ(std::memcmp(w.particleNormal(ParticleId(i)).data(), second[i - n].data(), sizeof(Vec3)), 0) << i;
  expectEntriesCounted(w);
}

}  // namespace
}  // namespace volpar
