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

/// 1 / (J M^-1 J^T) for direction d at arms rA, rB.
double effectiveMass(const SolverBody* a, const SolverBody* b, const Vec3& rA, const Vec3& rB, const Vec3& d) {
  double k = 0.0;
  if (a) {
    const Vec3 c = rA.cross(d);
    k += a->invMass + c.dot(a->invInertia * c);
  }
  if (b) {
    const Vec3 c = rB.cross(d);
    k += b->invMass + c.dot(b->invInertia * c);
  }
  return k > 0.0 ? 1.0 / k : 0.0;
}

Vec3 velocityAt(const SolverBody* s, const Vec3& r) { return s ? Vec3(s->v + s->w.cross(r)) : Vec3::Zero(); }
Vec3 pseudoAt(const SolverBody* s, const Vec3& r) { return s ? Vec3(s->pv + s->pw.cross(r)) : Vec3::Zero(); }

void applyImpulse(SolverBody* s, const Vec3& r, const Vec3& p) {
  if (!s) return;
  s->v += s->invMass * p;
  s->w += s->invInertia * r.cross(p);
}

void applyPseudo(SolverBody* s, const Vec3& r, const Vec3& p) {
  if (!s) return;
  s->pv += s->invMass * p;
  s->pw += s->invInertia * r.cross(p);
}

}  // namespace

void ContactSolver::solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt) {
  auto body = [&](std::uint32_t i) -> SolverBody* { return i == kFixed ? nullptr : &bodies[i]; };
  rows_.resize(points.size());
  warmStarted_ = 0;
  totalNormalImpulse_ = 0.0;

  // prepare rows: effective masses, restitution targets, warm start
  for (std::size_t i = 0; i < points.size(); ++i) {
    const ContactPointInput& in = points[i];
    Row& r = rows_[i];
    r.a = in.a;
    r.b = in.b;
    r.rA = in.rA;
    r.rB = in.rB;
    r.n = in.normal;
    tangents(r.n, r.t1, r.t2);
    r.key = in.key;
    r.friction = in.friction;
    SolverBody* a = body(r.a);
    SolverBody* b = body(r.b);
    r.massN = effectiveMass(a, b, r.rA, r.rB, r.n);
    r.massT1 = effectiveMass(a, b, r.rA, r.rB, r.t1);
    r.massT2 = effectiveMass(a, b, r.rA, r.rB, r.t2);
    // relative velocity of B with respect to A along n: negative when approaching
    const double vn = r.n.dot(velocityAt(b, r.rB) - velocityAt(a, r.rA));
    // bounce above the threshold; otherwise a speculative contact may close its gap this step, no more
    if (vn < -settings_.restitutionThreshold && in.restitution > 0.0) r.targetN = -in.restitution * vn;
    else r.targetN = in.depth < 0.0 ? in.depth / dt : 0.0;
    r.biasP = std::min(settings_.baumgarte * std::max(in.depth - in.slop, 0.0) / dt, settings_.maxCorrectionSpeed);
    r.lambdaN = r.lambdaT1 = r.lambdaT2 = r.lambdaP = 0.0;
  }

  // warm start, after every row took its approach speed from the unmodified velocities
  if (settings_.warmStart) {
    for (Row& r : rows_) {
      const auto it = std::lower_bound(cache_.begin(), cache_.end(), r.key, [](const Cached& c, std::uint64_t k) { return c.key < k; });
      if (it == cache_.end() || it->key != r.key) continue;
      r.lambdaN = it->lambdaN;
      r.lambdaT1 = it->lambdaT.dot(r.t1);
      r.lambdaT2 = it->lambdaT.dot(r.t2);
      const Vec3 p = r.lambdaN * r.n + r.lambdaT1 * r.t1 + r.lambdaT2 * r.t2;
      applyImpulse(body(r.a), r.rA, -p);
      applyImpulse(body(r.b), r.rB, p);
      ++warmStarted_;
    }
  }

  // velocity iterations: friction first (it depends on the normal impulse), then the normal
  for (int it = 0; it < settings_.iterations; ++it) {
    for (Row& r : rows_) {
      SolverBody* a = body(r.a);
      SolverBody* b = body(r.b);
      const Vec3 dv = velocityAt(b, r.rB) - velocityAt(a, r.rA);
      // friction: both directions, the sum clamped to the cone
      const double old1 = r.lambdaT1, old2 = r.lambdaT2;
      double l1 = old1 - r.massT1 * dv.dot(r.t1);
      double l2 = old2 - r.massT2 * dv.dot(r.t2);
      const double limit = r.friction * r.lambdaN;
      const double mag = std::hypot(l1, l2);
      if (mag > limit) {
        const double s = mag > 0.0 ? limit / mag : 0.0;
        l1 *= s;
        l2 *= s;
      }
      r.lambdaT1 = l1;
      r.lambdaT2 = l2;
      const Vec3 pt = (l1 - old1) * r.t1 + (l2 - old2) * r.t2;
      applyImpulse(a, r.rA, -pt);
      applyImpulse(b, r.rB, pt);
      // normal
      const double vn = r.n.dot(velocityAt(b, r.rB) - velocityAt(a, r.rA));
      const double oldN = r.lambdaN;
      r.lambdaN = std::max(oldN + r.massN * (r.targetN - vn), 0.0);
      const Vec3 pn = (r.lambdaN - oldN) * r.n;
      applyImpulse(a, r.rA, -pn);
      applyImpulse(b, r.rB, pn);
    }
  }

  // position iterations on pseudo velocities
  for (int it = 0; it < settings_.positionIterations; ++it) {
    for (Row& r : rows_) {
      if (r.biasP <= 0.0 && r.lambdaP <= 0.0) continue;
      SolverBody* a = body(r.a);
      SolverBody* b = body(r.b);
      const double vn = r.n.dot(pseudoAt(b, r.rB) - pseudoAt(a, r.rA));
      const double old = r.lambdaP;
      r.lambdaP = std::max(old + r.massN * (r.biasP - vn), 0.0);
      const Vec3 p = (r.lambdaP - old) * r.n;
      applyPseudo(a, r.rA, -p);
      applyPseudo(b, r.rB, p);
    }
  }

  impulses_.resize(rows_.size());
  for (std::size_t i = 0; i < rows_.size(); ++i) {
    const Row& r = rows_[i];
    impulses_[i] = r.lambdaN * r.n + r.lambdaT1 * r.t1 + r.lambdaT2 * r.t2;
  }
  // keep the impulses for the next step, sorted by key
  nextCache_.clear();
  for (const Row& r : rows_) {
    nextCache_.push_back({r.key, r.lambdaN, r.lambdaT1 * r.t1 + r.lambdaT2 * r.t2});
    totalNormalImpulse_ += r.lambdaN;
  }
  std::sort(nextCache_.begin(), nextCache_.end(), [](const Cached& x, const Cached& y) { return x.key < y.key; });
  // a key can repeat when two points share a particle pair (raw normals never, planes never): keep the first
  nextCache_.erase(std::unique(nextCache_.begin(), nextCache_.end(), [](const Cached& x, const Cached& y) { return x.key == y.key; }),
                   nextCache_.end());
  std::swap(cache_, nextCache_);
}

}  // namespace volpar
