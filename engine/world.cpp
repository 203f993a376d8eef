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
      particles_.normalIndex[p] = normals_.add(toCache * cloud.normals[i], std::span<const Vec3>(faces.data(), nf));
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
  stats_ = StepStats{};
  stats_.step = stepIndex_ + 1;

  auto t = Clock::now();
  integrateVelocities();
  stats_.time.integrateVelocities = secondsSince(t);

  t = Clock::now();
  solveContacts();
  stats_.time.solver = secondsSince(t);

  t = Clock::now();
  integratePositions();
  stats_.time.integratePositions = secondsSince(t);

  t = Clock::now();
  applyBreakage();
  stats_.time.breakage = secondsSince(t);

  ++stepIndex_;
  const bool finiteNow = finiteState();
  if (finiteNow) detectCollisions();
  stats_.time.total = secondsSince(t0);
  return finiteNow ? StepStatus::Ok : StepStatus::NonFinite;
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
  auto t = Clock::now();
  for (const BodyId id : rigidBodies_)
    broadphase_.moveBody(id, bodyBoxes_[id.index()], bodies_.state[id.index()].linearVelocity * settings_.dt);
  for (const BodyId id : deformableBodies_)
    broadphase_.moveBody(id, bodyBoxes_[id.index()], bodies_.state[id.index()].linearVelocity * settings_.dt);
  stats_.proxyMoves = broadphase_.reinsertions();
  broadphase_.findPairs(planes_, bodyPairs_, planePairs_, pool_.get());
  stats_.time.broadphase = secondsSince(t);

  t = Clock::now();
  contactFinder_.find(particles_, bodies_, connectors_, bodyPairs_, planePairs_, planes_, bodyBoxes_, contacts_, pool_.get());
  stats_.time.particleContacts = secondsSince(t);

  t = Clock::now();
  narrowPhase_.run(narrowPhaseInput(), contacts_, patches_, pool_.get());
  stats_.time.narrowPhase = secondsSince(t);
  const NarrowPhaseStats& np = patches_.stats;
  stats_.patches = np.patches;
  stats_.patchesByCase = np.byCase;
  stats_.candidates = np.candidates;
  stats_.lookAheads = np.lookAheads;
  stats_.unvalidatedPatches = np.unvalidated;
  stats_.contactLinePatches = np.contactLines;
  stats_.lookAheadsDecided = np.lookAheadsDecided;
  stats_.patchesReused = np.reused;
  stats_.bodyPairs = bodyPairs_.size();
  stats_.planePairs = planePairs_.size();
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
  switch (bodies_.info[b.index()].kind) {
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
  if (bodies_.info[b.index()].kind == BodyKind::Rigid) return rigidSolverIndex(b);
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

namespace {

/// A rigid patch's manifold of four of its `count` contacts `idx` (Bullet's choice): the deepest along the
/// normal, the one farthest from it, the one farthest from their line, and the one that adds most area on
/// the far side. Returns positions in idx; count must be above 4.
std::array<std::uint32_t, 4> manifoldOfFour(const ContactSet& cs, const std::uint32_t* idx, std::uint32_t count,
                                            std::span<const double> depth) {
  std::array<std::uint32_t, 4> reduced{};
  std::size_t chosen = 0;
  const auto pointOf = [&](std::uint32_t k) -> const Vec3& { return cs.contacts[idx[k]].point; };
  std::uint32_t deepest = 0;
  for (std::uint32_t k = 1; k < count; ++k)
    if (depth[idx[k]] > depth[idx[deepest]]) deepest = k;
  reduced[chosen++] = deepest;
  const auto best = [&](auto score) {
    const auto taken = [&](std::uint32_t k) {
      return std::find(reduced.begin(), reduced.begin() + static_cast<std::ptrdiff_t>(chosen), k) !=
             reduced.begin() + static_cast<std::ptrdiff_t>(chosen);
    };
    std::uint32_t arg = 0;
    double top = -1.0;
    for (std::uint32_t k = 0; k < count; ++k) {
      if (taken(k)) continue;
      const double v = score(pointOf(k));
      if (v > top) {
        top = v;
        arg = k;
      }
    }
    return arg;
  };
  const Vec3 p0 = pointOf(deepest);
  reduced[chosen++] = best([&](const Vec3& x) { return (x - p0).squaredNorm(); });
  const Vec3 p1 = pointOf(reduced[1]);
  reduced[chosen++] = best([&](const Vec3& x) { return (x - p0).cross(x - p1).squaredNorm(); });
  const Vec3 p2 = pointOf(reduced[2]);
  const Vec3 triNormal = (p1 - p0).cross(p2 - p0);
  reduced[chosen++] = best([&](const Vec3& x) {
    // area added outside the triangle: the largest of the three triangles the point makes with an edge
    const double a = (x - p0).cross(x - p1).dot(triNormal), b = (x - p1).cross(x - p2).dot(triNormal),
                 c = (x - p2).cross(x - p0).dot(triNormal);
    return std::max({-a, -b, -c});
  });
  return reduced;
}

/// The mean distance from a patch's centre over a square cell of side `cell` in the patch's plane at in-plane
/// offset d from it: sqrt(|d|^2 + cell^2 / 12), exact to second order in cell / |d| (over a face of n x n
/// cells within 1 % of the exact mean for n >= 2).
double cellLever(const Vec3& d, double cell) { return std::sqrt(d.squaredNorm() + cell * cell / 12.0); }

}  // namespace

void World::buildContactPoints() {
  const ContactSet& cs = contacts_;
  const PatchSet& ps = patches_;
  const std::size_t np = ps.patches.size();
  const double dt = settings_.dt;
  const auto kind = [&](BodyId b) { return bodyKinds_[b.index()]; };
  // a contact's normal, from its particle a to b (a plane's contacts: the patch's)
  const auto normalOf = [&](const ContactPatch& patch, std::uint32_t contact) -> Vec3 {
    const ParticleContact& c = cs.contacts[contact];
    if (!c.b.valid()) return patch.normal;
    return contactNormal(patch, particles_.position[c.a.index()], particles_.position[c.b.index()], ps.flipped[contact] != 0);
  };
  // how a patch becomes points: every contact on its own centre line (raw normals; point masses of
  // deformable bodies where the patch has no valid plane), every contact on the patch's plane (small
  // patches; breakable bodies, whose rod loads follow where the contacts are), or a rigid patch reduced
  // to a manifold of at most four points
  enum : std::uint8_t { kRaw, kAll, kReduced, kNone };
  patchPoints_.resize(np);
  pointFirst_.resize(np + 1);
  keptContacts_.resize(ps.contacts.size());
  // a patch's side as its points see it (looked up once per patch): a rigid body's motion, shared by all
  // its particles; a deformable body's particles, each on its own; or the fixed world
  struct Side {
    BodyKind kind = BodyKind::Static;
    Vec3 v = Vec3::Zero(), w = Vec3::Zero(), centre = Vec3::Zero();
  };
  const auto sideOf = [&](BodyId b, BodyKind k) {
    Side side;
    if (!b.valid()) return side;
    side.kind = k;
    if (side.kind == BodyKind::Rigid) {
      const BodyState& s = bodies_.state[b.index()];
      side.v = s.linearVelocity;
      side.w = s.angularVelocity;
      side.centre = s.position;
    }
    return side;
  };
  // (1) each patch's mode and the contacts that become points: the touching ones, and the speculative ones
  // whose gap is within speculativeDistance of touching or closes at the pair's approach speed within the
  // step; the others could only close if the solver drove the pair together faster than that distance per
  // step, and are left out (kept in keptContacts_ at the patch's place, in patch order)
  const auto select = [&](int, std::size_t begin, std::size_t end) {
    const auto velocityAt = [&](const Side& side, ParticleId p, const Vec3& point) -> Vec3 {
      switch (side.kind) {
        case BodyKind::Rigid: return side.v + side.w.cross(point - side.centre);
        case BodyKind::Deformable: return particles_.velocity[p.index()];
        default: return Vec3::Zero();
      }
    };
    for (std::size_t j = begin; j < end; ++j) {
      const ContactPatch& patch = ps.patches[j];
      const Side sideA = patch.a.valid() ? sideOf(patch.a, kind(patch.a)) : Side{},
                 sideB = patch.b.valid() ? sideOf(patch.b, kind(patch.b)) : Side{};
      const bool fixedA = sideA.kind == BodyKind::Static, fixedB = sideB.kind == BodyKind::Static;
      std::uint8_t mode = kAll;
      if (fixedA && fixedB) mode = kNone;
      else if (settings_.rawNormals || patch.source == NormalSource::ContactLines) mode = kRaw;
      const std::uint32_t* idx = ps.contacts.data() + patch.first;
      std::uint32_t* kept = keptContacts_.data() + patch.first;
      std::uint32_t count = 0;
      if (mode != kNone) {
        // (a bound on a point's approach speed: the sides' relative linear velocity plus each rigid side's
        // spin times the point's distance from its centre, at most the reach of the corner of its particles'
        // box farthest from the centre plus half the pair's gap (the point lies midway across it). A gap
        // beyond what that closes in the step is left out without working out its normal and velocities; a
        // deformable side has no bound here)
        bool bounded = sideA.kind != BodyKind::Deformable && sideB.kind != BodyKind::Deformable;
        double linear = 0.0, spinTotal = 0.0, spinReach = 0.0;
        if (bounded) {
          const auto spin = [&](const Side& side, BodyId b, double& turn, double& reach) {
            turn = reach = 0.0;
            if (side.kind != BodyKind::Rigid) return;
            const Aabb& box = bodyBoxes_[b.index()];
            turn = side.w.norm();
            reach = (box.hi - side.centre).cwiseAbs().cwiseMax((box.lo - side.centre).cwiseAbs()).norm();
          };
          double turnA = 0.0, reachA = 0.0, turnB = 0.0, reachB = 0.0;
          spin(sideA, patch.a, turnA, reachA);
          spin(sideB, patch.b, turnB, reachB);
          linear = (sideA.v - sideB.v).norm();
          spinTotal = turnA + turnB;
          spinReach = turnA * reachA + turnB * reachB;
          bounded = std::isfinite(linear + spinTotal + spinReach);
        }
        for (std::uint32_t k = 0; k < patch.count; ++k) {
          const ParticleContact& c = cs.contacts[idx[k]];
          const double depth = mode == kRaw ? c.depth : ps.depthAlongNormal[idx[k]];
          if (depth < 0.0) {
            const double rsum = particles_.radius[c.a.index()] + (c.b.valid() ? particles_.radius[c.b.index()] : 0.0);
            if (bounded) {
              const double fastest = (linear + spinReach + spinTotal * 0.5 * std::abs(c.depth)) * (1.0 + 1e-9);
              if (-depth > settings_.speculativeDistance * rsum + fastest * dt) continue;
            }
            // (the patch's normal as the contact sees it: from its particle a to b)
            const Vec3 n = mode == kRaw ? c.normal : normalOf(patch, idx[k]);
            const double approach = std::max(0.0, n.dot(velocityAt(sideA, c.a, c.point) - velocityAt(sideB, c.b, c.point)));
            if (-depth > settings_.speculativeDistance * rsum + approach * dt) continue;
          }
          kept[count++] = idx[k];
        }
        if (count == 0) mode = kNone;
      }
      const bool rigidPair = sideA.kind != BodyKind::Deformable && !breakable(patch.a) &&
                             (!patch.b.valid() || (sideB.kind != BodyKind::Deformable && !breakable(patch.b)));
      if (mode == kAll && rigidPair && count > 4) mode = kReduced;
      patchPoints_[j] = {patch.a, patch.b, count, mode, sideA.kind, sideB.kind};
    }
  };
  if (pool_ && pool_->worthSharing(np, 512)) pool_->runChunks(np, select);
  else select(0, 0, np);
  // (2) the points' places, and the solver bodies named in the order their first points name them (the
  // points of a patch of two rigid bodies all name the same two); with processes, each point's solver
  // bodies (a rigid body's points share its slot; a deformable body's particles have a slot each). One
  // thread walks the patches here, so it reads what select() wrote for each in 16 bytes, and leaves the
  // solver bodies' contents to makeSolverBodies(), which the workers share
  const auto slotOf = [&](BodyId b, BodyKind k, ParticleId p) {
    switch (k) {
      case BodyKind::Rigid: return bodySolverIndex_[b.index()];
      case BodyKind::Deformable: return *solverSlot(p);
      default: return ContactPointInput::kFixed;
    }
  };
  const bool divided = processes_ && processes_->size() > 1;
  pointBodies_.clear();
  pointFirst_[0] = 0;
  for (std::size_t j = 0; j < np; ++j) {
    const PatchPoints& pp = patchPoints_[j];
    pointFirst_[j + 1] = pointFirst_[j] + (pp.mode == kNone ? 0 : pp.mode == kReduced ? 4 : pp.kept);
    if (pp.mode == kNone) continue;
    const BodyKind kindA = pp.kindA, kindB = pp.kindB;
    if (kindA != BodyKind::Deformable && kindB != BodyKind::Deformable) {
      // (every point of the patch names the patch's two bodies, or body a and the fixed world: a rigid
      // body's points share its slot)
      const std::uint32_t slotA = kindA == BodyKind::Rigid ? rigidSolverIndex(pp.a) : ContactPointInput::kFixed;
      const std::uint32_t slotB = kindB == BodyKind::Rigid ? rigidSolverIndex(pp.b) : ContactPointInput::kFixed;
      pointBodies_.insert(pointBodies_.end(), pointFirst_[j + 1] - pointFirst_[j], {slotA, slotB});
      continue;
    }
    // (a patch with a deformable side is never reduced: each kept contact is a point)
    const ContactPatch& patch = ps.patches[j];
    const std::uint32_t* kept = keptContacts_.data() + patch.first;
    for (std::uint32_t k = 0; k < pp.kept; ++k) {
      const ParticleContact& c = cs.contacts[kept[k]];
      solverIndex(c.a);
      if (c.b.valid()) solverIndex(c.b);
      pointBodies_.emplace_back(slotOf(patch.a, kindA, c.a),
                                c.b.valid() ? slotOf(patch.b, kindB, c.b) : ContactPointInput::kFixed);
    }
  }
  makeSolverBodies();
  contactPoints_.resize(pointFirst_[np]);
  pointParticles_.resize(pointFirst_[np]);
  // the solver plans its order from the points' bodies alone (ContactSolver::plan()). With processes it
  // plans first, and the points of other processes' nodes are not read (their particles are named all the
  // same: the loads on breakable bodies take every point's impulse); on one process one thread plans while
  // the others make the points (below)
  const bool planned = !contactPoints_.empty();
  std::span<const std::uint8_t> read;
  if (divided && planned) {
    solver_.plan(solverBodies_, pointBodies_);
    read = solver_.pointsRead();
  }
  stats_.contactPointsRead = read.empty() ? contactPoints_.size()
                                          : static_cast<std::size_t>(std::count(read.begin(), read.end(), std::uint8_t{1}));
  touchingParticle_.resize(pool_ ? static_cast<std::size_t>(pool_->workers()) : 1);
  for (std::vector<std::uint8_t>& seen : touchingParticle_) seen.resize(particles_.size(), 0);
  // (3) the points themselves: patches shared among the workers, each point written at its patch's place
  const auto fill = [&](int worker, std::size_t begin, std::size_t end) {
    std::vector<std::uint8_t>& seen = touchingParticle_[static_cast<std::size_t>(worker)];
    // (a rigid body's points share its slot and centre; a deformable body's particles have a slot each
    // and no arm)
    const auto arm = [&](const Side& side, const Vec3& point) -> Vec3 {
      return side.kind == BodyKind::Rigid ? Vec3(point - side.centre) : Vec3::Zero();
    };
    for (std::size_t j = begin; j < end; ++j) {
      const std::uint8_t mode = patchPoints_[j].mode;
      if (mode == kNone) continue;
      const ContactPatch& patch = ps.patches[j];
      const std::uint32_t* kept = keptContacts_.data() + patch.first;
      const std::uint32_t count = patchPoints_[j].kept;
      std::uint32_t out = pointFirst_[j];
      if (!read.empty() && std::none_of(read.begin() + out, read.begin() + pointFirst_[j + 1], [](std::uint8_t r) { return r != 0; })) {
        for (std::uint32_t k = 0; out < pointFirst_[j + 1]; ++k) pointParticles_[out++] = {cs.contacts[kept[k]].a, cs.contacts[kept[k]].b};
        continue;
      }
      // (the contacts of a patch join the same two bodies, or a body and a plane)
      const ParticleContact& first = cs.contacts[kept[0]];
      const auto [ma, mb] = contactMaterials(patch.a, patch.b, patch.plane);
      const double friction = std::sqrt(ma->friction * mb->friction);
      const double restitution = std::max(ma->restitution, mb->restitution);
      const Side sideA = sideOf(patch.a, patchPoints_[j].kindA), sideB = sideOf(patch.b, patchPoints_[j].kindB);
      // a deformable particle is a point mass: a rigid body it touches takes the impulse on the line through
      // the particle's centre (equal and opposite on one line, so the pair keeps its angular momentum), and
      // the particle's overlap is left to the substeps' contacts (a position correction here would move it
      // without momentum, and carry its moment of momentum away)
      const bool deformableA = sideA.kind == BodyKind::Deformable, deformableB = sideB.kind == BodyKind::Deformable;
      const auto addPoint = [&](const ParticleContact& c, const Vec3& normal, double depth, const Vec3& frictionOffset) {
        ContactPointInput& in = contactPoints_[out];
        pointParticles_[out++] = {c.a, c.b};
        in.a = slotOf(patch.a, sideA.kind, c.a);
        in.b = c.b.valid() ? slotOf(patch.b, sideB.kind, c.b) : ContactPointInput::kFixed;
        const Vec3& at = deformableA ? particles_.position[c.a.index()]
                         : deformableB && c.b.valid() ? particles_.position[c.b.index()]
                                                      : c.point;
        in.rA = arm(sideA, at);
        in.rB = arm(sideB, at);
        in.normal = normal;
        in.frictionOffset = frictionOffset;
        in.depth = depth;
        const double rsum = particles_.radius[c.a.index()] + (c.b.valid() ? particles_.radius[c.b.index()] : 0.0);
        in.slop = deformableA || deformableB ? std::numeric_limits<double>::infinity() : settings_.slop * rsum;
        in.friction = friction;
        in.restitution = restitution;
        in.key = (static_cast<std::uint64_t>(c.a.value) << 32) |
                 (c.b.valid() ? c.b.value : (0x80000000u | static_cast<std::uint32_t>(c.plane.value)));
      };
      if (mode == kRaw) {
        for (std::uint32_t k = 0; k < count; ++k)
          addPoint(cs.contacts[kept[k]], cs.contacts[kept[k]].normal, cs.contacts[kept[k]].depth, Vec3::Zero());
        continue;
      }
      // friction that resists twisting as the contact area does: uniform pressure over the lattice cells of
      // the touching particles on the side with fewer of them (a crate on a floor: its bottom layer), each
      // cell a square as wide as its particle. The patch's points carry their friction scaled out from the
      // area's centre to that area's mean distance from it, so that a patch reduced to four corners resists
      // twisting as the whole face does. (A deformable body's particles are point masses: their friction
      // acts through their centres)
      const bool turns = sideA.kind != BodyKind::Deformable && sideB.kind != BodyKind::Deformable;
      const bool reduce = mode == kReduced;
      const std::array<std::uint32_t, 4> reduced = reduce ? manifoldOfFour(cs, kept, count, ps.depthAlongNormal)
                                                          : std::array<std::uint32_t, 4>{};
      Vec3 centre = Vec3::Zero();
      const auto inPlane = [&](const Vec3& x) -> Vec3 {
        const Vec3 d = x - centre;
        return d - d.dot(patch.normal) * patch.normal;
      };
      double scale = 1.0;
      if (turns) {
        // (the touching particles of each side, each counted once: marked, then unmarked)
        std::array<std::uint32_t, 2> touching{};
        std::array<Vec3, 2> sum{Vec3::Zero(), Vec3::Zero()};
        for (std::uint32_t k = 0; k < count; ++k) {
          const ParticleContact& c = cs.contacts[kept[k]];
          std::size_t side = 0;
          for (const ParticleId q : {c.a, c.b}) {
            if (q.valid() && !seen[q.index()]) {
              seen[q.index()] = 1;
              ++touching[side];
              sum[side] += particles_.position[q.index()];
            }
            ++side;
          }
        }
        const std::size_t side = !first.b.valid() || touching[0] <= touching[1] ? 0 : 1;
        centre = sum[side] / static_cast<double>(touching[side]);
        double area = 0.0;
        for (std::uint32_t k = 0; k < count; ++k) {
          const ParticleContact& c = cs.contacts[kept[k]];
          const ParticleId q = side == 0 ? c.a : c.b;
          if (seen[q.index()]) area += cellLever(inPlane(particles_.position[q.index()]), 2.0 * particles_.radius[q.index()]);
          seen[c.a.index()] = 0;
          if (c.b.valid()) seen[c.b.index()] = 0;
        }
        area /= static_cast<double>(touching[side]);
        double lever = 0.0;  // (the points' mean distance from the centre)
        if (reduce) {
          for (const std::uint32_t k : reduced) lever += inPlane(cs.contacts[kept[k]].point).norm() / 4.0;
        } else {
          for (std::uint32_t k = 0; k < count; ++k) lever += inPlane(cs.contacts[kept[k]].point).norm() / count;
        }
        if (lever > 0.0) scale = area / lever;
      }
      const auto offsetOf = [&](const ParticleContact& c) -> Vec3 { return turns ? Vec3((scale - 1.0) * inPlane(c.point)) : Vec3::Zero(); };
      if (reduce) {
        for (const std::uint32_t k : reduced) addPoint(cs.contacts[kept[k]], patch.normal, ps.depthAlongNormal[kept[k]], offsetOf(cs.contacts[kept[k]]));
      } else {
        for (std::uint32_t k = 0; k < count; ++k)
          addPoint(cs.contacts[kept[k]], normalOf(patch, kept[k]), ps.depthAlongNormal[kept[k]], offsetOf(cs.contacts[kept[k]]));
      }
    }
  };
  // (patches differ in cost, a reduced one most: handed out in chunks, with the solver's plan as one more
  // item where one process solves)
  const bool planHere = planned && !divided;
  if (pool_ && pool_->worthSharing(np, 512)) {
    if (planHere) {
      const std::size_t chunks = ThreadPool::kChunksPerWorker * static_cast<std::size_t>(pool_->workers());
      pool_->runItems(chunks + 1, [&](int worker, std::size_t item) {
        if (item == 0) solver_.plan(solverBodies_, pointBodies_);
        else fill(worker, np * (item - 1) / chunks, np * item / chunks);
      });
    } else {
      pool_->runChunks(np, fill);
    }
  } else {
    if (planHere) solver_.plan(solverBodies_, pointBodies_);
    fill(0, 0, np);
  }
}

std::pair<const Material*, const Material*> World::contactMaterials(ParticleId a, ParticleId b, PlaneId plane) const {
  const Material& ma = materials_[bodies_.info[particles_.body[a.index()].index()].material.index()];
  const MaterialId mb = plane.valid() ? planes_[plane.index()].material : bodies_.info[particles_.body[b.index()].index()].material;
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
    const auto kindOf = [&](BodyId b) { return b.valid() ? bodies_.info[b.index()].kind : BodyKind::Static; };
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
  // rigid bodies are independent: shared among the workers
  const auto rigid = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const BodyId id = rigidBodies_[i];
      const std::uint32_t k = id.index() < bodySolverIndex_.size() ? bodySolverIndex_[id.index()] : ContactPointInput::kFixed;
      if (k != ContactPointInput::kFixed) integrateRigidPose(bodies_.state[id.index()], dt, solverBodies_[k].pv, solverBodies_[k].pw);
      else integrateRigidPose(bodies_.state[id.index()], dt);
      updateRigidParticles(id);
    }
  };
  if (pool_ && pool_->worthSharing(rigidBodies_.size(), 256)) pool_->run(rigidBodies_.size(), rigid);
  else rigid(0, 0, rigidBodies_.size());
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
    const bool aDef = bodies_.info[patch.a.index()].kind == BodyKind::Deformable;
    const bool bDef = patch.b.valid() && bodies_.info[patch.b.index()].kind == BodyKind::Deformable;
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
    if (bodies_.info[b.index()].kind != BodyKind::Rigid || s.invMass == 0.0) continue;
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

void World::updateRigidParticles(BodyId id) {
  const ParticleBounds box = placeRigidParticles(bodies_.state[id.index()], bodies_.info[id.index()].particles,
                                                 particles_.local.data(), particles_.radius.data(),
                                                 particles_.position.data(), particles_.velocity.data());
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
