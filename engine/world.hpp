#pragma once
// The World owns every store and runs the step pipeline (docs/architecture.md, The step). Collision detection runs at
// the end of a step, on the positions the step produced, so that contacts() always describes the current
// state (what a trajectory frame or a cross-check sees) and the next step's solver uses it:
//   1. integrate velocities (gravity)
//   2. contact response (the solver)
//   3. integrate positions (rigid poses; deformable particles by XPBD substeps), particle world positions
//   4. broadphase (dynamic AABB trees) -> body pairs
//   5. particle contacts in each body pair, body-plane pair and deformable body
// Over a run this is the same sequence as detection-then-response inside each step. A step allocates
// nothing once the world is built (buffers keep their capacity), and never writes files: a Runner
// watches the world and writes trajectory frames.

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/collision/broadphase.hpp"
#include "volpar/collision/narrow_phase.hpp"
#include "volpar/collision/normal_cache.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/collision/polytope_cores.hpp"
#include "volpar/dynamics/bond_loads.hpp"
#include "volpar/dynamics/breakage.hpp"
#include "volpar/dynamics/deformable_integrator.hpp"
#include "volpar/engine/builders/particle_cloud.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/material.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/state_archive.hpp"
#include "volpar/engine/core/status.hpp"
#include "volpar/engine/core/step_stats.hpp"
#include "volpar/engine/world_settings.hpp"

namespace volpar {

/// How to turn a ParticleCloud into a body.
struct BodyDef {
  std::string name;
  BodyKind kind = BodyKind::Rigid;
  MaterialId material;
  Vec3 position = Vec3::Zero();            ///< origin of the shape frame, world [m]
  Quat orientation = Quat::Identity();     ///< shape frame -> world
  Vec3 linearVelocity = Vec3::Zero();      ///< of the centre of mass, world [m/s]
  Vec3 angularVelocity = Vec3::Zero();     ///< world [rad/s]
  ConnectorParams connectors;              ///< rods for rigid and static bodies
  std::optional<double> particleMass;      ///< [kg] per particle; default density x particle volume
  std::optional<double> totalMass;         ///< [kg] spread evenly over the particles
  SourceShape source;                      ///< the primitive the cloud was filled from, if any
  MassModel massModel = MassModel::Solid;  ///< Solid applies where the cloud has a solid (ParticleCloud::solid)
};

/// How a connector broke.
enum class BreakMode : std::uint8_t {
  Tension,      ///< a rod's tension above its strength, a bond's tensile stress above its tensile strength
  Compression,  ///< a rod's compression above its compressive strength
  Shear,        ///< a bond's shear stress above its shear strength
  Strain,       ///< a spring's strain above its limit
};

/// A connector that broke.
struct BreakEvent {
  std::int64_t step = 0;   ///< the step in which it broke (1 = the first)
  ConnectorId connector;
  ParticleId a, b;
  BodyId body;             ///< the body it belonged to
  ConnectorKind kind = ConnectorKind::Rod;
  /// rods: the force it carried [N]; springs: its strain [-]; bonds: the stress that broke it [Pa]
  double value = 0.0;
  BreakMode mode = BreakMode::Tension;
  double energy = 0.0;     ///< bonds: the elastic energy it held [J] (0 for rods and springs)
};

/// The fragments of a moment: the alive bodies that can break or broke off one (BodyInfo::breakable), by
/// their particle count.
struct FragmentHistogram {
  static constexpr std::size_t kBins = 32;  ///< bin k holds fragments of 2^k to 2^(k+1) - 1 particles
  std::size_t count = 0;                    ///< fragments
  std::size_t singles = 0;                  ///< fragments of one particle
  std::size_t largest = 0;                  ///< particles in the largest fragment
  std::size_t particles = 0;                ///< particles in all of them
  std::array<std::int64_t, kBins> bodies{}; ///< fragments per bin
  std::array<double, kBins> mass{};         ///< their mass per bin [kg]
};

/// How World::glue joins bodies into one.
struct GlueDef {
  std::string name;            ///< the glued body's name
  ConnectorParams bonds;       ///< the glue's bonds (kind Bond)
  /// Particles of different bodies whose centres are closer than reach x (r_a + r_b) are bonded [-]
  double reach = 1.5;
  /// If not empty, only these pairs of the bodies are glued to each other (indices into the bodies given)
  LargeVector<std::array<std::uint32_t, 2>> pairs;
};

/// Energies of the whole world [J].
struct EnergyReport {
  double kinetic = 0.0;
  double potential = 0.0;  ///< gravitational (relative to the origin) plus elastic
  [[nodiscard]] double total() const { return kinetic + potential; }
};

class World {
 public:
  explicit World(const WorldSettings& settings);

  MaterialId addMaterial(const Material& material);
  void addPlane(const Plane& plane);
  /// Creates a body from a builder's cloud. Fails on an empty cloud or a non-positive mass.
  Result<BodyId> addBody(const BodyDef& def, const ParticleCloud& cloud);

  /// Glues rigid bodies whose connectors are bonds (or single particles) into one rigid body: the touching
  /// particles of different bodies are joined by bonds of `def.bonds`. The bodies are retired (retired step:
  /// the current step) and the glued body takes their particles, connectors and mass properties, and the
  /// first body's material. Fails where a body is not rigid, has rods or springs, or touches none of the
  /// others it is glued to.
  Result<BodyId> glue(std::span<const BodyId> bodies, const GlueDef& def);

  /// Advances the world by settings().dt.
  StepStatus step();
  /// Worker threads for later steps (1 = run on the calling thread only); results do not depend on it.
  /// Work too small to be worth waking the workers runs on the calling thread, unless `shareAll`.
  void setThreads(int threads, bool shareAll = false);
  /// Shares the work of later steps with other processes, each stepping this same world
  /// (docs/distributed.md): the particle contacts' pairs, the narrow phase's contact groups and the contact
  /// solver's iterations; null: none. The trajectory is the same bit for bit.
  void setProcesses(ProcessGroup* processes);

  [[nodiscard]] const WorldSettings& settings() const { return settings_; }
  [[nodiscard]] const ParticleStore& particles() const { return particles_; }
  [[nodiscard]] const BodyStore& bodies() const { return bodies_; }
  [[nodiscard]] const ConnectorStore& connectors() const { return connectors_; }
  [[nodiscard]] const NormalCache& normals() const { return normals_; }
  /// The whole polytope cores of the rigid and static bodies that have one (polytope_cores.hpp).
  [[nodiscard]] const PolytopeCores& polytopeCores() const { return cores_; }
  [[nodiscard]] const std::vector<Material>& materials() const { return materials_; }
  [[nodiscard]] const std::vector<Plane>& planes() const { return planes_; }
  [[nodiscard]] const StepStats& stats() const { return stats_; }
  [[nodiscard]] double time() const { return static_cast<double>(stepIndex_) * settings_.dt; }
  /// Contacts of the current state (call refreshContacts() after adding bodies).
  [[nodiscard]] const ContactSet& contacts() const { return contacts_; }
  /// Candidate body pairs and body-plane pairs of the current state, sorted.
  [[nodiscard]] std::span<const BodyPair> bodyPairs() const { return broadphase_.pairs(); }
  [[nodiscard]] std::span<const BodyPlanePair> planePairs() const { return broadphase_.planePairs(); }
  /// Tight world boxes of the bodies' particle spheres [B].
  [[nodiscard]] const std::vector<Aabb>& bodyBoxes() const { return bodyBoxes_; }
  [[nodiscard]] const Broadphase& broadphase() const { return broadphase_; }
  [[nodiscard]] const ContactFinder& contactFinder() const { return contactFinder_; }
  /// Contact patches with their separating planes, for the current contacts.
  [[nodiscard]] const PatchSet& patches() const { return patches_; }
  /// What the narrow phase reads from this world.
  [[nodiscard]] NarrowPhaseInput narrowPhaseInput() const;
  /// Runs collision detection on the current state (done by step(); needed after adding bodies).
  void refreshContacts();
  /// Recomputes the cached normals of exactly these particles from their connector neighbourhood
  /// (NormalUpdater in collision/normal_cache.hpp); counted in stats().normalsRecomputed.
  std::size_t recomputeNormals(std::span<const ParticleId> ids);
  /// The fragments now.
  [[nodiscard]] FragmentHistogram fragments() const;
  /// The elastic energy the bonds that broke so far held when they broke [J].
  [[nodiscard]] double breakageEnergy() const { return breakageEnergy_; }
  /// Connectors that broke in the last step.
  [[nodiscard]] const std::vector<BreakEvent>& breakEvents() const { return breakEvents_; }
  /// The connectors of a body (broken ones included).
  [[nodiscard]] std::span<const ConnectorId> bodyConnectors(BodyId id) const { return bodyConnectors_[id.index()]; }
  [[nodiscard]] std::int64_t stepIndex() const { return stepIndex_; }

  /// World-frame outward normal of a surface particle (zero for interior particles).
  [[nodiscard]] Vec3 particleNormal(ParticleId id) const;
  [[nodiscard]] EnergyReport energy() const;
  /// Total linear momentum [kg m/s] and angular momentum about the origin [kg m^2/s].
  [[nodiscard]] Vec3 linearMomentum() const;
  [[nodiscard]] Vec3 angularMomentum() const;

  /// Mutable access for tests and tools that set up states directly (never during a step). Particles of
  /// rigid and static bodies follow their body: syncParticles() overwrites them.
  [[nodiscard]] BodyState& bodyState(BodyId id) { return bodies_.state[id.index()]; }
  [[nodiscard]] ParticleStore& editParticles() { return particles_; }
  /// Recomputes particle positions and velocities of rigid bodies from their body states.
  void syncParticles();

  /// Puts everything the next step depends on into `archive` (a checkpoint; world_state.cpp): the stores,
  /// the normal cache, the broken connectors' traces, the bond frames' history, the contacts and patches of
  /// the current state, the narrow phase's reuse cache, the broadphase's fat boxes and the solver's
  /// warm-starting impulses. Caches that only make a step faster, and give the same results without their
  /// history (the particle contacts' candidate lists), are left out.
  void saveState(StateArchive& archive) const;
  /// Takes a saved state back into a world built from the same scene (the same settings, materials, planes
  /// and bodies as the saving world had at its start): its later steps are bit for bit those of the world
  /// that saved it, for any thread count. A state that does not fit the world (other counts, indices out of
  /// range, an inconsistent cache) is refused with the reason; a world whose restore failed is to be
  /// discarded.
  Status restoreState(const StateArchive& archive);

 private:
  /// Runs one stage of the step, its time into stats_.time.*stage and its exchanges' into
  /// stats_.exchangeTime.*stage.
  template <class Stage>
  void timeStage(double StageTimes::*stage, const Stage& run);
  /// The processes' seconds in exchanges so far (0 without processes).
  [[nodiscard]] double exchangeSeconds() const;
  void integrateVelocities();
  void solveContacts();
  /// Rolling resistance of the last solve's patches, on the solver bodies' velocities.
  void resistRolling();
  /// The materials meeting at a contact: particle a's body's and particle b's body's (or the plane's).
  [[nodiscard]] std::pair<const Material*, const Material*> contactMaterials(ParticleId a, ParticleId b,
                                                                             PlaneId plane) const;
  /// The same from the bodies on a patch's two sides (body b invalid: the plane's): a patch's contacts all
  /// join particles of those two bodies, so this skips looking up each particle's body.
  [[nodiscard]] std::pair<const Material*, const Material*> contactMaterials(BodyId a, BodyId b, PlaneId plane) const;
  void buildContactPoints();
  /// The solver-body slot a particle's contacts use (its rigid body's, or its own for a deformable
  /// body's); null for static bodies. kFixed in it: not yet a solver body this step.
  std::uint32_t* solverSlot(ParticleId p);
  /// The particle's solver body, named on first use this step (kFixed for static bodies); its contents are
  /// made by makeSolverBodies().
  std::uint32_t solverIndex(ParticleId p);
  /// A rigid body's solver body, named on first use this step.
  std::uint32_t rigidSolverIndex(BodyId b);
  /// The contents of the solver bodies named this step, from their owners' state.
  void makeSolverBodies();
  void integratePositions();
  void applyBreakage();
  void splitBody(BodyId parent, std::span<const std::uint32_t> component, std::size_t components);
  /// Moves `ids` into body `id`, whose principal frame has its origin at `centre` and axes `axes` (world),
  /// turning each cached normal from its old body's frame to the new one's.
  void moveParticles(std::span<const ParticleId> ids, BodyId id, const Vec3& centre, const Quat& axes);
  /// Adds a rigid body whose particles were moved into it (moveParticles), with its connectors, and makes it
  /// take part: broadphase, contacts, breakage.
  /// Adds a rigid body and, where `lattice`, the lattice or frame of its breakable connectors (a split's
  /// largest piece keeps its parent's frame instead).
  BodyId addRigidBody(const BodyState& state, BodyInfo info, std::vector<ConnectorId> connectors, bool lattice = true);
  /// Retires a rigid body at `step` (it broke apart or was glued): it keeps its id and history, but no
  /// particles, motion or lattice.
  void retireBody(BodyId id, std::int64_t step);
  /// Adds a connector; a bond gets its radius from its particles' and its strengths drawn (Weibull) from the
  /// seed and its index.
  ConnectorId addConnector(ParticleId a, ParticleId b, double rest, const ConnectorParams& params);
  /// Makes the loads model of a rigid body from its unbroken connectors (rods or bonds), where any can break.
  void buildLattice(BodyId id);
  [[nodiscard]] bool breakable(BodyId id) const { return rodForces_[id.index()] || bondLoads_[id.index()]; }
  void recomputeNormalsAround(std::span<const ParticleId> seeds, int rings);
  /// Seeds the particles around deformable connectors that stretched or turned since their normals were
  /// last estimated.
  void seedDeformedNormals();
  void detectCollisions();
  /// The broadphase: bodies whose boxes left their fat boxes moved, and the body and plane pairs found.
  void findBodyPairs();
  template <class Pose>
  void shareRigidPoses(const Pose& pose);
  void updateRigidParticles(BodyId id);
  [[nodiscard]] bool finiteState() const;
  void updateDeformableBodyStates();
  void updateDeformableBodyState(BodyId id);

  WorldSettings settings_;
  std::vector<Material> materials_;
  std::vector<Plane> planes_;
  ParticleStore particles_;
  ConnectorStore connectors_;
  BodyStore bodies_;
  NormalCache normals_;
  NormalUpdater normalUpdater_;
  PolytopeCores cores_;                           // the rigid and static bodies' whole polytope cores
  std::vector<std::uint8_t> opened_;              // [P] 1 where a particle lost a connector (a crack face)
  LargeVector<Vec3> connectorDirection_;          // [C] deformable connectors: direction in the body frame
                                                  // when their particles' normals were last estimated
  Broadphase broadphase_;
  ContactFinder contactFinder_;
  std::vector<Aabb> bodyBoxes_;
  ContactSet contacts_;
  NarrowPhase narrowPhase_;
  PatchSet patches_;
  ContactSolver solver_;
  LargeVector<SolverBody> solverBodies_;
  LargeVector<ContactPointInput> contactPoints_;
  LargeVector<std::uint32_t> bodySolverIndex_;      // [B], kFixed when not in the solver this step
  LargeVector<std::uint32_t> particleSolverIndex_;  // [P], for particles of deformable bodies
  LargeVector<BodyId> solverBodyOwner_;             // per solver body: its rigid body (invalid: a particle)
  LargeVector<ParticleId> solverParticleOwner_;     // per solver body: its particle (invalid: a rigid body)
  LargeVector<Vec3> particleShift_;                 // [P] pseudo displacement of deformable particles
  LargeVector<DeformableContact> deformableContacts_;
  /// How a patch becomes contact points, as buildContactPoints() decides it for every patch at once (compact:
  /// the pass that names the solver bodies reads these alone, patch after patch)
  struct PatchPoints {
    BodyId a, b;               ///< the patch's bodies
    std::uint32_t kept = 0;    ///< how many of its contacts become points (keptContacts_)
    std::uint8_t mode = 0;     ///< how they do
    BodyKind kindA = BodyKind::Static, kindB = BodyKind::Static;  ///< its sides (a plane's: static)
  };
  LargeVector<PatchPoints> patchPoints_;            // per patch
  LargeVector<std::uint32_t> pointFirst_;           // per patch: its first contact point (and the end)
  LargeVector<std::uint32_t> keptContacts_;         // as PatchSet::contacts: each patch's contacts that become points
  std::vector<std::size_t> selectedFrom_;           // with processes: each one's first patch selected (and the end)
  std::vector<std::size_t> shareOffset_, shareCount_;  // with processes: the byte ranges of an exchange
  LargeVector<std::array<double, 10>> sharedPoses_;  // with processes: each rigid body's pose after the step
  /// per worker, per particle: whether it touches in the patch being made into points (0 between patches)
  LargeVector<std::vector<std::uint8_t>> touchingParticle_;
  LargeVector<std::pair<ParticleId, ParticleId>> pointParticles_;  // per contact point: its particles
  /// with processes: per contact point, its solver bodies (what the solver plans its division from, before
  /// the points of other processes' nodes are left unmade)
  LargeVector<std::pair<std::uint32_t, std::uint32_t>> pointBodies_;
  ProcessGroup* processes_ = nullptr;
  struct alignas(64) ContactTally {  // (one per worker, each on a cache line of its own)
    std::size_t touching = 0;
    double deepest = 0.0;
  };
  LargeVector<ContactTally> contactTally_;

  // breakage
  std::vector<std::vector<ConnectorId>> bodyConnectors_;    // [B]
  /// Each body's kind and material as in bodies_.info, kept compact for the lookups of every patch in the
  /// step (a BodyInfo takes several cache lines); written wherever a body is added or restored.
  LargeVector<BodyKind> bodyKinds_;            // [B]
  LargeVector<MaterialId> bodyMaterials_;      // [B]
  LargeVector<ParticleRun> bodyRuns_;          // [B] each body's particles as a run of ids, where they are one
  LargeVector<std::unique_ptr<RodForces>> rodForces_;       // [B], for rigid bodies with breakable rods
  LargeVector<std::unique_ptr<BondLoads>> bondLoads_;       // [B], for rigid bodies with breakable bonds
  LargeVector<BodyId> breakableRigid_;
  bool anyRollingResistance_ = false;  // (a material resists rolling)
  std::vector<Vec3> loads_;                                 // [P] loads on particles of breakable bodies [N]
  std::vector<double> rodForceScratch_;
  std::vector<BondLoad> bondLoadScratch_;
  struct Overload {
    ConnectorId connector;
    std::size_t entry = 0;  // its index in the body's lattice
    double ratio = 0.0;   // load over strength
    double value = 0.0;   // BreakEvent::value
    double energy = 0.0;
    BreakMode mode = BreakMode::Tension;
  };
  LargeVector<Overload> overloaded_;  // this pass's overloaded connectors of one body
  LargeVector<std::size_t> brokenEntries_;
  std::vector<std::uint32_t> changedBonds_;       // the entries a pass solved around its breaks changed
  LargeVector<std::uint8_t> bondChanged_;         // per entry of the body's frame, during a pass
  LargeVector<double> deformableForces_;                    // [C] XPBD connector forces [N]
  std::vector<BreakEvent> breakEvents_;
  double breakageEnergy_ = 0.0;
  std::unique_ptr<ThreadPool> pool_;  // null with one thread
  LargeVector<Vec3> deformableContactImpulses_;  // per deformable contact: what its particle got against a rigid body
  LargeVector<Vec3> deformableContactMoments_;   // (and the angular momentum about the origin)
  LargeVector<BodyId> touchedRigid_;
  LargeVector<ParticleId> seeds_, ringScratch_;
  LargeVector<std::uint32_t> ringMark_;
  std::uint32_t ringStamp_ = 0;
  bool contactsStale_ = true;
  double maxRadius_ = 0.0;

  // cached index lists, rebuilt when bodies are added
  LargeVector<BodyId> rigidBodies_;
  std::vector<std::uint8_t> leftFatBox_;  // scratch, by position in rigidBodies_: its box left its fat box
  LargeVector<BodyId> deformableBodies_;
  LargeVector<ParticleId> deformableParticles_;
  LargeVector<ConnectorId> deformableConnectors_;

  // scratch reused across steps (no allocation inside step())
  DeformableScratch scratch_;

  std::int64_t stepIndex_ = 0;
  StepStats stats_;
};

}  // namespace volpar
