#include "dynamics/contact_solver.hpp"

#include <algorithm>
#include <cmath>

namespace volpar {

namespace {

constexpr std::uint32_t kFixed = ContactPointInput::kFixed;

/// A deterministic tangent basis for a unit normal.
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 e = std::abs(n.x()) < 0.57735 ? Vec3::UnitX() : (std::abs(n.y()) < 0.57735 ? Vec3::UnitY() : Vec3::UnitZ());
  t1 = n.cross(e).normalized();
  t2 = n.cross(t1);
}

/// Velocity of B relative to A along the axis: J v.
template <class Axis>
inline double relative(const Axis& x, std::uint32_t a, std::uint32_t b, const std::vector<Vec3>& v,
                       const std::vector<Vec3>& w) {
  return x.d.dot(v[b] - v[a]) + x.crossB.dot(w[b]) - x.crossA.dot(w[a]);
}

/// Impulse lambda along the axis: +lambda on B, -lambda on A (the fixed side's entries stay zero: its
/// inverse mass and turns are).
template <class Row, class Axis>
inline void apply(const Row& r, const Axis& x, double lambda, std::vector<Vec3>& v, std::vector<Vec3>& w) {
  v[r.a] -= (r.invMassA * lambda) * x.d;
  w[r.a] -= lambda * x.turnA;
  v[r.b] += (r.invMassB * lambda) * x.d;
  w[r.b] += lambda * x.turnB;
}

/// The Jacobian of direction d at arms rA, rB, and its effective mass.
template <class Axis>
void prepareAxis(const SolverBody* a, const SolverBody* b, const Vec3& rA, const Vec3& rB, const Vec3& d, Axis& x) {
  x.d = d;
  x.crossA = rA.cross(d);
  x.crossB = rB.cross(d);
  x.turnA = a ? Vec3(a->invInertia * x.crossA) : Vec3::Zero();
  x.turnB = b ? Vec3(b->invInertia * x.crossB) : Vec3::Zero();
  const double k = (a ? a->invMass : 0.0) + (b ? b->invMass : 0.0) + x.crossA.dot(x.turnA) + x.crossB.dot(x.turnB);
  x.mass = k > 0.0 ? 1.0 / k : 0.0;
}

}  // namespace

void ContactSolver::order(std::span<const SolverBody> bodies, std::span<const ContactPointInput> points) {
  // the two halves: bodies sorted by x (ties by index), split at the median
  const std::size_t nb = bodies.size();
  byX_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) byX_[i] = {bodies[i].position.x(), static_cast<std::uint32_t>(i)};
  const std::size_t half = nb / 2;
  if (nb > 0) std::nth_element(byX_.begin(), byX_.begin() + static_cast<std::ptrdiff_t>(half), byX_.end());
  side_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) side_[byX_[i].second] = i < half ? 0 : 1;
  // each half's velocities contiguous, a cache line apart (two threads must not share a line): the left
  // half's bodies, its fixed entry, a gap, the right half's, its fixed entry, a gap, the joining points'
  // fixed entry
  constexpr std::size_t kGap = 8;
  slot_.resize(nb);
  std::size_t left = 0, right = half + 1 + kGap;
  for (std::size_t i = 0; i < nb; ++i) slot_[i] = static_cast<std::uint32_t>(side_[i] == 0 ? left++ : right++);
  fixedSlot_ = {static_cast<std::uint32_t>(half), static_cast<std::uint32_t>(right),
                static_cast<std::uint32_t>(right + 1 + kGap)};
  slots_ = right + 2 + kGap;
  // a point belongs to the half of its bodies (the fixed side belongs to both), else it joins the halves
  const auto partOf = [&](const ContactPointInput& in) -> std::size_t {
    if (in.a == kFixed) return side_[in.b];
    if (in.b == kFixed) return side_[in.a];
    return side_[in.a] == side_[in.b] ? side_[in.a] : 2;
  };
  std::array<std::size_t, 3> count{};
  for (const ContactPointInput& in : points) ++count[partOf(in)];
  parts_ = {0, count[0], count[0] + count[1], points.size()};
  std::array<std::size_t, 3> next{parts_[0], parts_[1], parts_[2]};
  order_.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) order_[next[partOf(points[i])]++] = static_cast<std::uint32_t>(i);
}

void ContactSolver::velocitySweep(std::size_t begin, std::size_t end) {
  for (std::size_t k = begin; k < end; ++k) {
    Row& r = rows_[k];
    // friction: both directions, the sum clamped to the cone
    const double old1 = r.lambdaT1, old2 = r.lambdaT2;
    double l1 = old1 - r.t1.mass * relative(r.t1, r.a, r.b, v_, w_);
    double l2 = old2 - r.t2.mass * relative(r.t2, r.a, r.b, v_, w_);
    const double limit = r.friction * r.lambdaN;
    const double mag2 = l1 * l1 + l2 * l2;
    if (mag2 > limit * limit) {
      const double s = mag2 > 0.0 ? limit / std::sqrt(mag2) : 0.0;
      l1 *= s;
      l2 *= s;
    }
    r.lambdaT1 = l1;
    r.lambdaT2 = l2;
    apply(r, r.t1, l1 - old1, v_, w_);
    apply(r, r.t2, l2 - old2, v_, w_);
    // normal
    const double oldN = r.lambdaN;
    r.lambdaN = std::max(oldN + r.n.mass * (r.targetN - relative(r.n, r.a, r.b, v_, w_)), 0.0);
    apply(r, r.n, r.lambdaN - oldN, v_, w_);
  }
}

bool ContactSolver::positionSweep(std::size_t begin, std::size_t end) {
  bool moved = false;  // whether a point's pseudo velocity changed by more than the tolerance
  const double tolerance = settings_.positionTolerance;
  for (std::size_t k = begin; k < end; ++k) {
    Row& r = rows_[k];
    if (r.biasP <= 0.0 && r.lambdaP <= 0.0) continue;
    const double old = r.lambdaP;
    r.lambdaP = std::max(old + r.n.mass * (r.biasP - relative(r.n, r.a, r.b, pv_, pw_)), 0.0);
    const double change = r.lambdaP - old;
    // (the change of the point's pseudo velocity is change / mass)
    moved = moved || std::abs(change) > tolerance * r.n.mass;
    apply(r, r.n, change, pv_, pw_);
  }
  return moved;
}

void ContactSolver::solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt,
                          ThreadPool* pool) {
  const std::size_t nb = bodies.size();
  order(bodies, points);
  // velocities in their slots; the fixed side of each part has an always-zero entry of its own
  v_.assign(slots_, Vec3::Zero());
  w_.assign(slots_, Vec3::Zero());
  pv_.assign(slots_, Vec3::Zero());
  pw_.assign(slots_, Vec3::Zero());
  for (std::size_t i = 0; i < nb; ++i) {
    v_[slot_[i]] = bodies[i].v;
    w_[slot_[i]] = bodies[i].w;
    pv_[slot_[i]] = bodies[i].pv;
    pw_[slot_[i]] = bodies[i].pw;
  }
  rows_.resize(points.size());
  keys_.resize(points.size());
  totalNormalImpulse_ = 0.0;

  // prepare rows: Jacobians, effective masses, restitution targets
  const auto prepare = [&](std::size_t part) {
    for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) {
      const ContactPointInput& in = points[order_[k]];
      Row& r = rows_[k];
      r.a = in.a == kFixed ? fixedSlot_[part] : slot_[in.a];
      r.b = in.b == kFixed ? fixedSlot_[part] : slot_[in.b];
      const SolverBody* a = in.a == kFixed ? nullptr : &bodies[in.a];
      const SolverBody* b = in.b == kFixed ? nullptr : &bodies[in.b];
      r.invMassA = a ? a->invMass : 0.0;
      r.invMassB = b ? b->invMass : 0.0;
      Vec3 t1, t2;
      tangents(in.normal, t1, t2);
      prepareAxis(a, b, in.rA, in.rB, in.normal, r.n);
      prepareAxis(a, b, in.rA, in.rB, t1, r.t1);
      prepareAxis(a, b, in.rA, in.rB, t2, r.t2);
      keys_[k] = in.key;
      r.friction = in.friction;
      // relative velocity of B with respect to A along n: negative when approaching
      const double vn = relative(r.n, r.a, r.b, v_, w_);
      // bounce above the threshold; otherwise a speculative contact may close its gap this step, no more
      if (vn < -settings_.restitutionThreshold && in.restitution > 0.0) r.targetN = -in.restitution * vn;
      else r.targetN = in.depth < 0.0 ? in.depth / dt : 0.0;
      r.biasP = std::min(settings_.baumgarte * std::max(in.depth - in.slop, 0.0) / dt, settings_.maxCorrectionSpeed);
      r.lambdaN = r.lambdaT1 = r.lambdaT2 = r.lambdaP = 0.0;
    }
  };
  // warm start from the last step's impulses, matched by key
  const auto warmStart = [&](std::size_t part) {
    std::size_t started = 0;
    for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) {
      Row& r = rows_[k];
      const auto it = std::lower_bound(cache_.begin(), cache_.end(), keys_[k], [](const Cached& c, std::uint64_t key) { return c.key < key; });
      if (it == cache_.end() || it->key != keys_[k]) continue;
      r.lambdaN = it->lambdaN;
      r.lambdaT1 = it->lambdaT.dot(r.t1.d);
      r.lambdaT2 = it->lambdaT.dot(r.t2.d);
      apply(r, r.n, r.lambdaN, v_, w_);
      apply(r, r.t1, r.lambdaT1, v_, w_);
      apply(r, r.t2, r.lambdaT2, v_, w_);
      ++started;
    }
    return started;
  };

  // everything in the same order of phases, on one thread or two: prepare (after which the approach
  // speeds are taken), warm start, the iterations; in each phase the two halves, then the joining points
  const int workers = pool && pool->workers() >= 2 ? 2 : 1;
  barrier_.reset(workers);
  std::array<std::size_t, 3> started{};
  // (two sets used alternately, so a thread deciding to stop never reads a flag the other has
  // already overwritten for the next sweep)
  std::array<std::array<std::uint8_t, 3>, 2> moved{};
  const auto iterate = [&](int worker, std::size_t begin, std::size_t end) {
    for (std::size_t part = begin; part < end; ++part) prepare(part);
    if (worker == 0) prepare(2);
    barrier_.wait();
    if (settings_.warmStart) {
      for (std::size_t part = begin; part < end; ++part) started[part] = warmStart(part);
      barrier_.wait();
      if (worker == 0) started[2] = warmStart(2);
      barrier_.wait();
    }
    for (int it = 0; it < settings_.iterations; ++it) {
      for (std::size_t part = begin; part < end; ++part) velocitySweep(parts_[part], parts_[part + 1]);
      barrier_.wait();
      if (worker == 0) velocitySweep(parts_[2], parts_[3]);
      barrier_.wait();
    }
    // (until no point's pseudo velocity changes by more than the tolerance: the same decision on every
    // thread, from the parts' own results)
    for (int it = 0; it < settings_.positionIterations; ++it) {
      auto& m = moved[static_cast<std::size_t>(it & 1)];
      for (std::size_t part = begin; part < end; ++part) m[part] = positionSweep(parts_[part], parts_[part + 1]);
      barrier_.wait();
      if (worker == 0) m[2] = positionSweep(parts_[2], parts_[3]);
      barrier_.wait();
      if (!m[0] && !m[1] && !m[2]) break;
    }
  };
  if (workers == 2 && !rows_.empty()) {
    // exactly two ranges of one half each, whatever the pool's size
    pool->run(static_cast<std::size_t>(pool->workers()), [&](int worker, std::size_t, std::size_t) {
      if (worker < 2) iterate(worker, static_cast<std::size_t>(worker), static_cast<std::size_t>(worker) + 1);
    });
  } else {
    iterate(0, 0, 2);
  }
  warmStarted_ = started[0] + started[1] + started[2];

  for (std::size_t i = 0; i < nb; ++i) {
    bodies[i].v = v_[slot_[i]];
    bodies[i].w = w_[slot_[i]];
    bodies[i].pv = pv_[slot_[i]];
    bodies[i].pw = pw_[slot_[i]];
  }
  impulses_.resize(rows_.size());
  nextCache_.clear();
  for (std::size_t k = 0; k < rows_.size(); ++k) {
    const Row& r = rows_[k];
    const Vec3 tangential = r.lambdaT1 * r.t1.d + r.lambdaT2 * r.t2.d;
    impulses_[order_[k]] = r.lambdaN * r.n.d + tangential;
    // kept for the next step, sorted by key below
    nextCache_.push_back({keys_[k], r.lambdaN, tangential});
    totalNormalImpulse_ += r.lambdaN;
  }
  std::sort(nextCache_.begin(), nextCache_.end(), [](const Cached& x, const Cached& y) { return x.key < y.key; });
  // a key can repeat when two points share a particle pair (raw normals never, planes never): keep the first
  nextCache_.erase(std::unique(nextCache_.begin(), nextCache_.end(), [](const Cached& x, const Cached& y) { return x.key == y.key; }),
                   nextCache_.end());
  std::swap(cache_, nextCache_);
}

}  // namespace volpar
