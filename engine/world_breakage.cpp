// The World's breakage stage (docs/fracture.md, docs/architecture.md): connectors that break under the step's loads, rigid bodies
// that split into the connected pieces of what is left, glued bodies, and the normals around what changed.

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>

#include "volpar/dynamics/mass_properties.hpp"
#include "volpar/dynamics/rigid_integrator.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

namespace {

/// A uniform number in (0, 1) from `seed` and `index` (SplitMix64 of both).
double uniformDraw(std::uint64_t seed, std::uint64_t index) {
  std::uint64_t z = seed * 0x9e3779b97f4a7c15ull + (index + 1) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  z ^= z >> 31;
  return (static_cast<double>(z >> 11) + 0.5) * 0x1.0p-53;
}

/// What the intact connectors of a body among `ids` are: whether any is a bond, and whether any can break.
struct IntactConnectors {
  bool bonds = false, canBreak = false;
};
IntactConnectors intactConnectors(const ConnectorStore& c, std::span<const ConnectorId> ids) {
  IntactConnectors out;
  for (const ConnectorId id : ids) {
    const std::size_t k = id.index();
    if (c.broken[k]) continue;
    out.bonds = out.bonds || c.kind[k] == ConnectorKind::Bond;
    out.canBreak = out.canBreak || std::isfinite(c.breakLimit[k]) || std::isfinite(c.compressionLimit[k]) ||
                   std::isfinite(c.tensileStrength[k]) || std::isfinite(c.shearStrength[k]);
  }
  return out;
}

}  // namespace

ConnectorId World::addConnector(ParticleId a, ParticleId b, double rest, const ConnectorParams& params) {
  double radius = 0.0, factor = 1.0;
  if (params.kind == ConnectorKind::Bond) {
    radius = params.bond.radiusFactor * std::min(particles_.radius[a.index()], particles_.radius[b.index()]);
    // Weibull: P(strength < s) = 1 - exp(-(s / s0)^m), drawn by inverting it at a uniform U
    if (params.bond.weibullModulus > 0.0)
      factor = std::pow(-std::log(uniformDraw(settings_.seed, connectors_.size())), 1.0 / params.bond.weibullModulus);
  }
  return connectors_.add(a, b, rest, params, radius, factor);
}

void World::buildLattice(BodyId id) {
  // (a body with a lattice is on breakableRigid_, one without is not, until applyBreakage drops the former)
  const bool listed = breakable(id);
  rodForces_[id.index()].reset();
  bondLoads_[id.index()].reset();
  std::vector<ConnectorId> intact;
  for (const ConnectorId c : bodyConnectors_[id.index()])
    if (!connectors_.broken[c.index()]) intact.push_back(c);
  const IntactConnectors kinds = intactConnectors(connectors_, intact);
  if (!kinds.canBreak) return;  // (nor where none is intact; applyBreakage drops it from breakableRigid_)
  if (kinds.bonds) {
    bondLoads_[id.index()] = std::make_unique<BondLoads>();
    bondLoads_[id.index()]->build(bodies_.info[id.index()], particles_, connectors_, intact);
  } else {
    rodForces_[id.index()] = std::make_unique<RodForces>();
    rodForces_[id.index()]->build(bodies_.info[id.index()], particles_, connectors_, intact);
  }
  bodies_.info[id.index()].breakable = true;
  if (!listed) breakableRigid_.push_back(id);
}

void World::applyBreakage() {
  breakEvents_.clear();
  seeds_.clear();
  bool anyBroken = false;
  // rigid bodies: the connectors' loads in the elastic lattice (rods) or frame (bonds) under this step's loads.
  // Failure progresses within the step: the most overloaded connectors break first (those within
  // kCriticalBand of the worst overload), the body's lattice is solved again without them under the same
  // loads, and so on, so that load is shed where the body fails first (a piece knocked out of a wall takes
  // the blow with it) instead of every connector that the intact body would overload breaking at once.
  // Fragments made join the list and are judged in this step under the same loads.
  constexpr double kCriticalBand = 0.8;
  constexpr int kMaxPasses = 64;  // then every overloaded connector breaks at once
  // A pass after one that broke bonds of a frame solves again only around those bonds
  // (BondLoads::solveAround), and judges only the bonds whose loads that changed; once no bond is
  // overloaded, the whole frame is solved again, and the passes go on from what that finds.
  for (std::size_t k = 0; k < breakableRigid_.size(); ++k) {
    const BodyId id = breakableRigid_[k];
    bool solvedAround = false;  // the last pass solved only around its breaks
    for (int pass = 0; bodies_.info[id.index()].alive && breakable(id); ++pass) {
      BondLoads* bl = bondLoads_[id.index()].get();
      const auto judgeBond = [&](std::size_t r) {
        const std::span<const ConnectorId> bonds = bl->bonds();
        const std::size_t c = bonds[r].index();
        const BondStress stress = bondStress(bondLoadScratch_[r], connectors_.bondRadius[c]);
        const BondFailure failure = bondFailure(stress, connectors_.tensileStrength[c], connectors_.shearStrength[c]);
        if (failure == BondFailure::None) return;
        const double ratio = std::max(stress.tensile / connectors_.tensileStrength[c], stress.shear / connectors_.shearStrength[c]);
        // the energy it held when the stress reached its strength (energy grows with the load squared)
        const double energy = bondLoadScratch_[r].energy / (ratio * ratio);
        if (failure == BondFailure::Tension) overloaded_.push_back({bonds[r], r, ratio, stress.tensile, energy, BreakMode::Tension});
        else overloaded_.push_back({bonds[r], r, ratio, stress.shear, energy, BreakMode::Shear});
      };
      if (bl) {
        if (!solvedAround || overloaded_.empty()) {
          bl->solve(bodies_.state[id.index()], bodies_.info[id.index()], particles_, loads_, bondLoadScratch_, pool_.get());
          overloaded_.clear();
          for (std::size_t r = 0; r < bl->bonds().size(); ++r) judgeBond(r);
          solvedAround = false;
        }
      } else if (RodForces* rf = rodForces_[id.index()].get()) {
        overloaded_.clear();
        rf->solve(bodies_.state[id.index()], bodies_.info[id.index()], particles_, loads_, rodForceScratch_);
        const std::span<const ConnectorId> rods = rf->rods();
        for (std::size_t r = 0; r < rods.size(); ++r) {
          const std::size_t c = rods[r].index();
          // tension above the tensile strength, or compression above the compressive strength
          const double f = rodForceScratch_[r];
          if (f > connectors_.breakLimit[c]) overloaded_.push_back({rods[r], r, f / connectors_.breakLimit[c], f, 0.0, BreakMode::Tension});
          else if (-f > connectors_.compressionLimit[c])
            overloaded_.push_back({rods[r], r, -f / connectors_.compressionLimit[c], f, 0.0, BreakMode::Compression});
        }
      }
      if (overloaded_.empty()) break;
      double worst = 0.0;
      for (const Overload& o : overloaded_) worst = std::max(worst, o.ratio);
      const double cut = pass + 1 < kMaxPasses ? std::max(1.0, kCriticalBand * worst) : 0.0;
      brokenEntries_.clear();
      for (const Overload& o : overloaded_) {
        if (o.ratio < cut) continue;
        brokenEntries_.push_back(o.entry);
        const std::size_t c = o.connector.index();
        connectors_.broken[c] = 1;
        opened_[connectors_.a[c].index()] = opened_[connectors_.b[c].index()] = 1;
        breakEvents_.push_back({stepIndex_ + 1, o.connector, connectors_.a[c], connectors_.b[c], id, connectors_.kind[c],
                                o.value, o.mode, o.energy});
        seeds_.push_back(connectors_.a[c]);
        seeds_.push_back(connectors_.b[c]);
      }
      anyBroken = true;
      // whether the body split: where a frame finds each broken bond's ends still joined near it, it did not
      // (O(the broken bonds)); else the connected components of what is left (O(the body))
      if (bl) bl->remove(brokenEntries_);
      std::vector<std::uint32_t> component;
      const std::size_t parts =
          bl && bl->endsJoined(brokenEntries_)
              ? 1
              : connectedComponents(bodies_.info[id.index()].particles, connectors_, bodyConnectors_[id.index()], component);
      if (parts > 1) {
        splitBody(id, component, parts);  // (retires it; its fragments are judged further down the list)
      } else if (bl) {
        bl->solveAround(brokenEntries_, bodies_.state[id.index()], bodies_.info[id.index()], particles_, loads_,
                        bondLoadScratch_, changedBonds_, pool_.get());
        // the overloaded bonds that broke or whose loads changed leave the list; those changed are judged again
        bondChanged_.resize(bl->bonds().size(), 0);
        for (const std::uint32_t r : changedBonds_) bondChanged_[r] = 1;
        overloaded_.erase(std::remove_if(overloaded_.begin(), overloaded_.end(),
                                         [&](const Overload& o) {
                                           return bondChanged_[o.entry] || connectors_.broken[o.connector.index()];
                                         }),
                          overloaded_.end());
        for (const std::uint32_t r : changedBonds_) {
          bondChanged_[r] = 0;
          if (!connectors_.broken[bl->bonds()[r].index()]) judgeBond(r);
        }
        solvedAround = true;
      } else {
        buildLattice(id);
      }
    }
  }
  // deformable bodies: springs past their strain limit, rods past their strength
  for (const ConnectorId cid : deformableConnectors_) {
    const std::size_t c = cid.index();
    if (connectors_.broken[c] || (!std::isfinite(connectors_.breakLimit[c]) && !std::isfinite(connectors_.compressionLimit[c])))
      continue;
    double value;
    bool breaks;
    if (connectors_.kind[c] == ConnectorKind::Spring) {
      const double len = (particles_.position[connectors_.b[c].index()] - particles_.position[connectors_.a[c].index()]).norm();
      value = std::abs(len / connectors_.restLength[c] - 1.0);
      breaks = value > connectors_.breakLimit[c];
    } else {
      value = deformableForces_[c];  // (tension positive)
      breaks = value > connectors_.breakLimit[c] || -value > connectors_.compressionLimit[c];
    }
    if (!breaks) continue;
    connectors_.broken[c] = 1;
    opened_[connectors_.a[c].index()] = opened_[connectors_.b[c].index()] = 1;
    anyBroken = true;
    breakEvents_.push_back({stepIndex_ + 1, cid, connectors_.a[c], connectors_.b[c], particles_.body[connectors_.a[c].index()],
                            connectors_.kind[c], value,
                            connectors_.kind[c] == ConnectorKind::Spring ? BreakMode::Strain
                            : value > 0.0                               ? BreakMode::Tension
                                                                        : BreakMode::Compression,
                            0.0});
    seeds_.push_back(connectors_.a[c]);
    seeds_.push_back(connectors_.b[c]);
  }
  // bodies that can no longer break (retired, or with nothing breakable left) leave the list
  if (anyBroken)
    breakableRigid_.erase(std::remove_if(breakableRigid_.begin(), breakableRigid_.end(),
                                         [&](BodyId id) { return !bodies_.info[id.index()].alive || !breakable(id); }),
                          breakableRigid_.end());
  stats_.connectorsBroken = breakEvents_.size();
  for (const BreakEvent& e : breakEvents_) breakageEnergy_ += e.energy;
  if (anyBroken) contactFinder_.refreshAdjacency(particles_, connectors_);
  // the faces a break opened: the particles within two connectors of it (their neighbourhoods changed)
  if (!seeds_.empty()) recomputeNormalsAround(seeds_, 2);
  // deformable regions that bent or stretched
  seedDeformedNormals();
}

void World::seedDeformedNormals() {
  seeds_.clear();
  const double cosTurn = std::cos(settings_.normalTurnThreshold);
  for (const ConnectorId cid : deformableConnectors_) {
    const std::size_t c = cid.index();
    if (connectors_.broken[c]) continue;
    const ParticleId a = connectors_.a[c], b = connectors_.b[c];
    const Vec3 d = particles_.position[b.index()] - particles_.position[a.index()];
    const double len = d.norm();
    if (!(len > 0.0)) continue;
    const Vec3 local = bodies_.state[particles_.body[a.index()].index()].orientation.conjugate() * (d / len);
    const bool stretched = std::abs(len / connectors_.restLength[c] - 1.0) > settings_.normalStrainThreshold;
    if (!stretched && local.dot(connectorDirection_[c]) >= cosTurn) continue;
    connectorDirection_[c] = local;
    seeds_.push_back(a);
    seeds_.push_back(b);
  }
  if (!seeds_.empty()) recomputeNormalsAround(seeds_, 1);
}

void World::recomputeNormalsAround(std::span<const ParticleId> seeds, int rings) {
  // the seeds and their neighbours within `rings` connectors, each once
  ringMark_.resize(particles_.size(), 0);
  if (++ringStamp_ == 0) {
    std::fill(ringMark_.begin(), ringMark_.end(), 0u);
    ringStamp_ = 1;
  }
  ringScratch_.clear();
  for (const ParticleId s : seeds)
    if (ringMark_[s.index()] != ringStamp_) {
      ringMark_[s.index()] = ringStamp_;
      ringScratch_.push_back(s);
    }
  std::size_t frontierBegin = 0;
  for (int r = 0; r < rings; ++r) {
    const std::size_t frontierEnd = ringScratch_.size();
    for (std::size_t i = frontierBegin; i < frontierEnd; ++i)
      for (const ParticleId n : contactFinder_.neighbours(ringScratch_[i]))
        if (ringMark_[n.index()] != ringStamp_) {
          ringMark_[n.index()] = ringStamp_;
          ringScratch_.push_back(n);
        }
    frontierBegin = frontierEnd;
  }
  std::sort(ringScratch_.begin(), ringScratch_.end());
  recomputeNormals(ringScratch_);
}

void World::splitBody(BodyId parentId, std::span<const std::uint32_t> component, std::size_t components) {
  const BodyInfo parentInfo = bodies_.info[parentId.index()];  // copy: the store grows below
  const BodyState parentState = bodies_.state[parentId.index()];
  const Quat shapeOrientation = bodies_.shapeOrientation(parentId);
  const Vec3 shapeOrigin = bodies_.shapeOrigin(parentId);
  const std::vector<ConnectorId> parentConnectors = bodyConnectors_[parentId.index()];
  // each part's particles and connectors, in the parent's order, in one pass over each (not one a part)
  std::vector<std::vector<ParticleId>> partParticles(components);
  std::vector<std::vector<ConnectorId>> partConnectors(components);
  std::vector<std::vector<std::uint32_t>> partParentIndex(components);  // each particle's place in the parent
  {
    std::vector<std::pair<std::size_t, std::uint32_t>> partOf(parentInfo.particles.size());  // (particle id, part)
    for (std::size_t i = 0; i < parentInfo.particles.size(); ++i) {
      partParticles[component[i]].push_back(parentInfo.particles[i]);
      partParentIndex[component[i]].push_back(static_cast<std::uint32_t>(i));
      partOf[i] = {parentInfo.particles[i].index(), component[i]};
    }
    std::sort(partOf.begin(), partOf.end());
    const auto part = [&](ParticleId q) {
      const auto it = std::lower_bound(partOf.begin(), partOf.end(), std::pair<std::size_t, std::uint32_t>{q.index(), 0u});
      return it != partOf.end() && it->first == q.index() ? it->second : std::uint32_t{0xffffffffu};
    };
    for (const ConnectorId c : parentConnectors) {
      const std::uint32_t pa = part(connectors_.a[c.index()]);
      if (pa != 0xffffffffu && pa == part(connectors_.b[c.index()])) partConnectors[pa].push_back(c);
    }
  }
  // the largest piece keeps the parent's frame where it holds at least half the frame's nodes and can still
  // break (the other pieces' bonds leave it): a chip knocked off a large body costs the chip's bonds, not a
  // new frame for the rest. The other pieces' frames are built, starting from the parent's displacements.
  std::unique_ptr<BondLoads> parentFrame = std::move(bondLoads_[parentId.index()]);
  std::size_t heir = components;
  if (parentFrame) {
    std::size_t largest = 0;
    for (std::size_t part = 1; part < components; ++part)
      if (partParticles[part].size() > partParticles[largest].size()) largest = part;
    // (where buildLattice would make it a frame of bonds)
    const IntactConnectors kinds = intactConnectors(connectors_, partConnectors[largest]);
    if (kinds.bonds && kinds.canBreak && 2 * partParticles[largest].size() >= parentFrame->nodes().size()) heir = largest;
  }
  BodyId heirId;
  Mat3 heirTurn = Mat3::Identity();
  for (std::size_t part = 0; part < components; ++part) {
    std::vector<ParticleId> ids = std::move(partParticles[part]);
    std::vector<Vec3> x;
    std::vector<double> m, own;
    for (const ParticleId q : ids) {
      x.push_back(particles_.position[q.index()]);
      m.push_back(particles_.mass[q.index()]);
      own.push_back(particles_.ownInertia[q.index()]);
    }
    // mass properties from the fragment's own particles, in the world, plus its share (by mass) of what its
    // parent's inertia added to its particles': the fragments' inertias about the parent's centre sum to the
    // parent's, so the split keeps angular momentum
    MassProperties mp = computeMassProperties(x, m, own);
    const Mat3 parentAxes = parentState.orientation.toRotationMatrix();
    const Mat3 share = (mp.mass / parentInfo.mass) * parentAxes * parentInfo.inertiaResidual * parentAxes.transpose();
    mp.inertia += share;
    const PrincipalAxes axes = principalAxes(mp.inertia);
    const BodyId id(bodies_.size());
    BodyInfo info;
    // "wall/17": the original body's name and the fragment's own body index
    info.name = parentInfo.name.substr(0, parentInfo.name.find('/')) + "/" + std::to_string(id.value);
    info.kind = BodyKind::Rigid;
    info.material = parentInfo.material;
    info.mass = mp.mass;
    info.inertiaLocal = axes.moments;
    // the fragment keeps its parent's shape frame
    info.principalInShape = (shapeOrientation.conjugate() * axes.rotation).normalized();
    info.comInShape = shapeOrientation.conjugate() * (mp.centre - shapeOrigin);
    {
      const Mat3 r = axes.rotation.toRotationMatrix();
      info.inertiaResidual = r.transpose() * share * r;
    }
    info.particles = ids;
    info.createdStep = stepIndex_ + 1;
    info.parent = parentId;
    BodyState state;
    state.position = mp.centre;
    state.orientation = axes.rotation;
    // velocity inherited from the parent's rigid motion: v + w x r
    state.linearVelocity = parentState.linearVelocity + parentState.angularVelocity.cross(mp.centre - parentState.position);
    state.angularVelocity = parentState.angularVelocity;
    state.invMass = 1.0 / mp.mass;
    state.invInertiaLocal = axes.moments.cwiseInverse();
    updateWorldInertia(state);
    moveParticles(ids, id, mp.centre, axes.rotation);
    const Mat3 turn = axes.rotation.toRotationMatrix().transpose() * parentState.orientation.toRotationMatrix();
    addRigidBody(state, std::move(info), std::move(partConnectors[part]), part != heir);
    if (part == heir) {
      heirId = id;
      heirTurn = turn;
      breakableRigid_.push_back(id);  // (its frame comes below, once the other pieces have started from it)
    } else if (BondLoads* frame = bondLoads_[id.index()].get(); frame && parentFrame) {
      // its frame starts from its parent's displacements, turned from the parent's axes into its own: under
      // the same loads, they differ near the crack
      frame->startFrom(*parentFrame, partParentIndex[part], turn);
    }
    bodies_.info[id.index()].breakable = true;  // (a fragment, whether or not it can break further)
    ++stats_.bodiesCreated;
  }
  if (heir < components) {
    parentFrame->keepFor(partParentIndex[heir], heirTurn);
    bondLoads_[heirId.index()] = std::move(parentFrame);
  }
  retireBody(parentId, stepIndex_ + 1);
}

void World::moveParticles(std::span<const ParticleId> ids, BodyId id, const Vec3& centre, const Quat& axes) {
  const Quat toLocal = axes.conjugate();
  for (const ParticleId q : ids) {
    const std::size_t i = q.index();
    const Quat from = bodies_.state[particles_.body[i].index()].orientation;
    particles_.body[i] = id;
    particles_.local[i] = toLocal * (particles_.position[i] - centre);
    const std::int32_t k = particles_.normalIndex[i];
    if (k >= 0) {
      // the cached normal (and its faces) from the old body's frame to the new one's
      std::array<Vec3, 3> faces{};
      const std::span<const Vec3> old = normals_.faces(k);
      for (std::size_t f = 0; f < old.size(); ++f) faces[f] = toLocal * (from * old[f]);
      particles_.normalIndex[i] = normals_.rewrite(k, toLocal * (from * normals_[k]), std::span<const Vec3>(faces.data(), old.size()));
    }
  }
}

BodyId World::addRigidBody(const BodyState& state, BodyInfo info, std::vector<ConnectorId> connectors, bool lattice) {
  const BodyId id = bodies_.add(state, std::move(info));
  bodyKinds_.push_back(bodies_.info.back().kind);
  bodyRuns_.push_back(runOf(bodies_.info.back().particles));
  bodyMaterials_.push_back(bodies_.info.back().material);
  bodyBoxes_.emplace_back();
  rodForces_.emplace_back();
  bondLoads_.emplace_back();
  bodyConnectors_.push_back(std::move(connectors));
  rigidBodies_.push_back(id);
  updateRigidParticles(id);
  broadphase_.addBody(id, bodyBoxes_[id.index()], false);
  contactFinder_.addBody(id, particles_, bodies_);
  cores_.update(id, particles_, bodies_, normals_);
  if (lattice) buildLattice(id);
  contactsStale_ = true;
  return id;
}

void World::retireBody(BodyId id, std::int64_t step) {
  BodyInfo& retired = bodies_.info[id.index()];
  retired.alive = false;
  retired.retiredStep = step;
  retired.particles.clear();
  bodyRuns_[id.index()] = runOf(retired.particles);
  bodies_.state[id.index()].invMass = 0.0;
  broadphase_.removeBody(id);
  rodForces_[id.index()].reset();
  bondLoads_[id.index()].reset();
  rigidBodies_.erase(std::find(rigidBodies_.begin(), rigidBodies_.end(), id));
  cores_.update(id, particles_, bodies_, normals_);  // (none)
  contactsStale_ = true;
}

Result<BodyId> World::glue(std::span<const BodyId> parts, const GlueDef& def) {
  auto fail = [&](const std::string& why) -> Result<BodyId> { return Error{"", 0, 0, "glue '" + def.name + "': " + why}; };
  if (parts.size() < 2) return fail("expected at least two bodies to glue");
  if (def.bonds.kind != ConnectorKind::Bond || !(def.bonds.bond.youngsModulus > 0.0))
    return fail("the glue's bonds need a positive Young's modulus");
  if (!(def.reach > 1.0 && def.reach <= 4.0)) return fail("expected a reach in (1, 4]");
  std::vector<std::uint32_t> partOf(particles_.size(), 0xffffffffu);
  for (std::uint32_t k = 0; k < parts.size(); ++k) {
    const BodyId id = parts[k];
    if (!id.valid() || id.index() >= bodies_.size()) return fail("unknown body");
    const BodyInfo& info = bodies_.info[id.index()];
    if (!info.alive || info.kind != BodyKind::Rigid)
      return fail("body '" + info.name + "' is " + (info.alive ? "not rigid" : "retired") + "; only rigid bodies are glued");
    for (const ConnectorId c : bodyConnectors_[id.index()])
      if (connectors_.kind[c.index()] != ConnectorKind::Bond)
        return fail("body '" + info.name + "' is joined by rods; glued bodies are joined by bonds (connectors: bonds)");
    for (const ParticleId q : info.particles) {
      if (partOf[q.index()] != 0xffffffffu) return fail("body '" + info.name + "' is listed twice");
      partOf[q.index()] = k;
    }
  }
  std::vector<std::uint8_t> allowed;  // [parts x parts], where only listed pairs are glued
  if (!def.pairs.empty()) {
    allowed.assign(parts.size() * parts.size(), 0);
    for (const auto& [i, j] : def.pairs) {
      if (i >= parts.size() || j >= parts.size() || i == j) return fail("a glued pair names a body outside the glue, or one body twice");
      allowed[i * parts.size() + j] = allowed[j * parts.size() + i] = 1;
    }
  }

  // the particles of different bodies within reach of each other, through a grid of cells as wide as the
  // farthest reach (each pair found once, from its lower particle id)
  std::vector<ParticleId> all;
  double largest = 0.0;
  for (const BodyId id : parts)
    for (const ParticleId q : bodies_.info[id.index()].particles) {
      all.push_back(q);
      largest = std::max(largest, particles_.radius[q.index()]);
    }
  std::sort(all.begin(), all.end());
  const double cell = def.reach * 2.0 * largest;
  auto key = [&](const Vec3& x) {
    const Eigen::Array3d c = (x.array() / cell).floor();
    return std::array<std::int64_t, 3>{static_cast<std::int64_t>(c[0]), static_cast<std::int64_t>(c[1]),
                                       static_cast<std::int64_t>(c[2])};
  };
  struct KeyHash {
    std::size_t operator()(const std::array<std::int64_t, 3>& k) const {
      return static_cast<std::size_t>(k[0] * 73856093 ^ k[1] * 19349663 ^ k[2] * 83492791);
    }
  };
  std::unordered_map<std::array<std::int64_t, 3>, std::vector<ParticleId>, KeyHash> grid;
  for (const ParticleId q : all) grid[key(particles_.position[q.index()])].push_back(q);
  std::vector<std::array<ParticleId, 2>> joints;
  std::vector<std::uint32_t> group(parts.size());
  std::iota(group.begin(), group.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (group[x] != x) x = group[x] = group[group[x]];
    return x;
  };
  for (const ParticleId q : all) {
    const Vec3& x = particles_.position[q.index()];
    const auto k0 = key(x);
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
          const auto it = grid.find({k0[0] + dx, k0[1] + dy, k0[2] + dz});
          if (it == grid.end()) continue;
          for (const ParticleId o : it->second) {
            if (!(q < o)) continue;
            const std::uint32_t pq = partOf[q.index()], po = partOf[o.index()];
            if (pq == po || (!allowed.empty() && !allowed[pq * parts.size() + po])) continue;
            const double reach = def.reach * (particles_.radius[q.index()] + particles_.radius[o.index()]);
            if ((particles_.position[o.index()] - x).squaredNorm() >= reach * reach) continue;
            joints.push_back({q, o});
            group[find(std::max(pq, po))] = find(std::min(pq, po));
          }
        }
  }
  std::sort(joints.begin(), joints.end());
  for (std::uint32_t k = 0; k < parts.size(); ++k)
    if (find(k) != find(0))
      return fail("body '" + bodies_.info[parts[k].index()].name + "' does not touch the others (within " +
                  std::to_string(def.reach) + " x the particles' radii summed); glued bodies must hold together");

  // the glued body: its particles' mass properties plus what each part's inertia added to its particles'
  std::vector<Vec3> x;
  std::vector<double> m, own;
  Mat3 residual = Mat3::Zero();
  Vec3 momentum = Vec3::Zero(), moment = Vec3::Zero();
  for (const BodyId id : parts) {
    const BodyState& ps = bodies_.state[id.index()];
    const Mat3 r = ps.orientation.toRotationMatrix();
    residual += r * bodies_.info[id.index()].inertiaResidual * r.transpose();
    const Mat3 inertia = r * bodies_.info[id.index()].inertiaLocal.asDiagonal() * r.transpose();
    momentum += bodies_.info[id.index()].mass * ps.linearVelocity;
    moment += bodies_.info[id.index()].mass * ps.position.cross(ps.linearVelocity) + inertia * ps.angularVelocity;
  }
  for (const ParticleId q : all) {
    x.push_back(particles_.position[q.index()]);
    m.push_back(particles_.mass[q.index()]);
    own.push_back(particles_.ownInertia[q.index()]);
  }
  MassProperties mp = computeMassProperties(x, m, own);
  mp.inertia += residual;
  const PrincipalAxes axes = principalAxes(mp.inertia);
  const BodyId id(bodies_.size());
  BodyInfo info;
  info.name = def.name;
  info.kind = BodyKind::Rigid;
  info.material = bodies_.info[parts[0].index()].material;
  info.mass = mp.mass;
  info.inertiaLocal = axes.moments;
  // its shape frame is the world frame when it was glued
  info.principalInShape = axes.rotation;
  info.comInShape = mp.centre;
  {
    const Mat3 r = axes.rotation.toRotationMatrix();
    info.inertiaResidual = r.transpose() * residual * r;
  }
  info.particles = all;
  info.createdStep = stepIndex_;
  BodyState state;
  state.position = mp.centre;
  state.orientation = axes.rotation;
  state.invMass = 1.0 / mp.mass;
  state.invInertiaLocal = axes.moments.cwiseInverse();
  updateWorldInertia(state);
  // the parts' momentum and angular momentum, kept
  state.linearVelocity = momentum / mp.mass;
  state.angularVelocity = state.invInertiaWorld * (moment - mp.centre.cross(momentum));
  moveParticles(all, id, mp.centre, axes.rotation);
  std::vector<ConnectorId> connectors;
  for (const BodyId p : parts) connectors.insert(connectors.end(), bodyConnectors_[p.index()].begin(), bodyConnectors_[p.index()].end());
  for (const auto& [a, b] : joints)
    connectors.push_back(addConnector(a, b, (particles_.position[b.index()] - particles_.position[a.index()]).norm(), def.bonds));
  connectorDirection_.resize(connectors_.size(), Vec3::Zero());
  // the parts are retired before any frame (their rows keep their names; created = retired = now)
  for (const BodyId p : parts) {
    retireBody(p, stepIndex_);
    bodies_.info[p.index()].gluedInto = id;
  }
  breakableRigid_.erase(std::remove_if(breakableRigid_.begin(), breakableRigid_.end(),
                                       [&](BodyId b) { return !bodies_.info[b.index()].alive; }),
                        breakableRigid_.end());
  return addRigidBody(state, std::move(info), std::move(connectors));
}

FragmentHistogram World::fragments() const {
  FragmentHistogram h;
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const BodyInfo& info = bodies_.info[i];
    if (!info.alive || !info.breakable) continue;
    const std::size_t n = info.particles.size();
    std::size_t bin = 0;
    while (bin + 1 < FragmentHistogram::kBins && (std::size_t{2} << bin) <= n) ++bin;
    ++h.count;
    h.particles += n;
    h.largest = std::max(h.largest, n);
    if (n == 1) ++h.singles;
    ++h.bodies[bin];
    h.mass[bin] += info.mass;
  }
  return h;
}

std::size_t World::recomputeNormals(std::span<const ParticleId> ids) {
  const std::size_t n = normalUpdater_.recompute(ids, particles_, bodies_, contactFinder_, opened_, normals_);
  stats_.normalsRecomputed += n;
  // the whole cores of the rigid and static bodies whose normals changed (ids of one body come together)
  BodyId last;
  for (const ParticleId q : ids) {
    const BodyId b = particles_.body[q.index()];
    if (b == last || bodies_.info[b.index()].kind == BodyKind::Deformable) continue;
    last = b;
    cores_.update(b, particles_, bodies_, normals_);
  }
  return n;
}

}  // namespace volpar
