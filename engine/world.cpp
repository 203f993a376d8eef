#include "volpar/engine/world.hpp"

#include <Eigen/SVD>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

#include "volpar/dynamics/contact_solver.hpp"
#include "volpar/dynamics/deformable_integrator.hpp"
#include "volpar/dynamics/mass_properties.hpp"
#include "volpar/dynamics/rigid_integrator.hpp"
#include "volpar/dynamics/rigid_particles.hpp"

namespace volpar {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

}  // namespace

World::World(const WorldSettings& settings) : settings_(settings) {
  setThreads(settings.threads);
  narrowPhase_.setSettings(settings.planes);
  SolverSettings solver = settings.solver;
  solver.iterations = settings.solverIterations;
  solver.positionIterations = settings.solverIterations;
  contactFinder_.setMargin(settings_.contactMargin);
  contactFinder_.setSweepTime(settings_.dt);
  solver_.setSettings(solver);
}

NarrowPhaseInput World::narrowPhaseInput() const {
  NarrowPhaseInput in;
  in.particles = &particles_;
  in.bodies = &bodies_;
  in.normals = &normals_;
  in.finder = &contactFinder_;
  in.planes = planes_;
  in.dt = settings_.dt;
  in.cores = &cores_;
  in.kinds = std::span<const BodyKind>(bodyKinds_.data(), bodyKinds_.size());
  return in;
}

MaterialId World::addMaterial(const Material& material) {
  materials_.push_back(material);
  anyRollingResistance_ = anyRollingResistance_ || material.rollingResistance > 0.0;
  return MaterialId(materials_.size() - 1);
}

void World::addPlane(const Plane& plane) {
  Plane p = plane;
  p.normal.normalize();
  planes_.push_back(p);
}

Result<BodyId> World::addBody(const BodyDef& def, const ParticleCloud& cloud) {
  const std::size_t n = cloud.size();
  if (n == 0) return Error{"", 0, 0, "body '" + def.name + "' has no particles"};
  if (!def.material.valid() || def.material.index() >= materials_.size())
    return Error{"", 0, 0, "body '" + def.name + "' refers to an unknown material"};
  const Material& material = materials_[def.material.index()];
  if (def.connectors.kind == ConnectorKind::Bond) {
    if (def.kind == BodyKind::Deformable)
      return Error{"", 0, 0, "body '" + def.name + "' is deformable; bonds join the particles of rigid bodies (deformable ones take springs or rods)"};
    if (!(def.connectors.bond.youngsModulus > 0.0) || !std::isfinite(def.connectors.bond.youngsModulus))
      return Error{"", 0, 0, "body '" + def.name + "' has bonds without a positive Young's modulus"};
  }
  // input a step could not survive: non-finite values, absurd sizes
  constexpr double kWorldLimit = 1e9;  // [m]
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 x = def.position + def.orientation * cloud.positions[i];
    if (!x.allFinite() || x.cwiseAbs().maxCoeff() > kWorldLimit)
      return Error{"", 0, 0, "body '" + def.name + "' has a particle at a non-finite or too distant position; expected coordinates within 1e9 m"};
    const double r = cloud.radii[i];
    if (!(r > 0.0) || !(r <= kWorldLimit))
      return Error{"", 0, 0, "body '" + def.name + "' has a particle radius of " + std::to_string(r) + " m; expected a positive, finite radius"};
  }
  if (!def.position.allFinite() || !def.linearVelocity.allFinite() || !def.angularVelocity.allFinite() ||
      !def.orientation.coeffs().allFinite())
    return Error{"", 0, 0, "body '" + def.name + "' has a non-finite pose or velocity"};

  // particle masses: explicit, or density x the volume each particle stands for
  std::vector<double> masses(n);
  for (std::size_t i = 0; i < n; ++i) {
    if (def.totalMass) masses[i] = *def.totalMass / static_cast<double>(n);
    else if (def.particleMass) masses[i] = *def.particleMass;
    else masses[i] = material.density * cloud.volumes[i];
    if (!(masses[i] > 0.0) || !std::isfinite(masses[i]))
      return Error{"", 0, 0, "body '" + def.name + "' would get a particle mass of " + std::to_string(masses[i]) +
                                 " kg; expected a positive, finite mass"};
  }

  // each particle's own moment: its lattice cell's, or its sphere's
  std::vector<double> own(n);
  for (std::size_t i = 0; i < n; ++i)
    own[i] = i < cloud.ownInertia.size() ? masses[i] * cloud.ownInertia[i] : sphereMoment(masses[i], cloud.radii[i]);
  MassProperties mp = computeMassProperties(cloud.positions, masses, own);
  // a rigid body filled from a solid takes the solid's inertia, moved to the particles' centre of mass (where
  // the fill is symmetric, as for the primitives on the cubic lattice, the two centres coincide); what that adds
  // to the particles' own is kept, so that fragments inherit their share of it
  Mat3 residual = Mat3::Zero();
  if (def.kind != BodyKind::Deformable && def.massModel == MassModel::Solid && cloud.solid && cloud.solid->volume > 0.0) {
    const double density = mp.mass / cloud.solid->volume;
    const Vec3 d = mp.centre - cloud.solid->centroid;
    const Mat3 solid = density * cloud.solid->inertia + mp.mass * (d.squaredNorm() * Mat3::Identity() - d * d.transpose());
    residual = solid - mp.inertia;
    mp.inertia = solid;
  }
  const PrincipalAxes axes = principalAxes(mp.inertia);

  BodyInfo info;
  info.name = def.name;
  info.kind = def.kind;
  info.material = def.material;
  info.mass = mp.mass;
  info.inertiaLocal = axes.moments;
  info.principalInShape = axes.rotation;
  info.comInShape = mp.centre;
  {
    const Mat3 r = axes.rotation.toRotationMatrix();
    info.inertiaResidual = r.transpose() * residual * r;
  }
  info.source = def.source;
  info.core = fittedCore(def.source, cloud.positions);

  BodyState state;
  state.orientation = (def.orientation * axes.rotation).normalized();
  state.position = def.position + def.orientation * mp.centre;
  if (def.kind != BodyKind::Static) {
    state.linearVelocity = def.linearVelocity;
    state.angularVelocity = def.angularVelocity;
    state.invMass = 1.0 / mp.mass;
  }
  if (def.kind == BodyKind::Rigid) {
    state.invInertiaLocal = axes.moments.cwiseInverse();
    updateWorldInertia(state);
  }

  const BodyId id(bodies_.size());
  const ParticleId first = particles_.grow(n);
  info.particles.reserve(n);
  const Quat toPrincipal = axes.rotation.conjugate();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t p = first.index() + i;
    info.particles.emplace_back(p);
    particles_.radius[p] = cloud.radii[i];
    particles_.mass[p] = masses[i];
    particles_.ownInertia[p] = own[i];
    const bool pinned = def.kind == BodyKind::Deformable && i < cloud.pinned.size() && cloud.pinned[i];
    particles_.invMass[p] = def.kind == BodyKind::Static || pinned ? 0.0 : 1.0 / masses[i];
    particles_.body[p] = id;
    particles_.local[p] = toPrincipal * (cloud.positions[i] - mp.centre);
    if (cloud.flags[i]) {
      particles_.flags[p] = static_cast<std::uint8_t>(cloud.flags[i] | kParticleSurface);
      // in the body's principal frame (for deformable bodies: the frame of their rest shape, which follows the
      // body's best-fit rotation)
      const Quat toCache = toPrincipal;
      const std::uint8_t features = i < cloud.features.size() ? cloud.features[i] : 0;
      std::array<Vec3, 3> faces{};
      std::size_t nf = 0;
      if (i < cloud.featureNormals.size())
        for (; nf < std::min<std::size_t>(features, 3); ++nf) faces[nf] = toCache * cloud.featureNormals[i][nf];
      // (a rigid or static body's entries are shared with equal ones; a deformable body's are its own, since
      // they are rewritten as it bends)
      const Vec3 normal = toCache * cloud.normals[i];
      const std::span<const Vec3> f(faces.data(), nf);
      particles_.normalIndex[p] = def.kind == BodyKind::Deformable ? normals_.add(normal, f) : normals_.addShared(normal, f);
    }
  }
  bodyConnectors_.emplace_back();
  ConnectorParams params = def.connectors;
  for (std::size_t k = 0; k < cloud.connectors.size(); ++k) {
    const auto& c = cloud.connectors[k];
    const ParticleId a(first.index() + c[0]);
    const ParticleId b(first.index() + c[1]);
    const double rest = (cloud.positions[c[1]] - cloud.positions[c[0]]).norm();
    if (k < cloud.connectorStiffness.size()) params.stiffness = cloud.connectorStiffness[k];
    const ConnectorId cid = addConnector(a, b, rest, params);
    bodyConnectors_.back().push_back(cid);
    connectorDirection_.resize(connectors_.size(), Vec3::Zero());
    if (def.kind == BodyKind::Deformable) {
      deformableConnectors_.push_back(cid);
      connectorDirection_[cid.index()] = (particles_.local[b.index()] - particles_.local[a.index()]).normalized();
    }
  }
  bodies_.add(state, std::move(info));
  bodyKinds_.push_back(bodies_.info.back().kind);
  bodyMaterials_.push_back(bodies_.info.back().material);
  bodyRuns_.push_back(runOf(bodies_.info.back().particles));
  rodForces_.emplace_back();
  bondLoads_.emplace_back();
  bodyBoxes_.emplace_back();

  if (def.kind == BodyKind::Deformable) {
    deformableBodies_.push_back(id);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t p = first.index() + i;
      particles_.position[p] = def.position + def.orientation * cloud.positions[i];
      particles_.velocity[p] = particles_.invMass[p] == 0.0
                                   ? Vec3::Zero()
                                   : Vec3(def.linearVelocity + def.angularVelocity.cross(particles_.position[p] - state.position));
      deformableParticles_.emplace_back(p);
    }
    updateDeformableBodyState(id);
  } else {
    if (def.kind == BodyKind::Rigid) rigidBodies_.push_back(id);
    updateRigidParticles(id);
    if (def.kind == BodyKind::Rigid) buildLattice(id);
  }
  for (std::size_t i = 0; i < n; ++i) maxRadius_ = std::max(maxRadius_, cloud.radii[i]);
  opened_.resize(particles_.size(), 0);
  broadphase_.setMargin(settings_.broadphaseMargin > 0.0 ? settings_.broadphaseMargin : maxRadius_);
  broadphase_.addBody(id, bodyBoxes_[id.index()], def.kind == BodyKind::Static);
  contactFinder_.addBody(id, particles_, bodies_);
  cores_.update(id, particles_, bodies_, normals_);
  contactsStale_ = true;
  return id;
}

void World::setProcesses(ProcessGroup* processes) {
  processes_ = processes;
  contactFinder_.setProcesses(processes);
  narrowPhase_.setProcesses(processes);
  solver_.setProcesses(processes);
}

void World::setThreads(int threads, bool shareAll) {
  settings_.threads = std::max(1, threads);
  if (settings_.threads == 1) pool_.reset();
  else if (!pool_ || pool_->workers() != settings_.threads) pool_ = std::make_unique<ThreadPool>(settings_.threads);
  if (pool_) pool_->setShareAll(shareAll);
}

StepStatus World::step() {
  if (contactsStale_) refreshContacts();
  const auto t0 = Clock::now();
  const double x0 = exchangeSeconds();
  stats_ = StepStats{};
  stats_.step = stepIndex_ + 1;
  timeStage(&StageTimes::integrateVelocities, [&] { integrateVelocities(); });
  timeStage(&StageTimes::solver, [&] { solveContacts(); });
  timeStage(&StageTimes::integratePositions, [&] { integratePositions(); });
  timeStage(&StageTimes::breakage, [&] { applyBreakage(); });
  ++stepIndex_;
  const bool finiteNow = finiteState();
  if (finiteNow) detectCollisions();
  stats_.time.total = secondsSince(t0);
  stats_.exchangeTime.total = exchangeSeconds() - x0;
  return finiteNow ? StepStatus::Ok : StepStatus::NonFinite;
}

double World::exchangeSeconds() const { return processes_ ? processes_->exchangeSeconds() : 0.0; }

template <class Stage>
void World::timeStage(double StageTimes::*stage, const Stage& run) {
  const auto t = Clock::now();
  const double x = exchangeSeconds();
  run();
  stats_.time.*stage = secondsSince(t);
  stats_.exchangeTime.*stage = exchangeSeconds() - x;
}

void World::refreshContacts() {
  const StepStats keep = stats_;
  detectCollisions();
  const StepStats found = stats_;
  stats_ = keep;
  // the counters describe the current contacts; the timings stay those of the last step
  stats_.bodyPairs = found.bodyPairs;
  stats_.planePairs = found.planePairs;
  stats_.contacts = found.contacts;
  stats_.contactGroups = found.contactGroups;
  stats_.maxPenetration = found.maxPenetration;
  stats_.patches = found.patches;
  stats_.patchesByCase = found.patchesByCase;
  stats_.candidates = found.candidates;
  stats_.lookAheads = found.lookAheads;
  stats_.unvalidatedPatches = found.unvalidatedPatches;
  stats_.contactLinePatches = found.contactLinePatches;
  stats_.lookAheadsDecided = found.lookAheadsDecided;
}

void World::detectCollisions() {
  timeStage(&StageTimes::broadphase, [&] { findBodyPairs(); });
  timeStage(&StageTimes::particleContacts, [&] {
    contactFinder_.find(particles_, bodies_, connectors_, broadphase_.pairs(), broadphase_.planePairs(), planes_, bodyBoxes_,
                        contacts_, pool_.get());
  });
  timeStage(&StageTimes::narrowPhase, [&] { narrowPhase_.run(narrowPhaseInput(), contacts_, patches_, pool_.get()); });
  const NarrowPhaseStats& np = patches_.stats;
  stats_.patches = np.patches;
  stats_.patchesByCase = np.byCase;
  stats_.candidates = np.candidates;
  stats_.lookAheads = np.lookAheads;
  stats_.unvalidatedPatches = np.unvalidated;
  stats_.contactLinePatches = np.contactLines;
  stats_.lookAheadsDecided = np.lookAheadsDecided;
  stats_.patchesReused = np.reused;
  stats_.bodyPairs = broadphase_.pairs().size();
  stats_.planePairs = broadphase_.planePairs().size();
  stats_.contactGroups = contacts_.groups.size();
  // touching contacts and the deepest overlap: each worker's range, then the ranges combined (a count and
  // a maximum, the same in any order)
  const std::size_t nc = contacts_.contacts.size();
  const std::size_t parts = pool_ && pool_->worthSharing(nc, 4096) ? static_cast<std::size_t>(pool_->workers()) : 1;
  contactTally_.assign(parts, {});
  const auto tally = [&](int worker, std::size_t begin, std::size_t end) {
    ContactTally mine;
    for (std::size_t i = begin; i < end; ++i) {
      const ParticleContact& c = contacts_.contacts[i];
      if (!c.touching()) continue;
      ++mine.touching;
      mine.deepest = std::max(mine.deepest, c.depth);
    }
    contactTally_[static_cast<std::size_t>(worker)] = mine;
  };
  if (parts > 1) pool_->run(nc, tally);
  else tally(0, 0, nc);
  stats_.contacts = 0;
  stats_.maxPenetration = 0.0;
  for (const ContactTally& part : contactTally_) {
    stats_.contacts += part.touching;
    stats_.maxPenetration = std::max(stats_.maxPenetration, part.deepest);
  }
  contactsStale_ = false;
}

void World::findBodyPairs() {
  auto displacement = [&](BodyId id) -> Vec3 { return bodies_.state[id.index()].linearVelocity * settings_.dt; };
  if (pool_ && pool_->worthSharing(rigidBodies_.size(), 128)) {
    // which rigid bodies' boxes left their fat boxes, tested on the threads (from 128 bodies a worker: a
    // test reads one compact box); the trees are then updated in the bodies' order on one, as without
    // threads
    leftFatBox_.resize(rigidBodies_.size());
    pool_->run(rigidBodies_.size(), [&](int, std::size_t begin, std::size_t end) {
      for (std::size_t k = begin; k < end; ++k) {
        const BodyId id = rigidBodies_[k];
        leftFatBox_[k] = broadphase_.keepsFatBox(id, bodyBoxes_[id.index()], displacement(id)) ? 0 : 1;
      }
    });
    for (std::size_t k = 0; k < rigidBodies_.size(); ++k)
      if (leftFatBox_[k]) broadphase_.moveBody(rigidBodies_[k], bodyBoxes_[rigidBodies_[k].index()], displacement(rigidBodies_[k]));
  } else {
    for (const BodyId id : rigidBodies_) broadphase_.moveBody(id, bodyBoxes_[id.index()], displacement(id));
  }
  for (const BodyId id : deformableBodies_) broadphase_.moveBody(id, bodyBoxes_[id.index()], displacement(id));
  stats_.proxyMoves = broadphase_.reinsertions();
  broadphase_.findPairs(planes_, pool_.get());
}

void World::integrateVelocities() {
  // deformable particles get gravity a substep at a time in integratePositions, where their contacts hold
  // them up as position constraints; the contact solver sees them as they are (impacts, not their weight)
  const auto gravity = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i)
      integrateRigidVelocity(bodies_.state[rigidBodies_[i].index()], settings_.gravity, settings_.dt);
  };
  if (pool_ && pool_->worthSharing(rigidBodies_.size(), 512)) pool_->run(rigidBodies_.size(), gravity);
  else gravity(0, 0, rigidBodies_.size());
}

std::uint32_t* World::solverSlot(ParticleId p) {
  const BodyId b = particles_.body[p.index()];
  switch (bodyKinds_[b.index()]) {
    case BodyKind::Static: return nullptr;
    case BodyKind::Rigid: return &bodySolverIndex_[b.index()];
    default: return &particleSolverIndex_[p.index()];
  }
}

std::uint32_t World::solverIndex(ParticleId p) {
  std::uint32_t* const found = solverSlot(p);
  if (!found) return ContactPointInput::kFixed;
  std::uint32_t& slot = *found;
  if (slot != ContactPointInput::kFixed) return slot;
  const BodyId b = particles_.body[p.index()];
  if (bodyKinds_[b.index()] == BodyKind::Rigid) return rigidSolverIndex(b);
  slot = static_cast<std::uint32_t>(solverBodyOwner_.size());
  solverBodyOwner_.emplace_back();
  solverParticleOwner_.push_back(p);
  return slot;
}

std::uint32_t World::rigidSolverIndex(BodyId b) {
  std::uint32_t& slot = bodySolverIndex_[b.index()];
  if (slot != ContactPointInput::kFixed) return slot;
  slot = static_cast<std::uint32_t>(solverBodyOwner_.size());
  solverBodyOwner_.push_back(b);
  solverParticleOwner_.emplace_back();
  return slot;
}

void World::makeSolverBodies() {
  solverBodies_.resize(solverBodyOwner_.size());
  const auto make = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      SolverBody& sb = solverBodies_[i];
      if (const BodyId b = solverBodyOwner_[i]; b.valid()) {
        const BodyState& s = bodies_.state[b.index()];
        sb.position = s.position;
        sb.v = s.linearVelocity;
        sb.w = s.angularVelocity;
        sb.invMass = s.invMass;
        sb.invInertia = s.invInertiaWorld;
      } else {
        const ParticleId p = solverParticleOwner_[i];
        sb.position = particles_.position[p.index()];
        sb.v = particles_.velocity[p.index()];
        sb.w = Vec3::Zero();
        sb.invMass = particles_.invMass[p.index()];
        sb.invInertia = Mat3::Zero();
      }
      sb.pv = sb.pw = Vec3::Zero();
    }
  };
  if (pool_ && pool_->worthSharing(solverBodies_.size(), 256)) pool_->run(solverBodies_.size(), make);
  else make(0, 0, solverBodies_.size());
}

std::pair<const Material*, const Material*> World::contactMaterials(ParticleId a, ParticleId b, PlaneId plane) const {
  const Material& ma = materials_[bodyMaterials_[particles_.body[a.index()].index()].index()];
  const MaterialId mb = plane.valid() ? planes_[plane.index()].material : bodyMaterials_[particles_.body[b.index()].index()];
  return {&ma, &materials_[mb.index()]};
}

std::pair<const Material*, const Material*> World::contactMaterials(BodyId a, BodyId b, PlaneId plane) const {
  const MaterialId mb = plane.valid() ? planes_[plane.index()].material : bodyMaterials_[b.index()];
  return {&materials_[bodyMaterials_[a.index()].index()], &materials_[mb.index()]};
}

void World::solveContacts() {
  // solver bodies of this step: only those in contact
  for (const BodyId b : solverBodyOwner_)
    if (b.valid()) bodySolverIndex_[b.index()] = ContactPointInput::kFixed;
  for (const ParticleId p : solverParticleOwner_)
    if (p.valid()) particleSolverIndex_[p.index()] = ContactPointInput::kFixed;
  // (solverBodies_ keeps its entries: makeSolverBodies() sizes it and writes every field of every one)
  solverBodyOwner_.clear();
  solverParticleOwner_.clear();
  bodySolverIndex_.resize(bodies_.size(), ContactPointInput::kFixed);
  particleSolverIndex_.resize(particles_.size(), ContactPointInput::kFixed);
  buildContactPoints();
  stats_.contactPoints = contactPoints_.size();
  // loads on the particles of breakable bodies: gravity, and below the contact impulses over the step
  if (!breakableRigid_.empty()) {
    loads_.resize(particles_.size());
    for (const BodyId b : breakableRigid_)
      for (const ParticleId q : bodies_.info[b.index()].particles) loads_[q.index()] = particles_.mass[q.index()] * settings_.gravity;
  }
  if (contactPoints_.empty()) return;
  solver_.solve(solverBodies_, contactPoints_, settings_.dt, pool_.get());
  stats_.warmStarted = solver_.warmStarted();
  stats_.heavyIslands = solver_.heavyIslandsSolved();
  stats_.solverNodesTakenOver = solver_.nodesTakenOver();
  static_assert(std::tuple_size_v<decltype(stats_.solverRowsByLevel)> == ContactSolver::kMaxDepth + 1);
  for (int l = 0; l <= solver_.depth(); ++l) stats_.solverRowsByLevel[static_cast<std::size_t>(l)] = solver_.rowsAtLevel(l);
  if (anyRollingResistance_) resistRolling();
  if (!breakableRigid_.empty()) {
    const std::span<const Vec3> impulses = solver_.impulses();
    for (std::size_t i = 0; i < impulses.size(); ++i) {
      const auto [pa, pb] = pointParticles_[i];
      if (breakable(particles_.body[pa.index()])) loads_[pa.index()] -= impulses[i] / settings_.dt;
      if (pb.valid() && breakable(particles_.body[pb.index()])) loads_[pb.index()] += impulses[i] / settings_.dt;
    }
  }
  // velocities back to the bodies and particles
  const auto back = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const SolverBody& sb = solverBodies_[i];
      if (solverBodyOwner_[i].valid()) {
        BodyState& s = bodies_.state[solverBodyOwner_[i].index()];
        s.linearVelocity = sb.v;
        s.angularVelocity = sb.w;
      } else {
        particles_.velocity[solverParticleOwner_[i].index()] = sb.v;
      }
    }
  };
  if (pool_ && pool_->worthSharing(solverBodies_.size(), 512)) pool_->run(solverBodies_.size(), back);
  else back(0, 0, solverBodies_.size());
}

void World::resistRolling() {
  // per patch of a rigid body on a rigid or static one, in patch order: a couple that opposes the two
  // sides' relative rolling (their relative angular velocity across the normal), at most mu_r R N over the
  // step, with N the patch's normal impulse and R the rolling radius (each rigid side's distance from its
  // centre of mass to the contact plane, combined as R_a R_b / (R_a + R_b)); it stops the rolling where that
  // is enough. A couple keeps the bodies' momenta; the friction of the next solve carries it to their
  // linear motion
  const std::span<const Vec3> impulses = solver_.impulses();
  const PatchSet& ps = patches_;
  for (std::size_t j = 0; j < ps.patches.size(); ++j) {
    if (pointFirst_[j] == pointFirst_[j + 1]) continue;
    const ContactPatch& patch = ps.patches[j];
    const auto [ma, mb] = contactMaterials(patch.a, patch.b, patch.plane);
    const double mu = std::max(ma->rollingResistance, mb->rollingResistance);
    if (mu <= 0.0) continue;
    const auto kindOf = [&](BodyId b) { return b.valid() ? bodyKinds_[b.index()] : BodyKind::Static; };
    const BodyKind ka = kindOf(patch.a), kb = kindOf(patch.b);
    if (ka == BodyKind::Deformable || kb == BodyKind::Deformable || (ka != BodyKind::Rigid && kb != BodyKind::Rigid)) continue;
    const Vec3& n = patch.normal;
    double normal = 0.0;
    for (std::uint32_t k = pointFirst_[j]; k < pointFirst_[j + 1]; ++k) normal += n.dot(impulses[k]);
    if (normal <= 0.0) continue;
    // each rigid side's solver body, inverse inertia and rolling radius (a static side: none, infinite)
    double inverseRadius = 0.0;
    std::array<SolverBody*, 2> side{};
    std::array<Mat3, 2> inverse{Mat3::Zero(), Mat3::Zero()};
    Vec3 relative = Vec3::Zero();  // (B's angular velocity relative to A's)
    for (std::size_t s = 0; s < 2; ++s) {
      const BodyId b = s == 0 ? patch.a : patch.b;
      if (kindOf(b) != BodyKind::Rigid) continue;
      side[s] = &solverBodies_[bodySolverIndex_[b.index()]];
      inverse[s] = side[s]->invInertia;
      relative += s == 0 ? Vec3(-side[s]->w) : side[s]->w;
      const double radius = std::abs(n.dot(patch.point - bodies_.state[b.index()].position));
      inverseRadius += radius > 0.0 ? 1.0 / radius : std::numeric_limits<double>::infinity();
    }
    const Vec3 rolling = relative - relative.dot(n) * n;
    const double speed = rolling.norm();
    if (speed == 0.0 || !(inverseRadius < std::numeric_limits<double>::infinity())) continue;
    const Vec3 e = rolling / speed;
    const double k = e.dot((inverse[0] + inverse[1]) * e);
    if (k <= 0.0) continue;
    const double couple = std::min(speed / k, mu * normal / inverseRadius);
    if (side[0]) side[0]->w += couple * (inverse[0] * e);
    if (side[1]) side[1]->w -= couple * (inverse[1] * e);
  }
}

void World::integratePositions() {
  const double dt = settings_.dt;
  const auto pose = [&](BodyId id) {
    const std::uint32_t k = id.index() < bodySolverIndex_.size() ? bodySolverIndex_[id.index()] : ContactPointInput::kFixed;
    if (k != ContactPointInput::kFixed) integrateRigidPose(bodies_.state[id.index()], dt, solverBodies_[k].pv, solverBodies_[k].pw);
    else integrateRigidPose(bodies_.state[id.index()], dt);
  };
  // rigid bodies are independent: shared among the workers
  const std::size_t nRigid = rigidBodies_.size();
  if (processes_ && processes_->size() > 1 && nRigid > 0) {
    shareRigidPoses(pose);
  } else {
    const auto rigid = [&](int, std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i) {
        pose(rigidBodies_[i]);
        updateRigidParticles(rigidBodies_[i]);
      }
    };
    if (pool_ && pool_->worthSharing(nRigid, 256)) pool_->run(nRigid, rigid);
    else rigid(0, 0, nRigid);
  }
  if (deformableBodies_.empty()) return;  // (what follows steps deformable bodies and their contacts)
  DeformableStepInput in;
  in.particles = deformableParticles_;
  in.connectors = deformableConnectors_;
  // gravity a substep at a time: a hanging or resting body feels its weight in every substep
  in.gravity = settings_.gravity;
  in.dt = dt;
  in.substeps = settings_.substeps;
  bool shifted = false;
  for (std::size_t i = 0; i < solverBodies_.size(); ++i) {
    if (!solverParticleOwner_[i].valid()) continue;
    if (!shifted) {
      particleShift_.assign(particles_.size(), Vec3::Zero());
      shifted = true;
    }
    particleShift_[solverParticleOwner_[i].index()] = solverBodies_[i].pv * dt;
  }
  if (shifted) in.shift = particleShift_;
  // the contacts of deformable particles hold in every substep, on the patch's plane (or, where the patch
  // could not validate a plane, such as cloth wrapped round a ball, on each pair's centre line), as in the
  // contact solver
  deformableContacts_.clear();
  for (const ContactPatch& patch : patches_.patches) {
    const bool aDef = bodyKinds_[patch.a.index()] == BodyKind::Deformable;
    const bool bDef = patch.b.valid() && bodyKinds_[patch.b.index()] == BodyKind::Deformable;
    if (!aDef && !bDef) continue;
    for (std::uint32_t k = patch.first; k < patch.first + patch.count; ++k) {
      const ParticleContact& c = contacts_.contacts[patches_.contacts[k]];
      const double ra = particles_.radius[c.a.index()];
      const auto [ma, mb] = contactMaterials(c.a, c.b, patch.plane);
      const double mu = std::sqrt(ma->friction * mb->friction);
      if (patch.plane.valid()) {
        const Plane& pl = planes_[patch.plane.index()];
        deformableContacts_.push_back({c.a, ParticleId{}, pl.normal, pl.offset + ra * (1.0 - settings_.slop), false, false, mu});
        continue;
      }
      const double sep = (ra + particles_.radius[c.b.index()]) * (1.0 - settings_.slop);
      // written for the deformable particle (the normal points from A to B; a flipped contact's a is on B)
      const bool line = patch.source == NormalSource::ContactLines;
      const Vec3 n = contactNormal(patch, particles_.position[c.a.index()], particles_.position[c.b.index()],
                                   patches_.flipped[patches_.contacts[k]] != 0);
      if (aDef) deformableContacts_.push_back({c.a, c.b, -n, sep, line, !bDef, mu});
      else deformableContacts_.push_back({c.b, c.a, n, sep, line, true, mu});
    }
  }
  in.contacts = deformableContacts_;
  deformableContactImpulses_.resize(deformableContacts_.size());
  in.contactImpulses = deformableContactImpulses_;
  deformableContactMoments_.resize(deformableContacts_.size());
  in.contactMoments = deformableContactMoments_;
  deformableForces_.resize(connectors_.size(), 0.0);
  in.forces = deformableForces_;
  integrateDeformables(particles_, connectors_, in, scratch_);
  // what stopped deformable particles against rigid bodies in the substeps pushes those bodies back
  // (momentum is conserved; the bodies' new velocities act from the next step)
  touchedRigid_.clear();
  for (std::size_t k = 0; k < deformableContacts_.size(); ++k) {
    const DeformableContact& ct = deformableContacts_[k];
    const Vec3& j = deformableContactImpulses_[k];
    const Vec3& moment = deformableContactMoments_[k];
    if (!ct.other.valid() || (j.isZero() && moment.isZero())) continue;
    const BodyId b = particles_.body[ct.other.index()];
    BodyState& s = bodies_.state[b.index()];
    if (bodyKinds_[b.index()] != BodyKind::Rigid || s.invMass == 0.0) continue;
    // (the opposite of what the particle got: its momentum, and its angular momentum about the origin,
    // which about the body's centre is moment - c x j)
    s.linearVelocity -= s.invMass * j;
    s.angularVelocity -= s.invInertiaWorld * (moment - s.position.cross(j));
    touchedRigid_.push_back(b);
  }
  std::sort(touchedRigid_.begin(), touchedRigid_.end());
  touchedRigid_.erase(std::unique(touchedRigid_.begin(), touchedRigid_.end()), touchedRigid_.end());
  for (const BodyId b : touchedRigid_) updateRigidParticles(b);
  updateDeformableBodyStates();
}

template <class Pose>
void World::shareRigidPoses(const Pose& pose) {
  // each process integrates the poses of a contiguous run of the rigid bodies, and one exchange hands every
  // process every body's centre, orientation and angular velocity (its world inverse inertia follows from
  // its orientation, by the same function on every process); every process then places every body's
  // particles, which every stage reads
  const std::size_t n = rigidBodies_.size();
  const int ranks = processes_->size();
  const std::size_t begin = firstShare(processes_->rank(), ranks, n), end = firstShare(processes_->rank() + 1, ranks, n);
  sharedPoses_.resize(n);
  // (a pose: the centre, the orientation's coefficients and the angular velocity, 10 doubles)
  using Centre = Eigen::Map<Vec3>;
  using Turn = Eigen::Map<Eigen::Vector4d>;
  const auto integrate = [&](int, std::size_t from, std::size_t to) {
    for (std::size_t i = begin + from; i < begin + to; ++i) {
      pose(rigidBodies_[i]);
      const BodyState& s = bodies_.state[rigidBodies_[i].index()];
      double* out = sharedPoses_[i].data();
      Centre{out} = s.position;
      Turn{out + 3} = s.orientation.coeffs();
      Centre{out + 7} = s.angularVelocity;
    }
  };
  if (pool_ && pool_->worthSharing(end - begin, 256)) pool_->run(end - begin, integrate);
  else integrate(0, 0, end - begin);
  shareRuns(*processes_, std::as_writable_bytes(std::span<std::array<double, 10>>(sharedPoses_.data(), n)),
            sizeof(std::array<double, 10>), [&](std::size_t r) { return firstShare(static_cast<int>(r), ranks, n); },
            shareOffset_, shareCount_);
  const auto place = [&](int, std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i) {
      const BodyId id = rigidBodies_[i];
      BodyState& s = bodies_.state[id.index()];
      if ((i < begin || i >= end) && s.invMass != 0.0) {  // (a body of no mass never moves: integrateRigidPose())
        double* in = sharedPoses_[i].data();
        s.position = Centre{in};
        s.orientation.coeffs() = Turn{in + 3};
        s.angularVelocity = Centre{in + 7};
        updateWorldInertia(s);
      }
      updateRigidParticles(id);
    }
  };
  if (pool_ && pool_->worthSharing(n, 256)) pool_->run(n, place);
  else place(0, 0, n);
}

void World::updateRigidParticles(BodyId id) {
  // (a run of ids read as such, without the body's list)
  const ParticleRun run = bodyRuns_[id.index()];
  const ParticleBounds box =
      run.consecutive
          ? placeRigidParticles(bodies_.state[id.index()], run, particles_.local.data(), particles_.radius.data(),
                                particles_.position.data(), particles_.velocity.data())
          : placeRigidParticles(bodies_.state[id.index()], bodies_.info[id.index()].particles, particles_.local.data(),
                                particles_.radius.data(), particles_.position.data(), particles_.velocity.data());
  bodyBoxes_[id.index()] = Aabb{box.lo, box.hi};
}

void World::updateDeformableBodyStates() {
  for (const BodyId id : deformableBodies_) updateDeformableBodyState(id);
}

void World::updateDeformableBodyState(BodyId id) {
  // centre of mass, its velocity, the angular velocity I^-1 L about it, and the best-fit rotation of the
  // rest shape (shape matching: the rotation of the polar decomposition of sum m (x - c) q^T, with q the
  // rest offsets), which carries the body's cached normals
  BodyState& s = bodies_.state[id.index()];
  const BodyInfo& info = bodies_.info[id.index()];
  Vec3 x = Vec3::Zero(), v = Vec3::Zero();
  for (const ParticleId p : info.particles) {
    x += particles_.mass[p.index()] * particles_.position[p.index()];
    v += particles_.mass[p.index()] * particles_.velocity[p.index()];
  }
  x /= info.mass;
  v /= info.mass;
  Mat3 inertia = Mat3::Zero();
  Mat3 apq = Mat3::Zero();
  Vec3 l = Vec3::Zero();
  Aabb box;
  for (const ParticleId p : info.particles) {
    const std::size_t i = p.index();
    const Vec3 d = particles_.position[i] - x;
    const double m = particles_.mass[i];
    inertia += (sphereMoment(m, particles_.radius[i]) + m * d.squaredNorm()) * Mat3::Identity() - m * d * d.transpose();
    apq += m * d * particles_.local[i].transpose();
    l += m * d.cross(particles_.velocity[i] - v);
    box.extend(Aabb::sphere(particles_.position[i], particles_.radius[i]));
  }
  s.position = x;
  s.linearVelocity = v;
  s.angularVelocity = inertia.ldlt().solve(l);
  const Eigen::JacobiSVD<Mat3> svd(apq, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 u = svd.matrixU();
  if ((u * svd.matrixV().transpose()).determinant() < 0.0) u.col(2) = -u.col(2);
  const Mat3 r = u * svd.matrixV().transpose();
  if (r.allFinite() && svd.singularValues()(1) > 0.0) s.orientation = Quat(r).normalized();
  bodyBoxes_[id.index()] = box;
}

void World::syncParticles() {
  for (const BodyId id : rigidBodies_) {
    updateWorldInertia(bodies_.state[id.index()]);
    updateRigidParticles(id);
  }
}

bool World::finiteState() const {
  for (const BodyId id : rigidBodies_) {
    const BodyState& s = bodies_.state[id.index()];
    if (!finite(s.position) || !finite(s.linearVelocity) || !finite(s.angularVelocity) ||
        !std::isfinite(s.orientation.w()))
      return false;
  }
  for (const ParticleId p : deformableParticles_)
    if (!finite(particles_.position[p.index()]) || !finite(particles_.velocity[p.index()])) return false;
  return true;
}

Vec3 World::particleNormal(ParticleId id) const { return cachedWorldNormal(particles_, bodies_, normals_, id); }

EnergyReport World::energy() const {
  EnergyReport e;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const BodyState& s = bodies_.state[b];
    const BodyInfo& info = bodies_.info[b];
    if (info.kind == BodyKind::Static || !info.alive) continue;
    if (info.kind == BodyKind::Rigid) {
      e.kinetic += 0.5 * info.mass * s.linearVelocity.squaredNorm() + rotationalEnergy(s, info.inertiaLocal);
      e.potential -= info.mass * settings_.gravity.dot(s.position);
    } else {
      for (const ParticleId p : info.particles) {
        const std::size_t i = p.index();
        e.kinetic += 0.5 * particles_.mass[i] * particles_.velocity[i].squaredNorm();
        e.potential -= particles_.mass[i] * settings_.gravity.dot(particles_.position[i]);
      }
    }
  }
  e.potential += springEnergy(particles_, connectors_, deformableConnectors_);
  return e;
}

Vec3 World::linearMomentum() const {
  Vec3 p = Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const BodyInfo& info = bodies_.info[b];
    if (info.kind == BodyKind::Static || !info.alive) continue;
    p += info.mass * bodies_.state[b].linearVelocity;
  }
  return p;
}

Vec3 World::angularMomentum() const {
  Vec3 l = Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const BodyInfo& info = bodies_.info[b];
    const BodyState& s = bodies_.state[b];
    if (!info.alive) continue;
    if (info.kind == BodyKind::Rigid) {
      l += info.mass * s.position.cross(s.linearVelocity) + volpar::angularMomentum(s, info.inertiaLocal);
    } else if (info.kind == BodyKind::Deformable) {
      for (const ParticleId p : info.particles) {
        const std::size_t i = p.index();
        l += particles_.mass[i] * particles_.position[i].cross(particles_.velocity[i]);
      }
    }
  }
  return l;
}

}  // namespace volpar
