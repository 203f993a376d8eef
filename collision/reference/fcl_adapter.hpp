#pragma once
// FCL as the independent referee of volpar's collision results (docs/narrow-phase.md). These files are the
// only ones that include FCL. FCL's own broadphase manager (DynamicAABBTreeCollisionManager) and narrow
// phase find, from scratch on the current state, which bodies' boxes overlap, which particle spheres
// touch and which particles reach below a plane; compareContacts() checks volpar's results against that.
//
// Touching follows FCL: spheres with |c2 - c1| <= r1 + r2. Pairs within a relative 1e-9 of the contact
// distance are *grazing*: FCL computes the distance with a square root and volpar compares squares, so
// the two may disagree exactly at the boundary; grazing pairs are left out of the comparison on both sides
// (see fcl-guide, section 6).

#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "volpar/collision/aabb.hpp"
#include "volpar/collision/broadphase.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/plane.hpp"
#include "volpar/engine/core/source_shape.hpp"

namespace volpar::reference {

/// Relative width of the grazing band.
inline constexpr double kGrazing = 1e-9;

struct SpherePair {
  ParticleId a;  ///< particle of the body with the lower id (a < b inside one body)
  ParticleId b;
  double distance = 0.0;  ///< between the centres [m], as FCL computes it
  auto operator<=>(const SpherePair& o) const { return std::pair(a, b) <=> std::pair(o.a, o.b); }
  bool operator==(const SpherePair& o) const { return a == o.a && b == o.b; }
};

struct PlaneTouch {
  ParticleId particle;
  PlaneId plane;
  double height = 0.0;  ///< of the centre above the plane [m]
  auto operator<=>(const PlaneTouch& o) const { return std::pair(particle, plane) <=> std::pair(o.particle, o.plane); }
  bool operator==(const PlaneTouch& o) const { return particle == o.particle && plane == o.plane; }
};

struct FclReport {
  std::vector<BodyPair> boxPairs;        ///< bodies whose tight boxes overlap (FCL's broadphase), sorted
  std::vector<BodyPair> touchingBodies;  ///< bodies with at least one touching particle pair, sorted
  std::vector<SpherePair> spherePairs;   ///< touching particle pairs (different bodies, or unconnected
                                         ///< particles of one deformable body), sorted
  std::vector<PlaneTouch> planeTouches;  ///< particles touching a plane (moving bodies), sorted
};

/// Which particles of one body may touch each other (deformable self-contact): (a, b) -> bool.
using SelfContactFilter = std::function<bool(ParticleId, ParticleId)>;

class FclWorldReference {
 public:
  FclWorldReference();
  ~FclWorldReference();
  FclWorldReference(const FclWorldReference&) = delete;
  FclWorldReference& operator=(const FclWorldReference&) = delete;

  /// Runs FCL on the current state. `boxes` are the bodies' tight boxes [B]; `selfContact` says which
  /// particle pairs of one deformable body count (volpar's rule: not joined by a connector).
  FclReport collide(const ParticleStore& particles, const BodyStore& bodies, std::span<const Aabb> boxes,
                    std::span<const Plane> planes, const SelfContactFilter& selfContact);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct Comparison {
  std::size_t bodyPairMismatches = 0;      ///< FCL pairs (box overlap or touching) missing from volpar's pairs
  std::size_t particlePairMismatches = 0;  ///< touching particle pairs found by one side only
  std::size_t planeContactMismatches = 0;  ///< particle-plane contacts found by one side only
  std::size_t contactsChecked = 0;         ///< non-grazing particle pairs and plane contacts compared
  std::size_t grazing = 0;                 ///< pairs left out as grazing
  std::vector<std::string> details;        ///< the first few mismatches, readable

  [[nodiscard]] std::size_t mismatches() const { return bodyPairMismatches + particlePairMismatches + planeContactMismatches; }
  Comparison& operator+=(const Comparison& o);
};

/// FCL's contact between two primitives placed in the world (pose of each shape frame), following
/// fcl-guide section 4: pairs with a sphere by collide() (closed form), box pairs by collide() (SAT; exact
/// on face contacts), capsule pairs by unsigned distance (closed form), every other pair by signed
/// distance (GJK + EPA, the minimum translation), except barely touching ones (collide() depth under 1e-4 of
/// the shapes' size), where libccd's EPA can abort and no normal is given. The normal points from a to b.
struct PrimitiveContact {
  bool hit = false;          ///< the primitives overlap or touch
  bool normalValid = false;  ///< a normal could be determined
  Vec3 normal = Vec3::Zero();
  double depth = 0.0;        ///< penetration depth [m]
};
[[nodiscard]] PrimitiveContact primitiveContact(const SourceShape& a, const Vec3& originA, const Quat& orientationA,
                                                const SourceShape& b, const Vec3& originB, const Quat& orientationB);

/// The exact reference between two bodies filled from convex solids (SourceShape::isConvexSolid): the
/// closest points of their cores (SourceShape::fittedCore, placed at the shape frames' poses), found by FCL's
/// distance query (closed forms where FCL has them, GJK otherwise). The normal is the direction from A's
/// closest point to B's: the direction in which the rounded bodies (core plus particle radius) touch, and
/// the separating-plane normal a body filled from the core exactly would have. Cores that overlap (the
/// rounded bodies interpenetrate by more than the sum of the radii) have no reference: libccd's EPA, which
/// signed distance would need, can abort the process in such poses (fcl-guide, section 5).
struct CoreContact {
  bool valid = false;        ///< both are convex solids, their cores are apart and FCL gave a direction
  bool overlap = false;      ///< the cores overlap
  Vec3 normal = Vec3::Zero();  ///< unit, from A towards B
  double distance = 0.0;     ///< between the cores [m] (0 when they overlap)
  Vec3 pointA = Vec3::Zero(), pointB = Vec3::Zero();  ///< the closest points, world [m]
};
[[nodiscard]] CoreContact coreContact(const SourceShape& coreA, const Vec3& originA, const Quat& orientationA,
                                      const SourceShape& coreB, const Vec3& originB, const Quat& orientationB);

/// The vertices of a convex polytope given by its face planes n . x <= d (duplicates merged); empty when the
/// planes bound no volume.
[[nodiscard]] std::vector<Vec3> polytopeVertices(const std::vector<std::pair<Vec3, double>>& planes);

/// Unit normals of the flat faces of a primitive in the world (box faces, cylinder caps); empty otherwise.
[[nodiscard]] std::vector<Vec3> flatFaceNormals(const SourceShape& s, const Quat& orientation);

/// Compares volpar's broadphase pairs and contacts with FCL's report.
[[nodiscard]] Comparison compareContacts(const FclReport& fcl, std::span<const BodyPair> pairs,
                                         std::span<const BodyPlanePair> planePairs, const ContactSet& contacts,
                                         const ParticleStore& particles, std::size_t maxDetails = 10);

}  // namespace volpar::reference
