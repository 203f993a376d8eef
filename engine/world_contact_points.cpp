// World::buildContactPoints(): the contact solver's points from the narrow phase's patches (docs/architecture.md,
// The step, 2): which contacts of each patch become points, a rigid patch's manifold of four, the friction
// that acts over a patch's contact area.

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "volpar/dynamics/contact_solver.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

namespace {

/// A contact point's identity for warm starting: its particle pair (a plane's contacts: the particle and the
/// plane), exact because ids are stable.
std::uint64_t warmStartKey(const ParticleContact& c) {
  return (static_cast<std::uint64_t>(c.a.value) << 32) |
         (c.b.valid() ? c.b.value : (0x80000000u | static_cast<std::uint32_t>(c.plane.value)));
}

/// A rigid patch's manifold of four of its `count` contacts `idx` (Bullet's choice): the deepest along the
/// normal, the one farthest from it, the one farthest from their line, and the one that adds most area on
/// the far side. Returns positions in idx; count must be above 4.
///
/// `wasPoint(contact)` says whether a contact was a point in the last step. Where a choice's best contact was
/// not, the choice takes instead the best of those that were, if its depth is within `depthTies` [m] of the
/// deepest's (the first choice) or its score within the fraction `scoreTies` of the best score (the others).
/// So a resting face, whose contacts are all about as deep, keeps its points, and their warm start, from
/// step to step; with ties of 0, only exact ties are decided by the last step.
template <class WasPoint>
std::array<std::uint32_t, 4> manifoldOfFour(const ContactSet& cs, const std::uint32_t* idx, std::uint32_t count,
                                            std::span<const double> depth, double depthTies, double scoreTies,
                                            const WasPoint& wasPoint) {
  std::array<std::uint32_t, 4> reduced{};
  std::size_t chosen = 0;
  const auto pointOf = [&](std::uint32_t k) -> const Vec3& { return cs.contacts[idx[k]].point; };
  const auto taken = [&](std::uint32_t k) {
    return std::find(reduced.begin(), reduced.begin() + static_cast<std::ptrdiff_t>(chosen), k) !=
           reduced.begin() + static_cast<std::ptrdiff_t>(chosen);
  };
  // the contact not yet taken with the highest score (the first of equals), or the best of the last step's
  // points within `ties(top)` of that score
  const auto best = [&](const auto& score, const auto& ties) {
    std::uint32_t arg = count;
    double top = 0.0;
    for (std::uint32_t k = 0; k < count; ++k) {
      if (taken(k)) continue;
      const double v = score(k);
      if (arg == count || v > top) {
        top = v;
        arg = k;
      }
    }
    if (wasPoint(idx[arg])) return arg;
    const double floor = top - ties(top);
    std::uint32_t kept = count;
    double keptScore = 0.0;
    for (std::uint32_t k = 0; k < count; ++k) {
      if (k == arg || taken(k)) continue;
      const double v = score(k);
      if (v >= floor && (kept == count || v > keptScore) && wasPoint(idx[k])) {
        keptScore = v;
        kept = k;
      }
    }
    return kept != count ? kept : arg;
  };
  const auto relativeTies = [&](double top) { return scoreTies * std::abs(top); };
  reduced[chosen] = best([&](std::uint32_t k) { return depth[idx[k]]; }, [&](double) { return depthTies; });
  const Vec3 p0 = pointOf(reduced[chosen++]);
  reduced[chosen] = best([&](std::uint32_t k) { return (pointOf(k) - p0).squaredNorm(); }, relativeTies);
  const Vec3 p1 = pointOf(reduced[chosen++]);
  reduced[chosen] = best([&](std::uint32_t k) { return (pointOf(k) - p0).cross(pointOf(k) - p1).squaredNorm(); }, relativeTies);
  const Vec3 p2 = pointOf(reduced[chosen++]);
  const Vec3 triNormal = (p1 - p0).cross(p2 - p0);
  reduced[chosen] = best(
      [&](std::uint32_t k) {
        // area added outside the triangle: the largest of the three triangles the point makes with an edge
        const Vec3& x = pointOf(k);
        const double a = (x - p0).cross(x - p1).dot(triNormal), b = (x - p1).cross(x - p2).dot(triNormal),
                     c = (x - p2).cross(x - p0).dot(triNormal);
        return std::max({-a, -b, -c});
      },
      relativeTies);
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
  // With processes, each selects a contiguous run of the patches, of about equal numbers of contacts, and
  // every process then holds every patch's selection (one exchange of the modes, one of the kept contacts:
  // each patch's contacts lie in patch order, so a run's kept contacts are one range). Which process
  // selects a patch changes nothing in its selection
  const bool divided = processes_ && processes_->size() > 1;
  std::size_t mineBegin = 0, mineEnd = np;
  if (divided && np > 0) {
    // process r's first patch: the first whose contacts begin at or past r / R of them all
    const int ranks = processes_->size();
    selectedFrom_.resize(static_cast<std::size_t>(ranks) + 1);
    for (int r = 0; r <= ranks; ++r) {
      const std::size_t at = firstShare(r, ranks, ps.contacts.size());
      selectedFrom_[static_cast<std::size_t>(r)] =
          r == ranks ? np
                     : static_cast<std::size_t>(std::partition_point(ps.patches.begin(), ps.patches.end(),
                                                                     [&](const ContactPatch& p) { return p.first < at; }) -
                                                ps.patches.begin());
    }
    mineBegin = selectedFrom_[static_cast<std::size_t>(processes_->rank())];
    mineEnd = selectedFrom_[static_cast<std::size_t>(processes_->rank()) + 1];
  }
  const std::size_t mine = mineEnd - mineBegin;
  if (pool_ && pool_->worthSharing(mine, 512))
    pool_->runChunks(mine, [&](int worker, std::size_t begin, std::size_t end) { select(worker, mineBegin + begin, mineBegin + end); });
  else select(0, mineBegin, mineEnd);
  if (divided && np > 0) {
    const auto contactOf = [&](std::size_t j) -> std::size_t { return j < np ? ps.patches[j].first : ps.contacts.size(); };
    shareRuns(*processes_, std::as_writable_bytes(std::span<PatchPoints>(patchPoints_.data(), np)), sizeof(PatchPoints),
              [&](std::size_t r) { return selectedFrom_[r]; }, shareOffset_, shareCount_);
    shareRuns(*processes_, std::as_writable_bytes(std::span<std::uint32_t>(keptContacts_.data(), keptContacts_.size())),
              sizeof(std::uint32_t), [&](std::size_t r) { return contactOf(selectedFrom_[r]); }, shareOffset_, shareCount_);
  }
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
        in.key = warmStartKey(c);
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
      // (the last step's points are looked up only where a choice's best contact was not one of them)
      const auto wasPoint = [&](std::uint32_t contact) { return solver_.warmStarts(warmStartKey(cs.contacts[contact])); };
      const double rsum = particles_.radius[first.a.index()] + (first.b.valid() ? particles_.radius[first.b.index()] : 0.0);
      const std::array<std::uint32_t, 4> reduced =
          reduce ? manifoldOfFour(cs, kept, count, ps.depthAlongNormal, settings_.manifoldDepthTies * rsum,
                                  settings_.manifoldScoreTies, wasPoint)
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

}  // namespace volpar
