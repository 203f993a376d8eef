#pragma once
// The separating plane of one contact patch (docs/narrow-phase.md, after "Volumetric Particle Separating Planes
// for Collision Detection"; docs/narrow-phase.md describes the method and its measured accuracy).
//
// 1. Each side's *local particles*: the patch's own particles and their k-ring connector neighbours
//    (PlaneSettings::validationRings). A neighbour counts when it is interior, part of a sheet or chain, or
//    its cached surface normal faces the other side (n . d > 0.05): around a concave corner (a peg against
//    the wall of a slot) the ring wraps onto the slot's floor, whose particles must not be judged by the
//    wall's plane.
// 2. The closest points of the hulls of the two sides' counted particle centres (hull_distance.hpp). Their
//    direction is the plane across which the local particles are farthest apart: the largest-margin plane
//    that the paper's choice among candidates approximates, found over all directions. The simplex says
//    which particles carry the closest features: a vertex, an edge or a face of each side.
// 3. The normal from those features' surface normals (the cached ones: a builder's exact face normals, or
//    estimated ones): a side whose closest feature is not on an edge or corner (flags kParticleSharp) has a
//    surface normal there, interpolated from the feature's particles; against a sharp side it is the
//    normal; of two such sides, a flat one (its nearby normals all agree) wins over a curved one, two flat
//    ones give the one across which the particles are farther apart, two curved ones their mean. Two sharp
//    sides (edge on edge, vertex on edge, vertex on vertex) keep the hulls' direction.
// 4. Validation: the normal must have a plane with the counted centres of A within `validationTolerance` x
//    (r_a + r_b) below it and those of B within as much above it. Otherwise the hulls' direction is used.
// 5. Where the local hulls overlap (deep interpenetration, interlocked crack faces) the paper's candidates
//    (separating_plane.hpp) are tried and the validated one with the largest margin is chosen.
// 6. Look-ahead: a patch of one contact, or of two parallel edges (edge_edge_2_3_collinear), whose two
//    closest features are both sharp has no normal that its geometry prefers; when the pair approaches,
//    its motion is followed (rigid bodies by their velocities, deformable particles by theirs) to the next
//    contacts, found exactly (the time each nearby pair of spheres meets), and the plane of that
//    configuration decides if it validates in the real one.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/collision/contact_patch.hpp"
#include "volpar/collision/hull_distance.hpp"

namespace volpar {

class PlaneSolver {
 public:
  void setSettings(const PlaneSettings& s) { settings_ = s; }

  /// Solves the plane of `patch`, whose contacts are `idx` (indices into set.contacts; `flipped` per
  /// contact of the set, see PatchSet::flipped): sets its normal, point, depth, margin, case, source,
  /// validated and lookAhead, writes depthAlongNormal of its contacts and counts into `stats`.
  void solve(const NarrowPhaseInput& in, const ContactSet& set, std::span<const std::uint32_t> idx,
             std::span<const std::uint8_t> flipped, ContactPatch& patch, std::span<double> depthAlongNormal,
             NarrowPhaseStats& stats);
  /// Between two bodies with whole polytope cores (in.cores, polytope_cores.hpp): the plane of contacts `idx`
  /// (all of a body pair's) as one patch, whose normal is the direction between the closest points of the two
  /// cores. False, with nothing written, where the cores overlap or leave the normal open (a corner on a
  /// corner, or parallel edges: solve() looks ahead there), and the caller makes patches and solves each.
  bool solveCores(const NarrowPhaseInput& in, const ContactSet& set, std::span<const std::uint32_t> idx,
                  ContactPatch& patch, std::span<double> depthAlongNormal, NarrowPhaseStats& stats);

 private:
  /// A particle of a side's neighbourhood, gathered once per patch.
  struct Local {
    Vec3 x = Vec3::Zero();                  // centre, world [m]
    Vec3 n = Vec3::Zero();                  // cached normal, world (zero: interior)
    std::array<Vec3, 3> faces{};            // cached faces, world
    double r = 0.0;
    ParticleId id;
    std::uint8_t flags = 0;
    std::uint8_t faceCount = 0;
    bool own = false;                       // one of the patch's particles
  };
  struct Side {
    std::vector<ParticleId> particles;      // the patch's own, unique, ascending
    std::vector<Vec3> points;               // their centres (or a look-ahead's)
    Vec3 centroid = Vec3::Zero();
    Vec3 line = Vec3::Zero();               // best-fit direction (unit) when >= 2 particles
    Vec3 face = Vec3::Zero();               // best-fit plane normal (unit) when not collinear
    bool collinear = true;
    double meanRadius = 0.0;
    std::vector<Local> local;               // own particles and their rings
    std::vector<Vec3> hull;                 // counted centres
    std::vector<std::uint32_t> hullLocal;   // their places in `local`
  };
  /// A normal and how well it separates the local particles.
  struct Evaluation {
    double separation = 0.0;  // of the counted centres along n [m] (negative: they overlap)
    double margin = 0.0;      // of the counted spheres along n [m]
  };
  struct Candidate {
    Vec3 normal;
    NormalSource source;
  };
  struct Choice {
    bool found = false;       // a normal was made
    Vec3 normal = Vec3::Zero();
    NormalSource source = NormalSource::Separation;
    bool open = false;  // the geometry leaves the normal open: corner on corner, or nothing rebuilt
    bool settled = false;  // exact: both hulls are the cores at their closest features, or one core a face
    std::int8_t curvedSide = -1;  // as ContactPatch::curvedSide
    std::array<Vec3, 2> core{Vec3::Zero(), Vec3::Zero()};
  };
  /// A contact of the look-ahead: local particles i (of A) and j (of B) meet at time `time` [s].
  struct Event {
    double time = 0.0;
    std::uint32_t i = 0, j = 0;
  };

  void gather(const NarrowPhaseInput& in, Side& side, int rings);
  [[nodiscard]] static bool counts(const Local& q, const Vec3& towards);
  [[nodiscard]] static Vec3 facing(const Local& q, const Vec3& towards);
  /// Whether q shows a surface to `towards` (a sheet only to what is across it).
  [[nodiscard]] static bool presents(const Local& q, const Vec3& towards);
  /// The counted centres of `side` seen along `towards` (into hull/hullLocal); whether they changed.
  static bool select(Side& side, const Vec3& towards);
  [[nodiscard]] Evaluation evaluate(const Vec3& n) const;
  /// Steps 2 and 3 on the sides' local particles, starting from direction d0 (A to B).
  Choice separationPlane(const NarrowPhaseInput& in, const Vec3& d0);
  /// Records in `out` the curved core of side A (onA) or B (onB) that gave its normal, when just one did.
  void curvedCore(bool onA, bool onB, Choice& out) const;
  /// The surface normal of side X at its closest feature, seen along `towards`; false when the feature is sharp.
  bool featureNormal(const Side& side, const HullDistance& h, bool isA, const Vec3& towards, Vec3& normal,
                     bool& flat) const;
  /// A sharp feature rebuilt from the faces its particles share: an edge (two faces) is the line where the
  /// two face planes meet, a corner (three) the point, each plane through the side's outermost local
  /// particle along its normal (the core's face there).
  struct Feature {
    int kind = 0;  // 0: not rebuilt, 1: corner point, 2: edge line
    Vec3 point = Vec3::Zero();
    Vec3 direction = Vec3::Zero();
  };
  [[nodiscard]] Feature sharpFeature(const Side& side, const HullDistance& h, bool isA) const;
  /// Side X's core near `at` as points whose hull it is: a polytope bounded by the face planes its particles
  /// carry (each through the outermost local particle along its normal; curved particles near `at` add
  /// their tangent planes), or, where the surface there is curved without flat faces, its centres of
  /// curvature (one point, or two for a surface curved one way; `curved`), or where a surface curved one way
  /// meets flat faces, points of the fitted cylinder clipped by them (roundedCore; `curved`). False when the
  /// particles carry no faces.
  bool localCore(const NarrowPhaseInput& in, const Side& side, const HullDistance& h, bool isA, const Vec3& towards,
                 std::vector<Vec3>& out, bool& curved, bool& exact);
  /// The points whose hull is the polytope of face planes n . x <= d near `at` (appends box planes when
  /// more than three faces, and removes them again); reach: how far from `at` the points go [m].
  static bool coreVertices(std::vector<std::pair<Vec3, double>>& planes, const Vec3& at, double reach,
                           std::vector<Vec3>& out);
  /// Whether the particles of side X's closest feature (hull simplex) lie on the planes of their flat faces
  /// (planes_) and `towards` is in the feature's normal cone: the particle hull is the core there.
  [[nodiscard]] bool exactFeature(const Side& side, const HullDistance& h, bool isA, const Vec3& towards,
                                  double spacing) const;
  /// The outermost centre along face normal f (world) of the particles carrying that face, climbing from
  /// particle `from` along connectors (a few steps): the face's plane of the core.
  [[nodiscard]] static double faceSupport(const NarrowPhaseInput& in, const Vec3& f, ParticleId from);
  /// The centres of curvature of a curved side near `at`: the point (or, for a surface curved one way, a
  /// segment along its axis) nearest to the normal lines of its surface particles within reach; into `out`
  /// (one or two points). False when too few particles or directions.
  bool curvatureCentres(const Side& side, const Vec3& at, const Vec3& towards, std::vector<Vec3>& out) const;
  /// Side X's core near `at` where a surface curved one way meets flat faces (a cylinder's rim): points on
  /// the fitted cylinder's rulings every few degrees round from `at`, clipped by the flat faces' planes.
  /// False when the curved particles fit no cylinder.
  bool roundedCore(const NarrowPhaseInput& in, const Side& side, const Vec3& at, const Vec3& towards,
                   std::vector<Vec3>& out);
  /// Follows the pair's motion to its next contacts (step 6); when that configuration has a plane, its
  /// normal, the case and true. `single`: a patch of one contact (else: parallel edges). The motion is
  /// followed only while no pair of local spheres sinks more than `sink` [m] into each other.
  bool lookAhead(const NarrowPhaseInput& in, bool single, double sink, Vec3& normal, PlaneCase& predicted,
                 NarrowPhaseStats& stats);
  void describe(Side& side) const;
  [[nodiscard]] static PlaneCase classify(const NarrowPhaseInput& in, const Side& a, const Side& b);
  void paperCandidates(const NarrowPhaseInput& in, const Vec3& contactDifference, PlaneCase c);
  static void ring(const NarrowPhaseInput& in, std::span<const ParticleId> seeds, int k, std::vector<ParticleId>& out,
                   std::vector<std::uint32_t>& mark, std::uint32_t& stamp, std::vector<ParticleId>& frontier,
                   std::vector<ParticleId>& next);

  PlaneSettings settings_;
  Side a_, b_;
  HullDistance hull_;
  std::vector<Candidate> candidates_;
  std::vector<Vec3> centresA_, centresB_, coreA_, coreB_, centres_;
  struct FaceCluster {
    Vec3 sum = Vec3::Zero();
    Vec3 first = Vec3::Zero();
    Vec3 position = Vec3::Zero();  // sum of the members' centres
    Mat3 spread = Mat3::Zero();    // sum of their outer products
    int count = 0;
    bool sharp = false;  // a face of an edge or corner particle
    bool near = false;   // has a member near the closest point
    bool flat = false;   // flatCluster()
  };
  /// A flat face: several particles share the normal over an area (not along one line, as the rulings of a
  /// cylinder do). (localCore also takes a face an edge bounds as flat, unless it is one of a fan of faces
  /// a few degrees apart turning about one axis: the rulings of a cylinder that end at its rim.)
  [[nodiscard]] static bool flatCluster(const FaceCluster& c, double spacing);
  std::vector<FaceCluster> clusters_;
  Side wide_;                               // roundedCore(): the side's particles with more rings
  std::vector<std::uint32_t> curvedLocal_;  // roundedCore(): the curved particles of the fit (in wide_.local)
  std::vector<std::uint8_t> flatLocal_;  // per local particle of the side being rebuilt: on a flat face
  std::vector<Vec3> velocityA_, velocityB_;  // per local particle
  std::vector<Event> events_;
  Side aheadA_, aheadB_;                 // the predicted configuration's contact particles
  std::vector<std::pair<Vec3, double>> planes_, planesA_, planesB_;
  std::vector<ParticleId> ringIds_, frontier_, next_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t stamp_ = 0;
};

}  // namespace volpar
