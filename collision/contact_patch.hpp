#pragma once
// What the narrow phase reads and produces: contact patches with their separating planes
// (docs/narrow-phase.md).

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/collision/normal_cache.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/collision/separating_plane.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/plane.hpp"

namespace volpar {

class PolytopeCores;

struct ContactPatch {
  BodyId a;                       ///< as in its ContactGroup
  BodyId b;
  PlaneId plane;
  Vec3 normal = Vec3::UnitZ();    ///< unit, from A towards B (into the plane), world
  Vec3 point = Vec3::Zero();      ///< the deepest contact point; the plane passes through it [m]
  double depth = 0.0;             ///< largest overlap along the normal [m]
  double margin = 0.0;            ///< validation margin of the chosen normal [m] (negative: unvalidated), as
                                  ///< computed: a reused patch keeps the margin of the step it was made in
  PlaneCase planeCase = PlaneCase::VertexFace11;
  NormalSource source = NormalSource::CentreLine;
  bool validated = false;
  bool lookAhead = false;         ///< a look-ahead decided the plane (the configuration it predicted gave the normal)
  PlaneCase lookAheadCase = PlaneCase::VertexFace11;  ///< when lookAhead: the case of the predicted configuration
  /// Where the plane came from one side's curved core (a sphere's centre: core[0] == core[1]; a cylinder's
  /// axis: the segment core[0]..core[1], world) against a deformable sheet or chain (which has no core): that
  /// side, 0 (A) or 1 (B); each contact then has the core's tangent plane at it (contactNormal). -1 elsewhere.
  std::int8_t curvedSide = -1;
  /// The side whose face the normal is, 0 (A) or 1 (B): where the patch is taken over in a later step
  /// (NarrowPhase), the normal turns with that side's body. 0 where the normal is A's face or both sides' (an
  /// edge crossing an edge, a corner near an edge).
  std::int8_t normalSide = 0;
  std::array<Vec3, 2> core{Vec3::Zero(), Vec3::Zero()};
  std::uint32_t first = 0;        ///< range in PatchSet::contacts
  std::uint32_t count = 0;
};

/// The normal of one contact of `patch`, from the contact's particle a (at xa) towards b (at xb); `flipped`:
/// its a is on the patch's side B. The patch's normal, or where the patch has a curved side, the normal of
/// that core's tangent plane through the contact (the direction from the core's nearest point to the other
/// side's particle), so that the contacts of a patch that wraps round a ball each push along their own
/// radius. Never more than 60 degrees from the patch's normal.
[[nodiscard]] inline Vec3 contactNormal(const ContactPatch& patch, const Vec3& xa, const Vec3& xb, bool flipped) {
  Vec3 n = patch.normal;
  if (patch.curvedSide >= 0) {
    const Vec3& onA = flipped ? xb : xa;
    const Vec3& onB = flipped ? xa : xb;
    const Vec3& x = patch.curvedSide == 0 ? onB : onA;
    const Vec3 axis = patch.core[1] - patch.core[0];
    const double len2 = axis.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp(axis.dot(x - patch.core[0]) / len2, 0.0, 1.0) : 0.0;
    Vec3 d = x - (patch.core[0] + t * axis);
    if (patch.curvedSide == 1) d = -d;
    const double norm = d.norm();
    if (norm > 0.0 && d.dot(patch.normal) > 0.5 * norm) n = d / norm;
  }
  return flipped ? Vec3(-n) : n;
}

struct NarrowPhaseStats {
  std::size_t patches = 0;
  std::array<std::size_t, kPlaneCaseCount> byCase{};
  std::size_t candidates = 0;     ///< candidate normals tried
  std::size_t lookAheads = 0;     ///< look-aheads run
  std::size_t lookAheadsDecided = 0;  ///< patches whose plane a look-ahead's configuration gave
  std::size_t unvalidated = 0;    ///< patches without a validated candidate
  std::size_t contactLines = 0;   ///< of them, resolved contact by contact along centre lines (last resort)
  std::size_t splits = 0;         ///< patches split because no plane validated
  std::size_t reused = 0;         ///< patches taken over from an earlier step (see NarrowPhase)
  NarrowPhaseStats& operator+=(const NarrowPhaseStats& o) {
    patches += o.patches;
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) byCase[k] += o.byCase[k];
    candidates += o.candidates;
    lookAheads += o.lookAheads;
    lookAheadsDecided += o.lookAheadsDecided;
    unvalidated += o.unvalidated;
    contactLines += o.contactLines;
    splits += o.splits;
    reused += o.reused;
    return *this;
  }
};

struct PatchSet {
  LargeVector<ContactPatch> patches;
  LargeVector<std::uint32_t> contacts;       ///< indices into ContactSet::contacts, grouped by patch
  /// Per contact of ContactSet (same order): overlap of the two particles' extents along the contact's
  /// normal (contactNormal), r_a + r_b - n . (x_b - x_a) [m] (plane contacts: the depth). A side's particle
  /// tops form a flat face.
  LargeVector<double> depthAlongNormal;
  LargeVector<std::uint32_t> patchOfContact; ///< per contact of ContactSet: its patch
  /// Per contact of ContactSet: 1 where its particle b lies on the patch's side A (self-contact of a
  /// deformable body, whose sides are found from the geometry); the contact's normal is then -normal.
  LargeVector<std::uint8_t> flipped;
  NarrowPhaseStats stats;
};

/// Read-only view of what the narrow phase needs from the world.
struct NarrowPhaseInput {
  const ParticleStore* particles = nullptr;
  const BodyStore* bodies = nullptr;
  const NormalCache* normals = nullptr;
  const ContactFinder* finder = nullptr;  ///< connector adjacency
  std::span<const Plane> planes;
  double dt = 0.0;                        ///< [s], scales the look-ahead
  /// The bodies' whole polytope cores, where they have one (null: none; the narrow phase then rebuilds
  /// every core from the local particles)
  const PolytopeCores* cores = nullptr;
  /// Each body's kind, compact (as bodies->info[b].kind, which takes a cache line of a BodyInfo to read);
  /// empty: read from bodies
  std::span<const BodyKind> kinds;

  [[nodiscard]] BodyKind kindOf(BodyId b) const { return kinds.empty() ? bodies->info[b.index()].kind : kinds[b.index()]; }
};

}  // namespace volpar
