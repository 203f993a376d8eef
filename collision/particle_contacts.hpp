#pragma once
// Particle contacts (docs/architecture.md): every pair of touching particles of two different bodies, of a
// body and a plane, and of non-neighbouring particles of one deformable body.
//
// Two particles touch when |x_b - x_a| < r_a + r_b, tested on world positions; a particle touches a plane
// when its centre is less than its radius above it. Pairs that are within a small margin of touching
// (`setMargin`, a fraction of r_a + r_b) are reported too, as speculative contacts with a negative depth:
// they keep a resting contact set stable (a stack rocking by a hair does not lose and regain contacts) and
// let the solver stop an approaching pair exactly at contact. Fast bodies reach farther: with a step time
// (`setSweepTime`), a pair of bodies that could close more than that margin within the step (their
// relative speed plus each one's spin times its extent, times the step) reports every particle pair
// that close, so that the solver sees a wall before a particle can jump through it in one step
// (speculative contacts as continuous collision, after Box2D v3 and Jolt). Inside a candidate body pair the search goes through
// a uniform grid of each body's particles, built once in the body frame for rigid and static bodies and
// every step in the world frame for deformable ones: only the grid cells inside the overlap of the two
// bodies' boxes are visited, and each particle there looks up the few cells of the other body within its
// reach. No pair of bodies is searched particle against particle.
//
// Temporal coherence: for a pair of rigid or static bodies the search also lists every particle pair
// within the reach plus a skin of a quarter of the largest sum of radii, with the bodies' relative pose.
// While B has moved relative to A by less than the skin (rotation x B's extent + translation, a bound on
// how far any particle pair's distance can have changed), no pair outside the list can have come within
// reach, so the next steps test only the listed pairs: the same contacts, in the same order, as a fresh
// search. A resting pile then costs a distance test per listed pair.
//
// Across processes (`setProcesses`, docs/distributed.md): each process searches a contiguous share of the
// body pairs, of the bodies' plane pairs and of the deformable bodies' self-contacts, keeping the candidate
// lists of its own pairs only, and the processes then hand each other the particle pairs they found (two ids
// each). Every process computes the contacts of every pair from those ids with the search's own arithmetic,
// in the search's order, so each holds the contacts one process alone would find, bit for bit. A pair whose
// list another process keeps is searched afresh, which finds the same contacts.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/paced_split.hpp"
#include "volpar/collision/aabb.hpp"
#include "volpar/collision/broadphase.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/plane.hpp"
#include "volpar/engine/core/process_group.hpp"
#include "volpar/engine/core/thread_pool.hpp"

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
  LargeVector<ParticleContact> contacts;
  LargeVector<ContactGroup> groups;
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
  /// The step [s] over which a pair's relative motion widens its reach (0: the margin alone).
  void setSweepTime(double dt) { sweepTime_ = dt; }
  /// Shares later searches with other processes, each finding the contacts of the same pairs (nullptr: this
  /// process alone). The group stays the caller's.
  void setProcesses(ProcessGroup* processes) { processes_ = processes; }
  [[nodiscard]] ProcessGroup* processes() const { return processes_; }
  /// Connector adjacency must be rebuilt (connectors added or broken).
  void connectorsChanged() { adjacencyDirty_ = true; }
  /// Rebuilds the connector adjacency now (after connectors broke).
  void refreshAdjacency(const ParticleStore& particles, const ConnectorStore& connectors) {
    rebuildAdjacency(particles, connectors);
  }

  /// Finds the contacts of the candidate pairs. `boxes` are the bodies' tight world boxes [B]. `pool`
  /// (optional) shares the body pairs among threads; the result does not depend on it.
  void find(const ParticleStore& particles, const BodyStore& bodies, const ConnectorStore& connectors,
            std::span<const BodyPair> pairs, std::span<const BodyPlanePair> planePairs, std::span<const Plane> planes,
            std::span<const Aabb> boxes, ContactSet& out, ThreadPool* pool = nullptr);
  /// Keep candidate particle pairs of rigid body pairs between steps (on by default; see the class notes).
  void setReuse(bool reuse) {
    reuse_ = reuse;
    if (!reuse) cache_.clear();
  }
  /// Body pairs whose candidate lists were reused in the last find() (by this process).
  [[nodiscard]] std::size_t reusedPairs() const { return reusedPairs_; }

  /// Whether particles a and b (of one body) are joined by an unbroken connector.
  [[nodiscard]] bool connected(ParticleId a, ParticleId b) const;
  /// The connector adjacency as compressed rows over all particles: the neighbours of particle i are
  /// adjacencyList()[adjacencyStart()[i] .. adjacencyStart()[i + 1]) (valid after find() or refreshAdjacency()).
  [[nodiscard]] std::span<const std::uint32_t> adjacencyStart() const { return adjacencyStart_; }
  [[nodiscard]] std::span<const ParticleId> adjacencyList() const { return adjacency_; }
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
    LargeVector<std::uint32_t> cellStart;
    LargeVector<ParticleId> items;
    double maxRadius = 0.0;
    bool worldFrame = false;
  };

  void buildGrid(BodyGrid& g, std::span<const ParticleId> ids, std::span<const Vec3> coords,
                 const ParticleStore& particles);
  void rebuildAdjacency(const ParticleStore& particles, const ConnectorStore& connectors);
  /// Visits the particles of grid body `g` whose cells overlap the world box `box` (expanded by reach).
  template <class F>
  void forCells(const BodyGrid& g, const BodyState& s, const Aabb& box, F&& f) const;
  /// Candidate particle pairs of a rigid or static body pair: every pair closer than the speculative reach
  /// plus `skin` when they were listed, with B's pose in A's frame at that time.
  struct PairList {
    std::uint32_t a = 0, b = 0;                   // body indices (the key)
    Quat relRotation = Quat::Identity();
    Vec3 relPosition = Vec3::Zero();
    double skin = 0.0;
    double sweep = 0.0;                           // the reach beyond the margin the list was made with [m]
    std::uint32_t first = 0, count = 0;           // range in PairCache::pairs
  };
  struct PairCache {
    LargeVector<PairList> lists;                  // sorted by (a, b)
    LargeVector<std::pair<ParticleId, ParticleId>> pairs;
    void clear() {
      lists.clear();
      pairs.clear();
    }
  };
  /// Output and cache of one chunk of the body pairs (and of the planes' pairs), merged in order afterwards.
  /// (A cache line of its own: two threads filling neighbouring chunks must not share one.)
  struct alignas(64) Chunk {
    ContactSet out;     // of body pairs
    ContactSet planes;  // of bodies on planes
    PairCache cache;
    // where the outputs go in the merged set
    std::size_t contactBase = 0, groupBase = 0, planeContactBase = 0, planeGroupBase = 0, listBase = 0, pairBase = 0;
    std::vector<std::pair<ParticleId, ParticleId>> found;
    std::array<std::vector<ParticleId>, 2> near;  // searchPair()'s scratch
    LargeVector<std::uint32_t> hits;              // a reused list's pairs within reach (bodyPair()'s scratch)
    std::size_t reused = 0;
    std::size_t cursor = 0;  // the last step's lists are walked in step with the (sorted) body pairs
    bool inOrder = true;     // the chunk's body pairs came in key order
  };

  /// How much farther than the margin [m] a pair of particles of bodies a and b (b invalid: a plane of
  /// normal n) can close within the sweep time.
  [[nodiscard]] double sweepReach(BodyId a, BodyId b, const Vec3& n = Vec3::Zero()) const;
  /// Grid search of a body pair: contacts within the reach plus `sweep` into `out` (unsorted); with
  /// `listed`, every pair within that plus `skin` into it as well.
  /// (Two bodies of at most kFewParticles particles each are searched pair by pair among the particles that
  /// reach the other's box, which finds the same pairs as the grids at less cost; `near` is the scratch.)
  void searchPair(const ParticleStore& particles, const BodyStore& bodies, BodyId a, BodyId b, std::span<const Aabb> boxes,
                  double sweep, double skin, ContactSet& out, std::vector<std::pair<ParticleId, ParticleId>>* listed,
                  std::array<std::vector<ParticleId>, 2>& near) const;
  static constexpr std::size_t kFewParticles = 64;
  void bodyPair(const ParticleStore& particles, const BodyStore& bodies, BodyId a, BodyId b,
                std::span<const Aabb> boxes, Chunk& w) const;
  /// The contacts of the given pairs (this process's share) into `out`: body pairs' groups, then planes',
  /// then self-contacts'. Returns the number of body pairs' groups and of planes' groups.
  std::pair<std::size_t, std::size_t> search(const ParticleStore& particles, const BodyStore& bodies,
                                             std::span<const BodyPair> pairs, std::span<const BodyPlanePair> planePairs,
                                             std::span<const Plane> planes, std::span<const BodyId> deformables,
                                             std::span<const Aabb> boxes, ContactSet& out, ThreadPool* pool);
  /// Every process's share, searched into `mine`, handed to every process and made into the contacts
  /// of all pairs, in the order of one process's search.
  void gatherShares(const ParticleStore& particles, std::span<const Plane> planes, const ContactSet& mine,
                    std::size_t bodyGroups, std::size_t planeGroups, ContactSet& out, ThreadPool* pool);
  /// The next step's division of the body pairs (boundary_), from every process's search time in this one.
  void moveBoundaries();
  void selfContacts(const ParticleStore& particles, BodyId id, ContactSet& out) const;
  void planeContacts(const ParticleStore& particles, const BodyStore& bodies, BodyId id, PlaneId plane,
                     const Plane& pl, ContactSet& out) const;

  LargeVector<BodyGrid> grids_;  // by body index
  LargeVector<double> extent_;   // by body index: farthest particle centre from the body's origin [m]
  /// A body's particles as the searches walk them (by body index): a run of consecutive ids, read without the
  /// body's list of ids, or that list
  LargeVector<ParticleRun> runs_;
  /// Calls f(particle) for each of body `id`'s particles, ascending.
  template <class F>
  void forParticles(const BodyStore& bodies, BodyId id, F&& f) const {
    const ParticleRun& r = runs_[id.index()];
    if (r.consecutive) {
      for (std::uint32_t i = r.first; i < r.first + r.count; ++i) f(ParticleId(i));
    } else {
      for (const ParticleId q : bodies.info[id.index()].particles) f(q);
    }
  }
  /// What a search reads of each body for every pair it is in, gathered once per find() (by body index).
  struct BodyMotion {
    Vec3 velocity = Vec3::Zero();  // linear [m/s]
    double spin = 0.0;             // angular speed times the extent: the fastest its particles turn [m/s]
    double margin = 0.0;           // the speculative margin times its largest radius [m]
    bool worldFrame = false;       // its grid is in the world frame (a deformable body)
  };
  LargeVector<BodyMotion> motion_;
  void gatherMotion(const BodyStore& bodies, ThreadPool* pool);
  bool reuse_ = true;
  PairCache cache_;              // candidate lists of the last find(), for the next
  LargeVector<Chunk> chunks_;
  PacedSplit pairSplit_;  // the body pairs' ranges of the workers, and their pieces (the chunks)
  std::size_t reusedPairs_ = 0;
  LargeVector<BodyId> deformables_;
  LargeVector<std::uint32_t> adjacencyStart_;  // CSR over particles [P + 1]
  LargeVector<ParticleId> adjacency_;          // sorted per particle
  bool adjacencyDirty_ = true;
  double margin_ = 0.0;
  double sweepTime_ = 0.0;
  LargeVector<std::uint32_t> fill_;  // counting-sort scratch, reused
  // across processes: this process's share of the contacts, what travels, and what arrived (kept between steps)
  ProcessGroup* processes_ = nullptr;
  ContactSet mine_;
  LargeVector<std::pair<ParticleId, ParticleId>> ids_;
  ExchangeBytes bytes_, gathered_;
  struct ShareHeader {
    std::uint64_t bodyGroups = 0, planeGroups = 0;  // the groups of body pairs, then of planes, lead
    double seconds = 0.0;                           // its search's
  };
  struct Share {
    ShareHeader header;
    LargeVector<ContactGroup> groups;
    LargeVector<std::pair<ParticleId, ParticleId>> ids;
  };
  LargeVector<Share> shares_;
  LargeVector<std::uint32_t> fromShare_, fromFirst_;  // per group of the whole set: its process and first id
  LargeVector<double> boundary_;  // where each process's share of the body pairs starts, as a fraction [R + 1]
  LargeVector<double> pace_;      // scratch of moveBoundaries()
  double searchSeconds_ = 0.0;
};

}  // namespace volpar
