#pragma once
// The narrow phase driver (DESIGN section 4): the contacts of each body pair, body-plane pair and
// deformable body are grouped into patches by connector adjacency, and each patch gets a local separating
// plane (separating_plane.hpp) with its normal, points and depths.
//
// Patches: two contacts of one group share a patch when their particles on side A are the same or
// connector neighbours AND their particles on side B are (for planes: side A only) AND their centre lines
// are within 78 degrees of each other (a lattice face tilts a contact's centre line by up to 35 degrees;
// a wall and a floor differ by 90), closed transitively. So a peg touching both walls of a slot makes two
// patches even if the peg is one particle wide, and its near-contacts with the slot's floor a third.

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
  double margin = 0.0;            ///< validation margin of the chosen normal [m] (negative: unvalidated)
  PlaneCase planeCase = PlaneCase::VertexFace11;
  NormalSource source = NormalSource::CentreLine;
  bool validated = false;
  bool lookAhead = false;         ///< a look-ahead supplied the configuration
  std::uint32_t first = 0;        ///< range in PatchSet::contacts
  std::uint32_t count = 0;
};

struct NarrowPhaseStats {
  std::size_t patches = 0;
  std::array<std::size_t, kPlaneCaseCount> byCase{};
  std::size_t candidates = 0;     ///< candidate normals tried
  std::size_t lookAheads = 0;     ///< look-aheads run
  std::size_t unvalidated = 0;    ///< patches without a validated candidate
};

struct PatchSet {
  std::vector<ContactPatch> patches;
  std::vector<std::uint32_t> contacts;       ///< indices into ContactSet::contacts, grouped by patch
  /// Per contact of ContactSet (same order): overlap of the two particles' extents along the patch normal,
  /// r_a + r_b - n . (x_b - x_a) [m] (plane contacts: the depth). A side's particle tops form a flat face.
  std::vector<double> depthAlongNormal;
  std::vector<std::uint32_t> patchOfContact; ///< per contact of ContactSet: its patch
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

class NarrowPhase {
 public:
  void setSettings(const PlaneSettings& s) { settings_ = s; }
  [[nodiscard]] const PlaneSettings& settings() const { return settings_; }

  /// Patches and planes for every contact group.
  void run(const NarrowPhaseInput& in, const ContactSet& contacts, PatchSet& out);

 private:
  struct Side {
    std::vector<ParticleId> particles;  // unique, ascending
    Vec3 centroid = Vec3::Zero();
    Vec3 line = Vec3::Zero();   // best-fit direction (unit) when >= 2 particles
    Vec3 face = Vec3::Zero();   // best-fit plane normal (unit) when not collinear
    bool collinear = true;
    double meanRadius = 0.0;
  };
  struct Candidate {
    Vec3 normal;
    NormalSource source;
  };

  void makePatches(const NarrowPhaseInput& in, const ContactSet& contacts, const ContactGroup& g, PatchSet& out);
  void solvePatch(const NarrowPhaseInput& in, const ContactSet& contacts, ContactPatch& patch, PatchSet& out);
  void describeSide(const std::vector<Vec3>& points, double meanRadius, Side& side) const;
  void addCandidates(const NarrowPhaseInput& in, const Side& a, const Side& b, const std::vector<Vec3>& pointsA,
                     const std::vector<Vec3>& pointsB, const Vec3& contactDifference, PlaneCase c, bool bIsPlane,
                     const Plane* plane);
  /// k-ring neighbourhood of `seeds` (seeds included) into `out`.
  void ring(const NarrowPhaseInput& in, std::span<const ParticleId> seeds, int k, std::vector<ParticleId>& out);
  bool lookAhead(const NarrowPhaseInput& in, ParticleId a, ParticleId b, std::vector<Vec3>& pointsA,
                 std::vector<Vec3>& pointsB, Vec3& contactDifference);
  [[nodiscard]] Vec3 worldNormal(const NarrowPhaseInput& in, ParticleId p) const;
  [[nodiscard]] PlaneCase classify(const NarrowPhaseInput& in, const Side& a, const Side& b) const;

  PlaneSettings settings_;
  // scratch, reused across patches and steps
  std::vector<std::uint32_t> parent_;
  std::vector<std::uint32_t> order_;
  std::vector<Vec3> pointsA_, pointsB_;
  Side sideA_, sideB_;
  std::vector<Candidate> candidates_;
  std::vector<ParticleId> ringA_, ringB_, seedsA_, seedsB_, frontier_, next_;
  std::vector<std::uint32_t> mark_;
  std::uint32_t stamp_ = 0;
  std::vector<ParticleId> aheadA_, aheadB_;
  std::vector<Vec3> aheadPosA_, aheadPosB_;
};

/// World-frame outward normal of a surface particle from the cache (zero for interior particles).
[[nodiscard]] Vec3 cachedWorldNormal(const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals,
                                     ParticleId p);

}  // namespace volpar
