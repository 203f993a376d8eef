#include "engine/world.hpp"

#include <chrono>
#include <cmath>

#include "dynamics/contact_solver.hpp"
#include "dynamics/deformable_integrator.hpp"
#include "dynamics/mass_properties.hpp"
#include "dynamics/rigid_integrator.hpp"

namespace volpar {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

bool finite(const Vec3& v) { return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z()); }

}  // namespace

World::World(const WorldSettings& settings) : settings_(settings) {
  narrowPhase_.setSettings(settings.planes);
  SolverSettings solver = settings.solver;
  solver.iterations = settings.solverIterations;
  solver.positionIterations = settings.solverIterations;
  contactFinder_.setMargin(settings_.contactMargin);
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
  return in;
}

MaterialId World::addMaterial(const Material& material) {
  materials_.push_back(material);
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

  const MassProperties mp = computeMassProperties(cloud.positions, cloud.radii, masses);
  const PrincipalAxes axes = principalAxes(mp.inertia);

  BodyInfo info;
  info.name = def.name;
  info.kind = def.kind;
  info.material = def.material;
  info.mass = mp.mass;
  info.inertiaLocal = axes.moments;
  info.principalInShape = axes.rotation;
  info.comInShape = mp.centre;
  info.source = def.source;

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
    particles_.invMass[p] = def.kind == BodyKind::Static ? 0.0 : 1.0 / masses[i];
    particles_.body[p] = id;
    particles_.local[p] = toPrincipal * (cloud.positions[i] - mp.centre);
    if (cloud.surface[i]) {
      particles_.flags[p] |= kParticleSurface;
      const std::uint8_t features = i < cloud.features.size() ? cloud.features[i] : 0;
      if (features == 2) particles_.flags[p] |= kParticleEdge;
      if (features >= 3) particles_.flags[p] |= kParticleCorner;
      // rigid and static: principal frame; deformable: world frame
      const Quat toCache = def.kind == BodyKind::Deformable ? def.orientation : toPrincipal;
      std::array<Vec3, 3> faces{};
      std::size_t nf = 0;
      if (i < cloud.featureNormals.size())
        for (; nf < std::min<std::size_t>(features, 3); ++nf) faces[nf] = toCache * cloud.featureNormals[i][nf];
      particles_.normalIndex[p] = normals_.add(toCache * cloud.normals[i], std::span<const Vec3>(faces.data(), nf));
    }
  }
  for (const auto& c : cloud.connectors) {
    const ParticleId a(first.index() + c[0]);
    const ParticleId b(first.index() + c[1]);
    const double rest = (cloud.positions[c[1]] - cloud.positions[c[0]]).norm();
    const ConnectorId cid = connectors_.add(a, b, rest, def.connectors);
    if (def.kind == BodyKind::Deformable) deformableConnectors_.push_back(cid);
  }
  bodies_.add(state, std::move(info));
  bodyBoxes_.emplace_back();

  if (def.kind == BodyKind::Deformable) {
    deformableBodies_.push_back(id);
    for (std::size_t i = 0; i < n; ++i) {
      const std::size_t p = first.index() + i;
      particles_.position[p] = def.position + def.orientation * cloud.positions[i];
      particles_.velocity[p] =
          def.linearVelocity + def.angularVelocity.cross(particles_.position[p] - state.position);
      deformableParticles_.emplace_back(p);
    }
    updateDeformableBodyState(id);
  } else {
    if (def.kind == BodyKind::Rigid) rigidBodies_.push_back(id);
    updateRigidParticles(id);
  }
  for (std::size_t i = 0; i < n; ++i) maxRadius_ = std::max(maxRadius_, cloud.radii[i]);
  broadphase_.setMargin(settings_.broadphaseMargin > 0.0 ? settings_.broadphaseMargin : maxRadius_);
  broadphase_.addBody(id, bodyBoxes_[id.index()], def.kind == BodyKind::Static);
  contactFinder_.addBody(id, particles_, bodies_);
  contactsStale_ = true;
  return id;
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
}

std::size_t World::recomputeNormals(std::span<const ParticleId> ids) {
  const std::size_t n = volpar::recomputeNormals(ids, particles_, bodies_, contactFinder_, normals_);
  stats_.normalsRecomputed += n;
  return n;
}

void World::detectCollisions() {
  auto t = Clock::now();
  for (const BodyId id : rigidBodies_)
    broadphase_.moveBody(id, bodyBoxes_[id.index()], bodies_.state[id.index()].linearVelocity * settings_.dt);
  for (const BodyId id : deformableBodies_)
    broadphase_.moveBody(id, bodyBoxes_[id.index()], bodies_.state[id.index()].linearVelocity * settings_.dt);
  stats_.proxyMoves = broadphase_.reinsertions();
  broadphase_.findPairs(planes_, bodyPairs_, planePairs_);
  stats_.time.broadphase = secondsSince(t);

  t = Clock::now();
  contactFinder_.find(particles_, bodies_, connectors_, bodyPairs_, planePairs_, planes_, bodyBoxes_, contacts_);
  stats_.time.particleContacts = secondsSince(t);

  t = Clock::now();
  narrowPhase_.run(narrowPhaseInput(), contacts_, patches_);
  stats_.time.narrowPhase = secondsSince(t);
  const NarrowPhaseStats& np = patches_.stats;
  stats_.patches = np.patches;
  stats_.patchesByCase = np.byCase;
  stats_.candidates = np.candidates;
  stats_.lookAheads = np.lookAheads;
  stats_.unvalidatedPatches = np.unvalidated;
  stats_.bodyPairs = bodyPairs_.size();
  stats_.planePairs = planePairs_.size();
  stats_.contacts = 0;
  stats_.contactGroups = contacts_.groups.size();
  stats_.maxPenetration = 0.0;
  for (const ParticleContact& c : contacts_.contacts) {
    if (!c.touching()) continue;
    ++stats_.contacts;
    stats_.maxPenetration = std::max(stats_.maxPenetration, c.depth);
  }
  contactsStale_ = false;
}

void World::integrateVelocities() {
  for (const BodyId id : rigidBodies_) integrateRigidVelocity(bodies_.state[id.index()], settings_.gravity, settings_.dt);
  for (const ParticleId p : deformableParticles_)
    if (particles_.invMass[p.index()] > 0.0) particles_.velocity[p.index()] += settings_.gravity * settings_.dt;
}

std::uint32_t World::solverIndex(ParticleId p) {
  const BodyId b = particles_.body[p.index()];
  const BodyInfo& info = bodies_.info[b.index()];
  if (info.kind == BodyKind::Static) return ContactPointInput::kFixed;
  std::uint32_t& slot = info.kind == BodyKind::Rigid ? bodySolverIndex_[b.index()] : particleSolverIndex_[p.index()];
  if (slot != ContactPointInput::kFixed) return slot;
  slot = static_cast<std::uint32_t>(solverBodies_.size());
  SolverBody sb;
  if (info.kind == BodyKind::Rigid) {
    const BodyState& s = bodies_.state[b.index()];
    sb.v = s.linearVelocity;
    sb.w = s.angularVelocity;
    sb.invMass = s.invMass;
    sb.invInertia = s.invInertiaWorld;
    solverBodyOwner_.push_back(b);
    solverParticleOwner_.emplace_back();
  } else {
    sb.v = particles_.velocity[p.index()];
    sb.invMass = particles_.invMass[p.index()];
    solverBodyOwner_.emplace_back();
    solverParticleOwner_.push_back(p);
  }
  solverBodies_.push_back(sb);
  return slot;
}

void World::buildContactPoints() {
  contactPoints_.clear();
  const ContactSet& cs = contacts_;
  const PatchSet& ps = patches_;
  auto combined = [&](ParticleId a, ParticleId b, PlaneId plane, double& friction, double& restitution) {
    const Material& ma = materials_[bodies_.info[particles_.body[a.index()].index()].material.index()];
    const MaterialId mbId = plane.valid() ? planes_[plane.index()].material
                                          : bodies_.info[particles_.body[b.index()].index()].material;
    const Material& mb = materials_[mbId.index()];
    friction = std::sqrt(ma.friction * mb.friction);
    restitution = std::max(ma.restitution, mb.restitution);
  };
  auto arm = [&](ParticleId p, const Vec3& point) -> Vec3 {
    const BodyId b = particles_.body[p.index()];
    return bodies_.info[b.index()].kind == BodyKind::Rigid ? Vec3(point - bodies_.state[b.index()].position) : Vec3::Zero();
  };
  auto addPoint = [&](const ParticleContact& c, const Vec3& normal, double depth) {
    ContactPointInput in;
    in.a = solverIndex(c.a);
    in.b = c.b.valid() ? solverIndex(c.b) : ContactPointInput::kFixed;
    if (in.a == ContactPointInput::kFixed && in.b == ContactPointInput::kFixed) return;
    in.rA = arm(c.a, c.point);
    in.rB = c.b.valid() ? arm(c.b, c.point) : Vec3::Zero();
    in.normal = normal;
    in.depth = depth;
    const double rsum = particles_.radius[c.a.index()] + (c.b.valid() ? particles_.radius[c.b.index()] : 0.0);
    in.slop = settings_.slop * rsum;
    combined(c.a, c.b, c.plane, in.friction, in.restitution);
    in.key = (static_cast<std::uint64_t>(c.a.value) << 32) |
             (c.b.valid() ? c.b.value : (0x80000000u | static_cast<std::uint32_t>(c.plane.value)));
    contactPoints_.push_back(in);
  };
  for (const ContactPatch& patch : ps.patches) {
    const std::uint32_t* idx = ps.contacts.data() + patch.first;
    if (settings_.rawNormals) {
      for (std::uint32_t k = 0; k < patch.count; ++k) addPoint(cs.contacts[idx[k]], cs.contacts[idx[k]].normal, cs.contacts[idx[k]].depth);
      continue;
    }
    const bool rigidPair = bodies_.info[patch.a.index()].kind != BodyKind::Deformable &&
                           (!patch.b.valid() || bodies_.info[patch.b.index()].kind != BodyKind::Deformable);
    if (!rigidPair || patch.count <= 4) {
      for (std::uint32_t k = 0; k < patch.count; ++k) addPoint(cs.contacts[idx[k]], patch.normal, ps.depthAlongNormal[idx[k]]);
      continue;
    }
    // a rigid patch becomes a manifold of at most four points (Bullet's choice): the deepest, the one
    // farthest from it, the one farthest from their line, and the one that adds most area on the far side
    reduced_.clear();
    auto pointOf = [&](std::uint32_t k) -> const Vec3& { return cs.contacts[idx[k]].point; };
    std::uint32_t deepest = 0;
    for (std::uint32_t k = 1; k < patch.count; ++k)
      if (ps.depthAlongNormal[idx[k]] > ps.depthAlongNormal[idx[deepest]]) deepest = k;
    reduced_.push_back(deepest);
    auto best = [&](auto score) {
      std::uint32_t arg = 0;
      double top = -1.0;
      for (std::uint32_t k = 0; k < patch.count; ++k) {
        if (std::find(reduced_.begin(), reduced_.end(), k) != reduced_.end()) continue;
        const double v = score(pointOf(k));
        if (v > top) {
          top = v;
          arg = k;
        }
      }
      return arg;
    };
    const Vec3 p0 = pointOf(deepest);
    reduced_.push_back(best([&](const Vec3& x) { return (x - p0).squaredNorm(); }));
    const Vec3 p1 = pointOf(reduced_[1]);
    reduced_.push_back(best([&](const Vec3& x) { return (x - p0).cross(x - p1).squaredNorm(); }));
    const Vec3 p2 = pointOf(reduced_[2]);
    const Vec3 triNormal = (p1 - p0).cross(p2 - p0);
    reduced_.push_back(best([&](const Vec3& x) {
      // area added outside the triangle: the largest of the three triangles the point makes with an edge
      const double a = (x - p0).cross(x - p1).dot(triNormal), b = (x - p1).cross(x - p2).dot(triNormal),
                   c = (x - p2).cross(x - p0).dot(triNormal);
      return std::max({-a, -b, -c});
    }));
    for (const std::uint32_t k : reduced_) addPoint(cs.contacts[idx[k]], patch.normal, ps.depthAlongNormal[idx[k]]);
  }
}

void World::solveContacts() {
  // solver bodies of this step: only those in contact
  for (const BodyId b : solverBodyOwner_)
    if (b.valid()) bodySolverIndex_[b.index()] = ContactPointInput::kFixed;
  for (const ParticleId p : solverParticleOwner_)
    if (p.valid()) particleSolverIndex_[p.index()] = ContactPointInput::kFixed;
  solverBodies_.clear();
  solverBodyOwner_.clear();
  solverParticleOwner_.clear();
  bodySolverIndex_.resize(bodies_.size(), ContactPointInput::kFixed);
  particleSolverIndex_.resize(particles_.size(), ContactPointInput::kFixed);
  buildContactPoints();
  stats_.contactPoints = contactPoints_.size();
  if (contactPoints_.empty()) return;
  solver_.solve(solverBodies_, contactPoints_, settings_.dt);
  stats_.warmStarted = solver_.warmStarted();
  // velocities back to the bodies and particles
  for (std::size_t i = 0; i < solverBodies_.size(); ++i) {
    const SolverBody& sb = solverBodies_[i];
    if (solverBodyOwner_[i].valid()) {
      BodyState& s = bodies_.state[solverBodyOwner_[i].index()];
      s.linearVelocity = sb.v;
      s.angularVelocity = sb.w;
    } else {
      particles_.velocity[solverParticleOwner_[i].index()] = sb.v;
    }
  }
}

void World::integratePositions() {
  const double dt = settings_.dt;
  for (const BodyId id : rigidBodies_) {
    const std::uint32_t k = id.index() < bodySolverIndex_.size() ? bodySolverIndex_[id.index()] : ContactPointInput::kFixed;
    if (k != ContactPointInput::kFixed) integrateRigidPose(bodies_.state[id.index()], dt, solverBodies_[k].pv, solverBodies_[k].pw);
    else integrateRigidPose(bodies_.state[id.index()], dt);
    updateRigidParticles(id);
  }
  DeformableStepInput in;
  in.particles = deformableParticles_;
  in.connectors = deformableConnectors_;
  in.gravity = Vec3::Zero();  // applied in integrateVelocities, before the contact solver
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
  integrateDeformables(particles_, connectors_, in, scratch_);
  updateDeformableBodyStates();
}

void World::updateRigidParticles(BodyId id) {
  const BodyState& s = bodies_.state[id.index()];
  const Mat3 r = s.orientation.toRotationMatrix();
  Aabb box;
  for (const ParticleId p : bodies_.info[id.index()].particles) {
    const Vec3 arm = r * particles_.local[p.index()];
    particles_.position[p.index()] = s.position + arm;
    particles_.velocity[p.index()] = s.linearVelocity + s.angularVelocity.cross(arm);
    box.extend(Aabb::sphere(particles_.position[p.index()], particles_.radius[p.index()]));
  }
  bodyBoxes_[id.index()] = box;
}

void World::updateDeformableBodyStates() {
  for (const BodyId id : deformableBodies_) updateDeformableBodyState(id);
}

void World::updateDeformableBodyState(BodyId id) {
  // centre of mass, its velocity, and the angular velocity I^-1 L about it
  {
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
    Vec3 l = Vec3::Zero();
    for (const ParticleId p : info.particles) {
      const std::size_t i = p.index();
      const Vec3 d = particles_.position[i] - x;
      const double m = particles_.mass[i];
      const double own = 0.4 * m * particles_.radius[i] * particles_.radius[i];
      inertia += (own + m * d.squaredNorm()) * Mat3::Identity() - m * d * d.transpose();
      l += m * d.cross(particles_.velocity[i] - v);
    }
    s.position = x;
    s.linearVelocity = v;
    s.angularVelocity = inertia.ldlt().solve(l);
    Aabb box;
    for (const ParticleId p : info.particles)
      box.extend(Aabb::sphere(particles_.position[p.index()], particles_.radius[p.index()]));
    bodyBoxes_[id.index()] = box;
  }
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

Vec3 World::particleNormal(ParticleId id) const {
  const std::int32_t k = particles_.normalIndex[id.index()];
  if (k < 0) return Vec3::Zero();
  const BodyId b = particles_.body[id.index()];
  if (bodies_.info[b.index()].kind == BodyKind::Deformable) return normals_[k];
  return bodies_.state[b.index()].orientation * normals_[k];
}

EnergyReport World::energy() const {
  EnergyReport e;
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const BodyState& s = bodies_.state[b];
    const BodyInfo& info = bodies_.info[b];
    if (info.kind == BodyKind::Static) continue;
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
    if (info.kind == BodyKind::Static) continue;
    p += info.mass * bodies_.state[b].linearVelocity;
  }
  return p;
}

Vec3 World::angularMomentum() const {
  Vec3 l = Vec3::Zero();
  for (std::size_t b = 0; b < bodies_.size(); ++b) {
    const BodyInfo& info = bodies_.info[b];
    const BodyState& s = bodies_.state[b];
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
