#pragma once
// Particle contacts (DESIGN section 4): every pair of touching particles of two different bodies, of a
// body and a plane, and of non-neighbouring particles of one deformable body.
//
// Two particles touch when |x_b - x_a| < r_a + r_b, tested on world positions; a particle touches a plane
// when its centre is less than its radius above it. Pairs that are within a small margin of touching
// (`setMargin`, a fraction of r_a + r_b) are reported too, as speculative contacts with a negative depth:
// they keep a resting contact set stable (a stack rocking by a hair does not lose and regain contacts) and
// let the solver stop an approaching pair exactly at contact. Inside a candidate body pair the search goes through
// a uniform grid of each body's particles, built once in the body frame for rigid and static bodies and
// every step in the world frame for deformable ones: only the grid cells inside the overlap of the two
// bodies' boxes are visited, and each particle there looks up the few cells of the other body within its
// reach. No pair of bodies is searched particle against particle.

#include <cstdint>
#include <span>
#include <vector>

#include "collision/aabb.hpp"
#include "collision/broadphase.hpp"
#include "engine/core/body_store.hpp"
#include "engine/core/connector_store.hpp"
#include "engine/core/particle_store.hpp"
#include "engine/core/plane.hpp"

namespace volpar {

struct ParticleContact {
  ParticleId a;                ///< particle of the body with the lower id (or the one touching a plane)
  ParticleId b;                ///< particle of the other body; invalid for a plane contact
  PlaneId plane;               ///< valid for a plane contact
  Vec3 point = Vec3::Zero();   ///< midpoint of the overlap on the centre line, world [m]
  Vec3 normal = Vec3::UnitZ(); ///< unit centre-line direction from a towards b (into the plane), world
  double depth = 0.0;          ///< overlap along the centre line [m]; negative: the gap of a speculative contact
  [[nodiscard]] bool touching() const { return depth > 0.0; }
};

/// The contacts of one body pair, body-plane pair or deformable body with itself: a range of
/// ContactSet::contacts, sorted by (a, b).
struct ContactGroup {
  BodyId a;             ///< a < b for body pairs; a == b for self-contact
  BodyId b;             ///< invalid for a plane
  PlaneId plane;        ///< valid for a body-plane group
  std::uint32_t first = 0;
  std::uint32_t count = 0;
};

struct ContactSet {
  std::vector<ParticleContact> contacts;
  std::vector<ContactGroup> groups;
  void clear() {
    contacts.clear();
    groups.clear();
  }
};

class ContactFinder {
 public:
  /// Registers a body (after its particles and connectors were added to the stores).
  void addBody(BodyId id, const ParticleStore& particles, const BodyStore& bodies);
  /// Speculative reach as a fraction of r_a + r_b (0: touching pairs only).
  void setMargin(double fraction) { margin_ = fraction; }
  [[nodiscard]] double margin() const { return margin_; }
  /// Connector adjacency must be rebuilt (connectors added or broken).
  void connectorsChanged() { adjacencyDirty_ = true; }
  /// Rebuilds the connector adjacency now (after connectors broke).
  void refreshAdjacency(const ParticleStore& particles, const ConnectorStore& connectors) {
    rebuildAdjacency(particles, connectors);
  }

  /// Finds the contacts of the candidate pairs. `boxes` are the bodies' tight world boxes [B].
  void find(const ParticleStore& particles, const BodyStore& bodies, const ConnectorStore& connectors,
            std::span<const BodyPair> pairs, std::span<const BodyPlanePair> planePairs, std::span<const Plane> planes,
            std::span<const Aabb> boxes, ContactSet& out);

  /// Whether particles a and b (of one body) are joined by an unbroken connector.
  [[nodiscard]] bool connected(ParticleId a, ParticleId b) const;
  /// The particles joined to `p` by unbroken connectors, ascending (valid after find()).
  [[nodiscard]] std::span<const ParticleId> neighbours(ParticleId p) const {
    if (p.index() + 1 >= adjacencyStart_.size()) return {};
    return {adjacency_.data() + adjacencyStart_[p.index()], adjacency_.data() + adjacencyStart_[p.index() + 1]};
  }

 private:
  /// Uniform grid over one body's particle centres, in the body frame (rigid, static) or world frame
  /// (deformable). Cells are `cell` wide starting at `origin`; cellStart has nx*ny*nz + 1 entries.
  struct BodyGrid {
    Vec3 origin = Vec3::Zero();
    double cell = 1.0;
    Eigen::Vector3i dims = Eigen::Vector3i::Ones();
    std::vector<std::uint32_t> cellStart;
    std::vector<ParticleId> items;
    double maxRadius = 0.0;
    bool worldFrame = false;
  };

  void buildGrid(BodyGrid& g, std::span<const ParticleId> ids, const std::vector<Vec3>& coords,
                 const ParticleStore& particles);
  void rebuildAdjacency(const ParticleStore& particles, const ConnectorStore& connectors);
  /// Visits the particles of grid body `g` whose cells overlap the world box `box` (expanded by reach).
  template <class F>
  void forCells(const BodyGrid& g, const BodyState& s, const Aabb& box, F&& f) const;
  void bodyPair(const ParticleStore& particles, const BodyStore& bodies, BodyId a, BodyId b,
                std::span<const Aabb> boxes, ContactSet& out) const;
  void selfContacts(const ParticleStore& particles, BodyId id, ContactSet& out) const;
  void planeContacts(const ParticleStore& particles, const BodyStore& bodies, BodyId id, PlaneId plane,
                     const Plane& pl, ContactSet& out) const;

  std::vector<BodyGrid> grids_;  // by body index
  std::vector<BodyId> deformables_;
  std::vector<std::uint32_t> adjacencyStart_;  // CSR over particles [P + 1]
  std::vector<ParticleId> adjacency_;          // sorted per particle
  bool adjacencyDirty_ = true;
  double margin_ = 0.0;
  std::vector<std::uint32_t> fill_;  // counting-sort scratch, reused
};

}  // namespace volpar
