// World::saveState and World::restoreState: the world's checkpoint (engine/core/state_archive.hpp).

#include <algorithm>
#include <cmath>
#include <cstring>
#include <span>
#include <string>

#include "volpar/collision/collision_state.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

namespace {

/// Copies a checkpoint's array into a store's (which may take its memory from another allocator).
template <class To, class From>
void assignFrom(To& to, const From& from) {
  to.assign(from.begin(), from.end());
}

constexpr std::uint32_t kNone = 0xffffffffu;

template <class Tag>
std::vector<std::uint32_t> rawIds(std::span<const Id<Tag>> ids) {
  std::vector<std::uint32_t> out(ids.size());
  for (std::size_t i = 0; i < ids.size(); ++i) out[i] = ids[i].value;
  return out;
}

/// Lists of ids, one per row, as "<name>" (all of them) and "<name>_start" (where each row's begin, and one
/// past the last).
template <class Tag>
void putLists(StateArchive& archive, const std::string& name, const std::vector<std::vector<Id<Tag>>>& lists) {
  std::vector<std::uint32_t> start{0}, all;
  for (const auto& list : lists) {
    for (const Id<Tag> id : list) all.push_back(id.value);
    start.push_back(static_cast<std::uint32_t>(all.size()));
  }
  archive.put(name, std::span<const std::uint32_t>(all));
  archive.put(name + "_start", std::span<const std::uint32_t>(start));
}

/// Reads lists written by putLists: `rows` of them, each id below `bound`.
template <class Tag>
std::vector<std::vector<Id<Tag>>> getLists(StateReader& r, const std::string& name, std::size_t rows, std::size_t bound) {
  const std::vector<std::uint32_t> all = r.get<std::uint32_t>(name);
  const std::vector<std::uint32_t> start = r.get<std::uint32_t>(name + "_start", 1, rows + 1);
  std::vector<std::vector<Id<Tag>>> lists;
  if (!r.ok()) return lists;
  r.checkIndices(all, bound, name);
  if (start[0] != 0 || start[rows] != all.size()) r.fail("the checkpoint's " + name + " do not add up");
  for (std::size_t i = 0; r.ok() && i < rows; ++i)
    if (start[i + 1] < start[i]) r.fail("the checkpoint's " + name + " do not add up");
  if (!r.ok()) return lists;
  lists.resize(rows);
  for (std::size_t i = 0; i < rows; ++i)
    for (std::uint32_t k = start[i]; k < start[i + 1]; ++k) lists[i].emplace_back(all[k]);
  return lists;
}

std::vector<std::int64_t> counters(const StepStats& s) {
  std::vector<std::int64_t> c{s.step,
                              static_cast<std::int64_t>(s.bodyPairs),
                              static_cast<std::int64_t>(s.planePairs),
                              static_cast<std::int64_t>(s.proxyMoves),
                              static_cast<std::int64_t>(s.contacts),
                              static_cast<std::int64_t>(s.contactGroups),
                              static_cast<std::int64_t>(s.patches),
                              static_cast<std::int64_t>(s.candidates),
                              static_cast<std::int64_t>(s.lookAheads),
                              static_cast<std::int64_t>(s.unvalidatedPatches),
                              static_cast<std::int64_t>(s.contactLinePatches),
                              static_cast<std::int64_t>(s.lookAheadsDecided),
                              static_cast<std::int64_t>(s.patchesReused),
                              static_cast<std::int64_t>(s.normalsRecomputed),
                              static_cast<std::int64_t>(s.contactPoints),
                              static_cast<std::int64_t>(s.warmStarted),
                              static_cast<std::int64_t>(s.heavyIslands),
                              static_cast<std::int64_t>(s.connectorsBroken),
                              static_cast<std::int64_t>(s.bodiesCreated)};
  for (const std::size_t n : s.patchesByCase) c.push_back(static_cast<std::int64_t>(n));
  return c;
}

void takeCounters(const std::vector<std::int64_t>& c, StepStats& s) {
  std::size_t k = 0;
  const auto next = [&] { return static_cast<std::size_t>(std::max<std::int64_t>(c[k++], 0)); };
  s = StepStats{};
  s.step = c[k++];
  s.bodyPairs = next();
  s.planePairs = next();
  s.proxyMoves = next();
  s.contacts = next();
  s.contactGroups = next();
  s.patches = next();
  s.candidates = next();
  s.lookAheads = next();
  s.unvalidatedPatches = next();
  s.contactLinePatches = next();
  s.lookAheadsDecided = next();
  s.patchesReused = next();
  s.normalsRecomputed = next();
  s.contactPoints = next();
  s.warmStarted = next();
  s.heavyIslands = next();
  s.connectorsBroken = next();
  s.bodiesCreated = next();
  for (std::size_t& n : s.patchesByCase) n = next();
}

/// FNV-1a over the bytes of what a run never changes in the connectors: their particles, kinds, lengths,
/// stiffnesses and strengths.
std::uint64_t connectorFingerprint(const ConnectorStore& c) {
  std::uint64_t h = 1469598103934665603ull;
  const auto mix = [&](const void* data, std::size_t bytes) {
    const auto* b = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) h = (h ^ b[i]) * 1099511628211ull;
  };
  mix(c.a.data(), c.a.size() * sizeof(ParticleId));
  mix(c.b.data(), c.b.size() * sizeof(ParticleId));
  mix(c.kind.data(), c.kind.size() * sizeof(ConnectorKind));
  for (const std::vector<double>* v : {&c.restLength, &c.stiffness, &c.damping, &c.breakLimit, &c.compressionLimit, &c.bondRadius,
                                       &c.youngsModulus, &c.poissonRatio, &c.tensileStrength, &c.shearStrength})
    mix(v->data(), v->size() * sizeof(double));
  return h;
}

constexpr std::size_t kCounters = 19 + std::tuple_size_v<decltype(StepStats::patchesByCase)>;

}  // namespace

void World::saveState(StateArchive& a) const {
  const std::int64_t counts[5] = {static_cast<std::int64_t>(particles_.size()), static_cast<std::int64_t>(connectors_.size()),
                                  static_cast<std::int64_t>(bodies_.size()), static_cast<std::int64_t>(planes_.size()),
                                  static_cast<std::int64_t>(materials_.size())};
  a.put("world/particles_connectors_bodies_planes_materials", std::span<const std::int64_t>(counts));
  a.putScalar("world/step", stepIndex_);
  a.putScalar("world/breakage_energy", breakageEnergy_);
  a.put("world/step_counters", std::span<const std::int64_t>(counters(stats_)));
  a.putScalar("world/max_penetration", stats_.maxPenetration);

  // particles
  const ParticleStore& p = particles_;
  a.putVec3("particles/position", p.position);
  a.putVec3("particles/velocity", p.velocity);
  a.putVec3("particles/local", p.local);
  a.put("particles/radius", std::span<const double>(p.radius));
  a.put("particles/mass", std::span<const double>(p.mass));
  a.put("particles/inverse_mass", std::span<const double>(p.invMass));
  a.put("particles/own_inertia", std::span<const double>(p.ownInertia));
  a.put("particles/body", std::span<const std::uint32_t>(rawIds(std::span<const BodyId>(p.body))));
  std::vector<std::uint32_t> normalIndex(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) normalIndex[i] = p.normalIndex[i] < 0 ? kNone : static_cast<std::uint32_t>(p.normalIndex[i]);
  a.put("particles/normal_index", std::span<const std::uint32_t>(normalIndex));
  a.put("particles/flags", std::span<const std::uint8_t>(p.flags));
  a.put("particles/opened", std::span<const std::uint8_t>(opened_));

  // connectors
  const ConnectorStore& c = connectors_;
  // what breaks, and the deformable connectors' directions; the rest is the scene's (a fingerprint of it)
  a.put("connectors/broken", std::span<const std::uint8_t>(c.broken));
  std::vector<Vec3> direction;
  for (const ConnectorId id : deformableConnectors_) direction.push_back(connectorDirection_[id.index()]);
  a.putVec3("connectors/deformable_direction", direction);
  a.putScalar("connectors/fingerprint", static_cast<std::int64_t>(connectorFingerprint(c)));

  // bodies
  const std::size_t nb = bodies_.size();
  std::vector<Vec3> position(nb), linear(nb), angular(nb), invInertia(nb), inertia(nb), com(nb), boxLo(nb), boxHi(nb);
  std::vector<Quat> orientation(nb), principal(nb);
  std::vector<Mat3> invInertiaWorld(nb), residual(nb);
  std::vector<double> invMass(nb), mass(nb);
  std::vector<std::uint8_t> bodyKind(nb), alive(nb), breakableFlag(nb);
  std::vector<std::uint32_t> material(nb), parent(nb), glued(nb);
  std::vector<std::int64_t> created(nb), retired(nb);
  std::vector<std::vector<ParticleId>> members(nb);
  for (std::size_t i = 0; i < nb; ++i) {
    const BodyState& s = bodies_.state[i];
    const BodyInfo& info = bodies_.info[i];
    position[i] = s.position;
    orientation[i] = s.orientation;
    linear[i] = s.linearVelocity;
    angular[i] = s.angularVelocity;
    invInertia[i] = s.invInertiaLocal;
    invMass[i] = s.invMass;
    invInertiaWorld[i] = s.invInertiaWorld;
    bodyKind[i] = static_cast<std::uint8_t>(info.kind);
    material[i] = info.material.value;
    mass[i] = info.mass;
    inertia[i] = info.inertiaLocal;
    principal[i] = info.principalInShape;
    com[i] = info.comInShape;
    residual[i] = info.inertiaResidual;
    members[i] = info.particles;
    alive[i] = info.alive ? 1 : 0;
    created[i] = info.createdStep;
    retired[i] = info.retiredStep;
    parent[i] = info.parent.value;
    glued[i] = info.gluedInto.value;
    breakableFlag[i] = info.breakable ? 1 : 0;
    boxLo[i] = bodyBoxes_[i].lo;
    boxHi[i] = bodyBoxes_[i].hi;
  }
  a.putVec3("bodies/position", position);
  a.putQuat("bodies/orientation", orientation);
  a.putVec3("bodies/linear_velocity", linear);
  a.putVec3("bodies/angular_velocity", angular);
  a.putVec3("bodies/inverse_inertia_local", invInertia);
  a.put("bodies/inverse_mass", std::span<const double>(invMass));
  a.putMat3("bodies/inverse_inertia_world", invInertiaWorld);
  a.put("bodies/kind", std::span<const std::uint8_t>(bodyKind));
  a.put("bodies/material", std::span<const std::uint32_t>(material));
  a.put("bodies/mass", std::span<const double>(mass));
  a.putVec3("bodies/inertia_local", inertia);
  a.putQuat("bodies/principal_in_shape", principal);
  a.putVec3("bodies/com_in_shape", com);
  a.putMat3("bodies/inertia_residual", residual);
  putLists(a, "bodies/particles", members);
  putLists(a, "bodies/connectors", bodyConnectors_);
  a.put("bodies/alive", std::span<const std::uint8_t>(alive));
  a.put("bodies/created_step", std::span<const std::int64_t>(created));
  a.put("bodies/retired_step", std::span<const std::int64_t>(retired));
  a.put("bodies/parent", std::span<const std::uint32_t>(parent));
  a.put("bodies/glued_into", std::span<const std::uint32_t>(glued));
  a.put("bodies/breakable", std::span<const std::uint8_t>(breakableFlag));
  a.putVec3("bodies/box_lo", boxLo);
  a.putVec3("bodies/box_hi", boxHi);

  // the broadphase's fat boxes of the bodies in it (alive ones)
  std::vector<std::uint32_t> proxied;
  std::vector<Vec3> fatLo, fatHi;
  for (std::size_t i = 0; i < nb; ++i)
    if (bodies_.info[i].alive) {
      proxied.push_back(static_cast<std::uint32_t>(i));
      const Aabb& fat = broadphase_.fatBox(BodyId(i));
      fatLo.push_back(fat.lo);
      fatHi.push_back(fat.hi);
    }
  a.put("broadphase/body", std::span<const std::uint32_t>(proxied));
  a.putVec3("broadphase/fat_lo", fatLo);
  a.putVec3("broadphase/fat_hi", fatHi);

  // bonded bodies' frames: the bonds they were built from and what was removed since
  std::vector<std::uint32_t> framed;
  std::vector<std::vector<ConnectorId>> frameBonds;
  std::vector<std::uint32_t> removedAll, removedStart{0};
  std::vector<double> displacements;
  std::vector<std::vector<ParticleId>> frameNodes;
  std::vector<Vec3> nodePositions;
  std::vector<Mat3> frameAxes;
  for (std::size_t i = 0; i < nb; ++i)
    if (const BondLoads* bl = bondLoads_[i].get()) {
      framed.push_back(static_cast<std::uint32_t>(i));
      frameBonds.emplace_back(bl->bonds().begin(), bl->bonds().end());
      frameNodes.emplace_back();
      for (const std::uint32_t q : bl->nodes()) frameNodes.back().emplace_back(q);
      nodePositions.insert(nodePositions.end(), bl->nodePositions().begin(), bl->nodePositions().end());
      frameAxes.push_back(bl->axes());
      removedAll.insert(removedAll.end(), bl->removed().begin(), bl->removed().end());
      removedStart.push_back(static_cast<std::uint32_t>(removedAll.size()));
      displacements.insert(displacements.end(), bl->displacements().begin(), bl->displacements().end());
    }
  a.put("bond_frames/body", std::span<const std::uint32_t>(framed));
  putLists(a, "bond_frames/bonds", frameBonds);
  a.put("bond_frames/removed", std::span<const std::uint32_t>(removedAll));
  a.put("bond_frames/removed_start", std::span<const std::uint32_t>(removedStart));
  a.put("bond_frames/displacements", std::span<const double>(displacements), 6);
  putLists(a, "bond_frames/nodes", frameNodes);
  a.putVec3("bond_frames/node_positions", nodePositions);
  a.putMat3("bond_frames/axes", frameAxes);

  normals_.save(a);
  saveContacts(a, contacts_);
  savePatches(a, patches_);
  narrowPhase_.saveCache(a);
  solver_.saveWarmStart(a);
}

Status World::restoreState(const StateArchive& archive) {
  StateReader r(archive);
  const auto refuse = [&]() -> Status { return Error{"", 0, 0, r.error()}; };
  const std::size_t np = particles_.size(), nc = connectors_.size(), built = bodies_.size();
  const std::vector<std::int64_t> counts = r.get<std::int64_t>("world/particles_connectors_bodies_planes_materials", 1, 5);
  if (!r.ok()) return refuse();
  if (counts[0] != static_cast<std::int64_t>(np) || counts[1] != static_cast<std::int64_t>(nc) ||
      counts[2] < static_cast<std::int64_t>(built) || counts[2] > static_cast<std::int64_t>(np + built) ||
      counts[3] != static_cast<std::int64_t>(planes_.size()) || counts[4] != static_cast<std::int64_t>(materials_.size()))
    return Error{"", 0, 0,
                 "the checkpoint is of a world with " + std::to_string(counts[0]) + " particles, " + std::to_string(counts[1]) +
                     " connectors, " + std::to_string(counts[2]) + " bodies, " + std::to_string(counts[3]) + " planes and " +
                     std::to_string(counts[4]) + " materials; the scene builds " + std::to_string(np) + ", " +
                     std::to_string(nc) + ", " + std::to_string(built) + ", " + std::to_string(planes_.size()) + " and " +
                     std::to_string(materials_.size())};
  const std::size_t nb = static_cast<std::size_t>(counts[2]);
  const std::int64_t step = r.i64("world/step");
  const double breakageEnergy = r.f64("world/breakage_energy");
  const std::vector<std::int64_t> stepCounters = r.get<std::int64_t>("world/step_counters", 1, kCounters);
  const double maxPenetration = r.f64("world/max_penetration");
  if (r.ok() && step < 0) r.fail("the checkpoint's step is negative");

  // particles
  ParticleStore p;
  assignFrom(p.position, r.vec3("particles/position", np));
  assignFrom(p.velocity, r.vec3("particles/velocity", np));
  assignFrom(p.local, r.vec3("particles/local", np));
  assignFrom(p.radius, r.get<double>("particles/radius", 1, np));
  assignFrom(p.mass, r.get<double>("particles/mass", 1, np));
  assignFrom(p.invMass, r.get<double>("particles/inverse_mass", 1, np));
  assignFrom(p.ownInertia, r.get<double>("particles/own_inertia", 1, np));
  const std::vector<std::uint32_t> particleBody = r.get<std::uint32_t>("particles/body", 1, np);
  const std::vector<std::uint32_t> normalIndex = r.get<std::uint32_t>("particles/normal_index", 1, np);
  assignFrom(p.flags, r.get<std::uint8_t>("particles/flags", 1, np));
  std::vector<std::uint8_t> opened = r.get<std::uint8_t>("particles/opened", 1, np);
  r.checkIndices(particleBody, nb, "particles' bodies");

  // connectors: which broke (the rest must be the scene's)
  std::vector<std::uint8_t> broken = r.get<std::uint8_t>("connectors/broken", 1, nc);
  const std::vector<Vec3> deformableDirection = r.vec3("connectors/deformable_direction", deformableConnectors_.size());
  const std::int64_t fingerprint = r.i64("connectors/fingerprint");
  if (r.ok() && fingerprint != static_cast<std::int64_t>(connectorFingerprint(connectors_)))
    r.fail("the checkpoint's connectors are not the scene's (another scene, seed or version)");
  // what a run never changes must be the scene's; the state must be finite and within the world's bounds
  // (a step could not survive it)
  const auto sameBits = [](std::span<const double> x, std::span<const double> y) {
    return x.size() == y.size() && (x.empty() || std::memcmp(x.data(), y.data(), x.size() * sizeof(double)) == 0);
  };
  if (r.ok() && (!sameBits(p.radius, particles_.radius) || !sameBits(p.mass, particles_.mass) ||
                 !sameBits(p.ownInertia, particles_.ownInertia) || !sameBits(p.invMass, particles_.invMass)))
    r.fail("the checkpoint's particles have other radii or masses than the scene's");
  constexpr double kWorldLimit = 1e9;  // [m], as World::addBody
  const auto bounded = [&](std::span<const Vec3> xs) {
    return std::all_of(xs.begin(), xs.end(), [&](const Vec3& x) { return x.allFinite() && x.cwiseAbs().maxCoeff() <= kWorldLimit; });
  };
  if (r.ok() && (!bounded(p.position) || !bounded(p.local) || !bounded(p.velocity) || !bounded(deformableDirection)))
    r.fail("the checkpoint has particles at non-finite or too distant positions, or with non-finite velocities");
  for (std::size_t i = 0; r.ok() && i < nc; ++i)
    if (broken[i] > 1) r.fail("checkpoint connector " + std::to_string(i) + " is neither broken nor whole");
  if (!r.ok()) return refuse();
  p.body.resize(np);
  p.normalIndex.resize(np);
  for (std::size_t i = 0; i < np; ++i) {
    p.body[i] = BodyId(particleBody[i]);
    p.normalIndex[i] = normalIndex[i] == kNone ? -1 : static_cast<std::int32_t>(std::min<std::uint32_t>(normalIndex[i], 0x7fffffffu));
  }

  // bodies
  const std::vector<Vec3> position = r.vec3("bodies/position", nb), linear = r.vec3("bodies/linear_velocity", nb),
                          angular = r.vec3("bodies/angular_velocity", nb),
                          invInertia = r.vec3("bodies/inverse_inertia_local", nb), inertia = r.vec3("bodies/inertia_local", nb),
                          com = r.vec3("bodies/com_in_shape", nb), boxLo = r.vec3("bodies/box_lo", nb),
                          boxHi = r.vec3("bodies/box_hi", nb);
  const std::vector<Quat> orientation = r.quat("bodies/orientation", nb), principal = r.quat("bodies/principal_in_shape", nb);
  const std::vector<Mat3> invInertiaWorld = r.mat3("bodies/inverse_inertia_world", nb), residual = r.mat3("bodies/inertia_residual", nb);
  const std::vector<double> invMass = r.get<double>("bodies/inverse_mass", 1, nb), mass = r.get<double>("bodies/mass", 1, nb);
  const std::vector<std::uint8_t> bodyKind = r.get<std::uint8_t>("bodies/kind", 1, nb), alive = r.get<std::uint8_t>("bodies/alive", 1, nb),
                                  breakableFlag = r.get<std::uint8_t>("bodies/breakable", 1, nb);
  const std::vector<std::uint32_t> material = r.get<std::uint32_t>("bodies/material", 1, nb),
                                   parent = r.get<std::uint32_t>("bodies/parent", 1, nb),
                                   glued = r.get<std::uint32_t>("bodies/glued_into", 1, nb);
  const std::vector<std::int64_t> created = r.get<std::int64_t>("bodies/created_step", 1, nb),
                                  retired = r.get<std::int64_t>("bodies/retired_step", 1, nb);
  std::vector<std::vector<ParticleId>> members = getLists<ParticleTag>(r, "bodies/particles", nb, np);
  std::vector<std::vector<ConnectorId>> bodyConnectors = getLists<ConnectorTag>(r, "bodies/connectors", nb, nc);
  r.checkIndices(material, materials_.size(), "bodies' materials");
  if (!r.ok()) return refuse();
  std::vector<std::uint8_t> owned(np, 0);
  for (std::size_t i = 0; i < nb && r.ok(); ++i) {
    const bool fragment = i >= built;
    const BodyKind k = static_cast<BodyKind>(std::min<std::uint8_t>(bodyKind[i], 3));
    if (bodyKind[i] > static_cast<std::uint8_t>(BodyKind::Static) || (!fragment && k != bodies_.info[i].kind) ||
        (fragment && k != BodyKind::Rigid) || alive[i] > 1 || (parent[i] != kNone && parent[i] >= nb) ||
        (glued[i] != kNone && glued[i] >= nb) || (!alive[i] && !members[i].empty()))
      r.fail("checkpoint body " + std::to_string(i) + " is not one the scene can have");
    for (const ParticleId q : members[i]) {
      if (owned[q.index()] || p.body[q.index()].index() != i) r.fail("checkpoint body " + std::to_string(i) + " shares a particle");
      owned[q.index()] = 1;
    }
  }
  for (std::size_t i = 0; i < np && r.ok(); ++i)
    if (!owned[i]) r.fail("checkpoint particle " + std::to_string(i) + " belongs to no body");
  for (std::size_t i = 0; i < nb && r.ok(); ++i) {
    const bool finite = position[i].allFinite() && linear[i].allFinite() && angular[i].allFinite() && invInertia[i].allFinite() &&
                        inertia[i].allFinite() && com[i].allFinite() && orientation[i].coeffs().allFinite() &&
                        principal[i].coeffs().allFinite() && invInertiaWorld[i].allFinite() && residual[i].allFinite() &&
                        std::isfinite(invMass[i]) && std::isfinite(mass[i]) &&
                        (!alive[i] || (boxLo[i].allFinite() && boxHi[i].allFinite() && (boxLo[i].array() <= boxHi[i].array()).all()));
    if (!finite) r.fail("checkpoint body " + std::to_string(i) + " has a non-finite state");
  }

  // the normal cache (its entries are what the particles' normal indices point into)
  NormalCache normals;
  if (r.ok()) normals.restore(r);
  for (std::size_t i = 0; i < np && r.ok(); ++i)
    if (p.normalIndex[i] >= 0 && static_cast<std::size_t>(p.normalIndex[i]) >= normals.size())
      r.fail("checkpoint particle " + std::to_string(i) + " points past the normal cache");
  if (r.ok() && !normals.countUsers(p.normalIndex)) r.fail("a checkpoint particle points to a free normal cache entry");

  // broadphase and bond frames
  const std::vector<std::uint32_t> proxied = r.get<std::uint32_t>("broadphase/body");
  const std::vector<Vec3> fatLo = r.vec3("broadphase/fat_lo", proxied.size()), fatHi = r.vec3("broadphase/fat_hi", proxied.size());
  std::size_t aliveCount = 0;
  for (std::size_t i = 0; i < nb && r.ok(); ++i) aliveCount += alive[i];
  if (r.ok() && proxied.size() != aliveCount) r.fail("the checkpoint's broadphase does not hold every body alive");
  for (std::size_t k = 0; k < proxied.size() && r.ok(); ++k)
    if (proxied[k] >= nb || !alive[proxied[k]] || (k > 0 && proxied[k] <= proxied[k - 1]))
      r.fail("the checkpoint's broadphase holds a body that is not alive");
  for (std::size_t k = 0; k < proxied.size() && r.ok(); ++k)
    if (!fatLo[k].allFinite() || !fatHi[k].allFinite() || !(fatLo[k].array() <= fatHi[k].array()).all())
      r.fail("the checkpoint's broadphase has a box that is not finite");
  const std::vector<std::uint32_t> framed = r.get<std::uint32_t>("bond_frames/body");
  const std::vector<std::vector<ConnectorId>> frameBonds = getLists<ConnectorTag>(r, "bond_frames/bonds", framed.size(), nc);
  const std::vector<std::uint32_t> removedAll = r.get<std::uint32_t>("bond_frames/removed");
  const std::vector<std::uint32_t> removedStart = r.get<std::uint32_t>("bond_frames/removed_start", 1, framed.size() + 1);
  const std::vector<double> displacements = r.get<double>("bond_frames/displacements", 6);
  // a frame's nodes: its body's particles, and those of pieces split off it while it was kept (bond_loads.hpp)
  const std::vector<std::vector<ParticleId>> frameNodes = getLists<ParticleTag>(r, "bond_frames/nodes", framed.size(), np);
  std::vector<std::size_t> nodeStart{0};
  for (const auto& nodes : frameNodes) nodeStart.push_back(nodeStart.back() + nodes.size());
  const std::vector<Vec3> nodePositions = r.vec3("bond_frames/node_positions", nodeStart.back());
  const std::vector<Mat3> frameAxes = r.mat3("bond_frames/axes", framed.size());
  for (std::size_t k = 0; k < frameAxes.size() && r.ok(); ++k)
    if (!frameAxes[k].allFinite() || !(frameAxes[k].transpose() * frameAxes[k]).isApprox(Mat3::Identity(), 1e-9))
      r.fail("checkpoint bond frame " + std::to_string(k) + "'s axes are not a rotation");
  std::vector<std::size_t> displacementStart{0};
  for (std::size_t k = 0; k < framed.size() && r.ok(); ++k) {
    const std::uint32_t b = framed[k];
    bool fits = b < nb && alive[b] && bodyKind[b] == static_cast<std::uint8_t>(BodyKind::Rigid) && (k == 0 || b > framed[k - 1]) &&
                removedStart[k] <= removedStart[k + 1] && removedStart[k + 1] <= removedAll.size() &&
                frameNodes[k].size() >= members[b].size();
    if (fits) displacementStart.push_back(displacementStart.back() + 6 * frameNodes[k].size());
    for (std::size_t j = 0; fits && j < frameBonds[k].size(); ++j) fits = connectors_.kind[frameBonds[k][j].index()] == ConnectorKind::Bond;
    if (!fits) r.fail("checkpoint bond frame " + std::to_string(k) + " does not fit its body");
  }
  if (r.ok() && (removedStart.empty() || removedStart.front() != 0 || removedStart.back() != removedAll.size()))
    r.fail("the checkpoint's removed bonds do not add up");
  if (r.ok() && displacementStart.back() != displacements.size())
    r.fail("the checkpoint's bond frame displacements do not match its frames' particles");
  for (std::size_t k = 0; k < displacements.size() && r.ok(); ++k)
    if (!std::isfinite(displacements[k])) r.fail("the checkpoint's bond frame displacements are not finite");

  // what the next step starts from: contacts, patches, caches
  ContactSet contacts;
  PatchSet patches;
  if (r.ok()) restoreContacts(r, contacts, np, nb, planes_.size());
  if (r.ok()) restorePatches(r, patches, contacts, nb, planes_.size());
  if (r.ok() && (patches.depthAlongNormal.size() != contacts.contacts.size()))
    r.fail("the checkpoint's patches do not cover its contacts");
  if (!r.ok()) return refuse();

  // all read: take it over
  particles_ = std::move(p);
  connectors_.broken = std::move(broken);
  opened_ = std::move(opened);
  for (std::size_t k = 0; k < deformableConnectors_.size(); ++k) connectorDirection_[deformableConnectors_[k].index()] = deformableDirection[k];
  normals_ = std::move(normals);
  bodies_.state.resize(nb);
  bodies_.info.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) {
    BodyState& s = bodies_.state[i];
    s.position = position[i];
    s.orientation = orientation[i];
    s.linearVelocity = linear[i];
    s.angularVelocity = angular[i];
    s.invInertiaLocal = invInertia[i];
    s.invMass = invMass[i];
    s.invInertiaWorld = invInertiaWorld[i];
    BodyInfo& info = bodies_.info[i];
    if (i >= built) {
      // a fragment: "wall/17", its first ancestor's name and its own index (World::splitBody)
      BodyId root(i);
      while (root.index() >= built && parent[root.index()] != kNone && parent[root.index()] < root.index()) root = BodyId(parent[root.index()]);
      const std::string& base = bodies_.info[root.index()].name;
      info.name = base.substr(0, base.find('/')) + "/" + std::to_string(i);
      info.source = SourceShape{};
      info.core = SourceShape{};
    }
    info.kind = static_cast<BodyKind>(bodyKind[i]);
    info.material = MaterialId(material[i]);
    info.mass = mass[i];
    info.inertiaLocal = inertia[i];
    info.principalInShape = principal[i];
    info.comInShape = com[i];
    info.inertiaResidual = residual[i];
    info.particles = std::move(members[i]);
    info.alive = alive[i] != 0;
    info.createdStep = created[i];
    info.retiredStep = retired[i];
    info.parent = BodyId(parent[i]);
    info.gluedInto = BodyId(glued[i]);
    info.breakable = breakableFlag[i] != 0;
  }
  bodyConnectors_ = std::move(bodyConnectors);
  bodyBoxes_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) bodyBoxes_[i] = Aabb{boxLo[i], boxHi[i]};

  // the lists and models made from the bodies
  rigidBodies_.clear();
  for (std::size_t i = 0; i < nb; ++i)
    if (bodies_.info[i].alive && bodies_.info[i].kind == BodyKind::Rigid) rigidBodies_.emplace_back(i);
  bodyKinds_.resize(nb);
  bodyMaterials_.resize(nb);
  bodyRuns_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i)
    bodyKinds_[i] = bodies_.info[i].kind, bodyMaterials_[i] = bodies_.info[i].material, bodyRuns_[i] = runOf(bodies_.info[i].particles);
  rodForces_.clear();
  bondLoads_.clear();
  rodForces_.resize(nb);
  bondLoads_.resize(nb);
  breakableRigid_.clear();
  std::size_t frame = 0;
  for (const BodyId id : rigidBodies_) {
    if (frame < framed.size() && framed[frame] == id.value) {
      auto loads = std::make_unique<BondLoads>();
      const std::span<const std::uint32_t> removed(removedAll.data() + removedStart[frame], removedStart[frame + 1] - removedStart[frame]);
      const std::span<const double> u(displacements.data() + displacementStart[frame],
                                      displacementStart[frame + 1] - displacementStart[frame]);
      const std::vector<std::uint32_t> nodes = rawIds(std::span<const ParticleId>(frameNodes[frame]));
      const std::span<const Vec3> positions(nodePositions.data() + nodeStart[frame], nodes.size());
      if (!loads->replay(bodies_.info[id.index()], connectors_, nodes, positions, frameAxes[frame], frameBonds[frame], removed, u))
        return Error{"", 0, 0, "checkpoint bond frame " + std::to_string(frame) + " cannot be made again"};
      bondLoads_[id.index()] = std::move(loads);
      breakableRigid_.push_back(id);
      ++frame;
      continue;
    }
    buildLattice(id);
    if (bondLoads_[id.index()])
      return Error{"", 0, 0, "the checkpoint has no bond frame for body " + std::to_string(id.value) + ", which has breakable bonds"};
  }
  // the same breakable flags as saved (buildLattice sets them where a lattice is made)
  for (std::size_t i = 0; i < nb; ++i) bodies_.info[i].breakable = breakableFlag[i] != 0;

  const double broadphaseMargin = broadphase_.margin();
  broadphase_ = Broadphase();
  broadphase_.setMargin(broadphaseMargin);
  for (std::size_t k = 0; k < proxied.size(); ++k)
    broadphase_.restoreBody(BodyId(proxied[k]), Aabb{fatLo[k], fatHi[k]}, bodies_.info[proxied[k]].kind == BodyKind::Static);
  const double contactMargin = contactFinder_.margin();
  ProcessGroup* const processes = contactFinder_.processes();
  contactFinder_ = ContactFinder();
  contactFinder_.setProcesses(processes);
  contactFinder_.setMargin(contactMargin);
  contactFinder_.setSweepTime(settings_.dt);
  for (std::size_t i = 0; i < nb; ++i)
    if (!bodies_.info[i].particles.empty()) contactFinder_.addBody(BodyId(i), particles_, bodies_);  // (retired: none)
  contactFinder_.refreshAdjacency(particles_, connectors_);
  cores_.updateAll(particles_, bodies_, normals_);

  contacts_ = std::move(contacts);
  patches_ = std::move(patches);
  if (!narrowPhase_.restoreCache(r) || !solver_.restoreWarmStart(r)) return refuse();
  stepIndex_ = step;
  breakageEnergy_ = breakageEnergy;
  takeCounters(stepCounters, stats_);
  stats_.maxPenetration = maxPenetration;
  breakEvents_.clear();
  contactsStale_ = false;
  return okStatus();
}

}  // namespace volpar
