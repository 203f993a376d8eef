#pragma once
// What the narrow phase reads and produces: contact patches with their separating planes (DESIGN
// section 4; docs/narrow-phase.md).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "collision/normal_cache.hpp"
#include "collision/particle_contacts.hpp"
#include "collision/separating_plane.hpp"
#include "engine/core/body_store.hpp"
#include "engine/core/particle_store.hpp"
#include "engine/core/plane.hpp"

namespace volpar {

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
  std::uint32_t first = 0;        ///< range in PatchSet::contacts
  std::uint32_t count = 0;
};

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
  std::vector<ContactPatch> patches;
  std::vector<std::uint32_t> contacts;       ///< indices into ContactSet::contacts, grouped by patch
  /// Per contact of ContactSet (same order): overlap of the two particles' extents along the patch normal,
  /// r_a + r_b - n . (x_b - x_a) [m] (plane contacts: the depth). A side's particle tops form a flat face.
  std::vector<double> depthAlongNormal;
  std::vector<std::uint32_t> patchOfContact; ///< per contact of ContactSet: its patch
  /// Per contact of ContactSet: 1 where its particle b lies on the patch's side A (self-contact of a
  /// deformable body, whose sides are found from the geometry); the contact's normal is then -normal.
  std::vector<std::uint8_t> flipped;
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
};

}  // namespace volpar
