#include "dynamics/contact_solver.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace volpar {

namespace {

constexpr std::uint32_t kFixed = ContactPointInput::kFixed;
using V4 = Eigen::Vector4f;

/// A deterministic tangent basis for a unit normal.
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 e = std::abs(n.x()) < 0.57735 ? Vec3::UnitX() : (std::abs(n.y()) < 0.57735 ? Vec3::UnitY() : Vec3::UnitZ());
  t1 = n.cross(e).normalized();
  t2 = n.cross(t1);
}

V4 narrow(const Vec3& x) { return V4(static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z()), 0.0f); }
Vec3 wide(const V4& x) { return x.head<3>().cast<double>(); }

/// Velocity of B relative to A along the axis: J v.
template <class Axis>
inline float relative(const Axis& x, const V4& va, const V4& wa, const V4& vb, const V4& wb) {
  return (x.d.cwiseProduct(vb - va) + x.crossB.cwiseProduct(wb) - x.crossA.cwiseProduct(wa)).sum();
}

/// The Jacobian of direction d at arms rA, rB, and its effective mass (computed in double).
template <class Axis>
float prepareAxis(const SolverBody* a, const SolverBody* b, const Vec3& rA, const Vec3& rB, const Vec3& d, Axis& x) {
  const Vec3 crossA = rA.cross(d), crossB = rB.cross(d);
  const Vec3 turnA = a ? Vec3(a->invInertia * crossA) : Vec3::Zero();
  const Vec3 turnB = b ? Vec3(b->invInertia * crossB) : Vec3::Zero();
  const double k = (a ? a->invMass : 0.0) + (b ? b->invMass : 0.0) + crossA.dot(turnA) + crossB.dot(turnB);
  x.d = narrow(d);
  x.crossA = narrow(crossA);
  x.crossB = narrow(crossB);
  x.turnA = narrow(turnA);
  x.turnB = narrow(turnB);
  return k > 0.0 ? static_cast<float>(1.0 / k) : 0.0f;
}

using F4 = Eigen::Array4f;

/// The x, y and z of four bodies' vectors, lane by lane.
inline void gather(const V4* base, const std::array<std::uint32_t, 4>& slot, F4& x, F4& y, F4& z) {
  const V4& p0 = base[slot[0]];
  const V4& p1 = base[slot[1]];
  const V4& p2 = base[slot[2]];
  const V4& p3 = base[slot[3]];
  x = F4(p0.x(), p1.x(), p2.x(), p3.x());
  y = F4(p0.y(), p1.y(), p2.y(), p3.y());
  z = F4(p0.z(), p1.z(), p2.z(), p3.z());
}

/// The inverse of gather (lane by lane, in order: a padding lane writes the fixed side's zero back).
inline void scatter(V4* base, const std::array<std::uint32_t, 4>& slot, const F4& x, const F4& y, const F4& z) {
  for (int i = 0; i < 4; ++i) base[slot[static_cast<std::size_t>(i)]] = V4(x[i], y[i], z[i], 0.0f);
}

/// Slot of a key in a table of 2^bits entries (Fibonacci hashing: the top bits of the product, which
/// depend on every bit of the key; a key's two particle ids live in its two halves).
inline std::uint64_t hashSlot(std::uint64_t key, int bits) { return (key * 0x9E3779B97F4A7C15ull) >> (64 - bits); }

}  // namespace

void ContactSolver::order(std::span<const SolverBody> bodies) {
  const std::size_t nb = bodies.size(), np = ab_.size();
  // the two halves: bodies sorted by x (ties by index), split at the median
  byX_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) byX_[i] = {bodies[i].position.x(), static_cast<std::uint32_t>(i)};
  const std::size_t half = nb / 2;
  if (nb > 0) std::nth_element(byX_.begin(), byX_.begin() + static_cast<std::ptrdiff_t>(half), byX_.end());
  half_ = half;
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
  const auto partOf = [&](const std::pair<std::uint32_t, std::uint32_t>& p) -> std::size_t {
    if (p.first == kFixed) return side_[p.second];
    if (p.second == kFixed) return side_[p.first];
    return side_[p.first] == side_[p.second] ? side_[p.first] : 2;
  };
  std::array<std::size_t, 3> count{};
  for (const auto& p : ab_) ++count[partOf(p)];
  parts_ = {0, count[0], count[0] + count[1], np};
  std::array<std::size_t, 3> next{parts_[0], parts_[1], parts_[2]};
  order_.resize(np);
  for (std::size_t i = 0; i < np; ++i) order_[next[partOf(ab_[i])]++] = static_cast<std::uint32_t>(i);
  // (the points' ranks within their body pair, for spread(), which reorders from scratch_ into order_)
  rank_.resize(np);
  for (std::size_t i = 0; i < np; ++i) rank_[i] = i > 0 && ab_[i] == ab_[i - 1] ? rank_[i - 1] + 1 : 0;
  scratch_.resize(np);
  std::swap(order_, scratch_);
}

void ContactSolver::spread(std::size_t part) {
  // within a part, the points of one body pair (which come one after another) spread apart: first every
  // pair's first point, then every pair's second, and so on. Neighbouring rows then mostly touch other
  // bodies, and the processor overlaps their work instead of waiting for each row's result
  std::vector<std::uint32_t>& start = rankStart_[part];
  const std::vector<std::uint32_t>& from = scratch_;
  std::uint32_t ranks = 0;
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) ranks = std::max(ranks, rank_[from[k]] + 1);
  start.assign(ranks + 1, 0);
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) ++start[rank_[from[k]] + 1];
  for (std::size_t q = 1; q <= ranks; ++q) start[q] += start[q - 1];
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) order_[parts_[part] + start[rank_[from[k]]]++] = from[k];
}

void ContactSolver::velocitySweep(std::span<const std::uint32_t> rows) {
  // (each row's two bodies are loaded once, updated in registers and stored once: a row's a and b differ)
  V4* const v = v_.data();
  V4* const w = w_.data();
  for (const std::uint32_t k : rows) {
    Row& r = rows_[k];
    V4 va = v[r.a], wa = w[r.a], vb = v[r.b], wb = w[r.b];
    // friction: both directions, the sum clamped to the cone
    const float old1 = r.lambdaT1, old2 = r.lambdaT2;
    float l1 = old1 - r.massT1 * relative(r.t1, va, wa, vb, wb);
    float l2 = old2 - r.massT2 * relative(r.t2, va, wa, vb, wb);
    const float limit = r.friction * r.lambdaN;
    const float mag2 = l1 * l1 + l2 * l2;
    if (mag2 > limit * limit) {
      const float s = mag2 > 0.0f ? limit / std::sqrt(mag2) : 0.0f;
      l1 *= s;
      l2 *= s;
    }
    r.lambdaT1 = l1;
    r.lambdaT2 = l2;
    const float d1 = l1 - old1, d2 = l2 - old2;
    const V4 p = d1 * r.t1.d + d2 * r.t2.d;
    va -= r.invMassA * p;
    vb += r.invMassB * p;
    wa -= d1 * r.t1.turnA + d2 * r.t2.turnA;
    wb += d1 * r.t1.turnB + d2 * r.t2.turnB;
    // normal
    const float oldN = r.lambdaN;
    r.lambdaN = std::max(oldN + r.massN * (r.targetN - relative(r.n, va, wa, vb, wb)), 0.0f);
    const float dn = r.lambdaN - oldN;
    va -= (r.invMassA * dn) * r.n.d;
    vb += (r.invMassB * dn) * r.n.d;
    wa -= dn * r.n.turnA;
    wb += dn * r.n.turnB;
    v[r.a] = va;
    w[r.a] = wa;
    v[r.b] = vb;
    w[r.b] = wb;
  }
}

bool ContactSolver::positionSweep(std::span<const std::uint32_t> rows) {
  bool moved = false;  // whether a point's pseudo velocity changed by more than the tolerance
  const auto tolerance = static_cast<float>(settings_.positionTolerance);
  V4* const v = pv_.data();
  V4* const w = pw_.data();
  for (const std::uint32_t k : rows) {
    Row& r = rows_[k];
    if (r.biasP <= 0.0f && r.lambdaP <= 0.0f) continue;
    const float old = r.lambdaP;
    r.lambdaP = std::max(old + r.massN * (r.biasP - relative(r.n, v[r.a], w[r.a], v[r.b], w[r.b])), 0.0f);
    const float change = r.lambdaP - old;
    // (the change of the point's pseudo velocity is change / mass)
    moved = moved || std::abs(change) > tolerance * r.massN;
    v[r.a] -= (r.invMassA * change) * r.n.d;
    w[r.a] -= change * r.n.turnA;
    v[r.b] += (r.invMassB * change) * r.n.d;
    w[r.b] += change * r.n.turnB;
  }
  return moved;
}

void ContactSolver::pack(std::size_t part) {
  PartBatches& pb = batches_[part];
  const auto begin = static_cast<std::uint32_t>(parts_[part]);
  const auto count = static_cast<std::uint32_t>(parts_[part + 1] - parts_[part]);
  const std::uint32_t fixed = fixedSlot_[part];
  pb.used.assign(slots_, 0);
  pb.colour.resize(count);
  pb.rest.clear();
  pb.batches.clear();
  // greedy colouring in row order: the first colour neither body has taken (the fixed side takes none)
  std::array<std::uint32_t, 64> perColour{};
  for (std::uint32_t i = 0; i < count; ++i) {
    const Row& r = rows_[begin + i];
    const std::uint64_t taken = (r.a == fixed ? 0 : pb.used[r.a]) | (r.b == fixed ? 0 : pb.used[r.b]);
    if (taken == ~std::uint64_t{0}) {
      pb.colour[i] = 64;
      pb.rest.push_back(begin + i);
      continue;
    }
    const auto c = static_cast<std::uint8_t>(std::countr_one(taken));
    pb.colour[i] = c;
    ++perColour[c];
    if (r.a != fixed) pb.used[r.a] |= std::uint64_t{1} << c;
    if (r.b != fixed) pb.used[r.b] |= std::uint64_t{1} << c;
  }
  // rows by colour (in row order within a colour), four to a batch, a colour's last batch padded
  pb.start[0] = 0;
  for (std::size_t c = 0; c < 64; ++c) pb.start[c + 1] = pb.start[c] + (perColour[c] + 3) / 4 * 4;
  pb.sorted.assign(pb.start[64], kNoRow);
  std::array<std::uint32_t, 64> next{};
  std::copy(pb.start.begin(), pb.start.begin() + 64, next.begin());
  for (std::uint32_t i = 0; i < count; ++i)
    if (pb.colour[i] < 64) pb.sorted[next[pb.colour[i]]++] = begin + i;
  pb.batches.resize(pb.start[64] / 4);
  const auto put = [](const Axis& x, AxisBatch& b, int l) {
    b.dx[l] = x.d.x(), b.dy[l] = x.d.y(), b.dz[l] = x.d.z();
    b.ax[l] = x.crossA.x(), b.ay[l] = x.crossA.y(), b.az[l] = x.crossA.z();
    b.bx[l] = x.crossB.x(), b.by[l] = x.crossB.y(), b.bz[l] = x.crossB.z();
    b.tax[l] = x.turnA.x(), b.tay[l] = x.turnA.y(), b.taz[l] = x.turnA.z();
    b.tbx[l] = x.turnB.x(), b.tby[l] = x.turnB.y(), b.tbz[l] = x.turnB.z();
  };
  for (std::size_t j = 0; j < pb.batches.size(); ++j) {
    Batch& b = pb.batches[j];
    for (int l = 0; l < 4; ++l) {
      const auto lane = static_cast<std::size_t>(l);
      const std::uint32_t k = pb.sorted[4 * j + lane];
      b.row[lane] = k;
      if (k == kNoRow) {  // padding: all zero on the fixed side
        static const Row zero{};
        b.a[lane] = b.b[lane] = fixed;
        put(zero.n, b.n, l), put(zero.t1, b.t1, l), put(zero.t2, b.t2, l);
        b.massN[l] = b.massT1[l] = b.massT2[l] = b.invMassA[l] = b.invMassB[l] = 0.0f;
        b.targetN[l] = b.friction[l] = b.biasP[l] = 0.0f;
        b.lambdaN[l] = b.lambdaT1[l] = b.lambdaT2[l] = b.lambdaP[l] = 0.0f;
        continue;
      }
      const Row& r = rows_[k];
      b.a[lane] = r.a;
      b.b[lane] = r.b;
      put(r.n, b.n, l), put(r.t1, b.t1, l), put(r.t2, b.t2, l);
      b.massN[l] = r.massN, b.massT1[l] = r.massT1, b.massT2[l] = r.massT2;
      b.invMassA[l] = r.invMassA, b.invMassB[l] = r.invMassB;
      b.targetN[l] = r.targetN, b.friction[l] = r.friction, b.biasP[l] = r.biasP;
      b.lambdaN[l] = r.lambdaN, b.lambdaT1[l] = r.lambdaT1, b.lambdaT2[l] = r.lambdaT2, b.lambdaP[l] = r.lambdaP;
    }
  }
}

void ContactSolver::unpack(std::size_t part) {
  for (const Batch& b : batches_[part].batches)
    for (int l = 0; l < 4; ++l) {
      const std::uint32_t k = b.row[static_cast<std::size_t>(l)];
      if (k == kNoRow) continue;
      Row& r = rows_[k];
      r.lambdaN = b.lambdaN[l], r.lambdaT1 = b.lambdaT1[l], r.lambdaT2 = b.lambdaT2[l], r.lambdaP = b.lambdaP[l];
    }
}

namespace {

/// Lane by lane: a where x > 0 or y > 0, else b. (Eigen 3.4's select() goes one coefficient at a time, with
/// a branch per lane; this stays in vector registers.)
inline F4 whereEitherPositive(const F4& x, const F4& y, const F4& a, const F4& b) {
#if defined(__SSE2__)
  const __m128 zero = _mm_setzero_ps();
  const __m128 mask = _mm_or_ps(_mm_cmpgt_ps(_mm_load_ps(x.data()), zero), _mm_cmpgt_ps(_mm_load_ps(y.data()), zero));
  F4 out;
  _mm_store_ps(out.data(), _mm_or_ps(_mm_and_ps(mask, _mm_load_ps(a.data())), _mm_andnot_ps(mask, _mm_load_ps(b.data()))));
  return out;
#else
  F4 out;
  for (int i = 0; i < 4; ++i) out[i] = x[i] > 0.0f || y[i] > 0.0f ? a[i] : b[i];
  return out;
#endif
}

/// J v of an axis, lane by lane.
struct Motion {
  F4 vax, vay, vaz, wax, way, waz, vbx, vby, vbz, wbx, wby, wbz;
  [[nodiscard]] F4 along(const auto& x) const {
    return x.dx * (vbx - vax) + x.dy * (vby - vay) + x.dz * (vbz - vaz) + (x.bx * wbx + x.by * wby + x.bz * wbz) -
           (x.ax * wax + x.ay * way + x.az * waz);
  }
  /// An impulse lam along the axis: -lam on A, +lam on B.
  void push(const auto& x, const F4& lam, const F4& invMassA, const F4& invMassB) {
    const F4 ia = invMassA * lam, ib = invMassB * lam;
    vax -= ia * x.dx, vay -= ia * x.dy, vaz -= ia * x.dz;
    vbx += ib * x.dx, vby += ib * x.dy, vbz += ib * x.dz;
    wax -= lam * x.tax, way -= lam * x.tay, waz -= lam * x.taz;
    wbx += lam * x.tbx, wby += lam * x.tby, wbz += lam * x.tbz;
  }
  void load(const V4* v, const V4* w, const std::array<std::uint32_t, 4>& a, const std::array<std::uint32_t, 4>& b) {
    gather(v, a, vax, vay, vaz);
    gather(w, a, wax, way, waz);
    gather(v, b, vbx, vby, vbz);
    gather(w, b, wbx, wby, wbz);
  }
  void store(V4* v, V4* w, const std::array<std::uint32_t, 4>& a, const std::array<std::uint32_t, 4>& b) const {
    scatter(v, a, vax, vay, vaz);
    scatter(w, a, wax, way, waz);
    scatter(v, b, vbx, vby, vbz);
    scatter(w, b, wbx, wby, wbz);
  }
};

}  // namespace

namespace {

/// The velocity step of a batch whose bodies' velocities are in m (the arithmetic of velocitySweep).
template <class Batch>
inline void velocityBatch(Batch& b, Motion& m) {
  const F4 old1 = b.lambdaT1, old2 = b.lambdaT2;
  F4 l1 = old1 - b.massT1 * m.along(b.t1);
  F4 l2 = old2 - b.massT2 * m.along(b.t2);
  const F4 limit = b.friction * b.lambdaN;
  const F4 mag2 = l1 * l1 + l2 * l2;
  // (limit / |l| where that is below 1: the cone's bound, without a lane-by-lane select)
  const F4 scale = (limit / mag2.max(1e-30f).sqrt()).min(1.0f);
  l1 *= scale;
  l2 *= scale;
  b.lambdaT1 = l1;
  b.lambdaT2 = l2;
  m.push(b.t1, l1 - old1, b.invMassA, b.invMassB);
  m.push(b.t2, l2 - old2, b.invMassA, b.invMassB);
  const F4 oldN = b.lambdaN;
  b.lambdaN = (oldN + b.massN * (b.targetN - m.along(b.n))).max(0.0f);
  m.push(b.n, b.lambdaN - oldN, b.invMassA, b.invMassB);
}

}  // namespace

void ContactSolver::velocityPart(std::size_t part) {
  // four rows at once; and two batches of one colour at once, since they share no body (other than the
  // fixed side, which stays zero): each one's work then overlaps the other's waiting for its results
  V4* const v = v_.data();
  V4* const w = w_.data();
  PartBatches& pb = batches_[part];
  for (std::size_t c = 0; c < 64; ++c) {
    std::size_t j = pb.start[c] / 4;
    const std::size_t end = pb.start[c + 1] / 4;
    for (; j + 1 < end; j += 2) {
      Batch& b0 = pb.batches[j];
      Batch& b1 = pb.batches[j + 1];
      Motion m0, m1;
      m0.load(v, w, b0.a, b0.b);
      m1.load(v, w, b1.a, b1.b);
      velocityBatch(b0, m0);
      velocityBatch(b1, m1);
      m0.store(v, w, b0.a, b0.b);
      m1.store(v, w, b1.a, b1.b);
    }
    if (j < end) {
      Batch& b = pb.batches[j];
      Motion m;
      m.load(v, w, b.a, b.b);
      velocityBatch(b, m);
      m.store(v, w, b.a, b.b);
    }
  }
  velocitySweep(pb.rest);
}

bool ContactSolver::positionPart(std::size_t part) {
  const auto tolerance = static_cast<float>(settings_.positionTolerance);
  V4* const v = pv_.data();
  V4* const w = pw_.data();
  bool moved = false;
  for (Batch& b : batches_[part].batches) {
    // (a row with nothing to correct and no impulse yet stays out)
    const auto active = (b.biasP > 0.0f) || (b.lambdaP > 0.0f);
    if (!active.any()) continue;
    Motion m;
    m.load(v, w, b.a, b.b);
    const F4 old = b.lambdaP;
    b.lambdaP = whereEitherPositive(b.biasP, b.lambdaP, (old + b.massN * (b.biasP - m.along(b.n))).max(0.0f), old);
    const F4 change = b.lambdaP - old;
    moved = moved || (change.abs() > tolerance * b.massN).any();
    m.push(b.n, change, b.invMassA, b.invMassB);
    m.store(v, w, b.a, b.b);
  }
  return positionSweep(batches_[part].rest) || moved;
}

const ContactSolver::Cached* ContactSolver::cached(std::uint64_t key) const {
  if (table_.empty()) return nullptr;
  for (std::uint64_t i = hashSlot(key, tableBits_);; i = (i + 1) & (table_.size() - 1)) {
    const std::uint32_t k = table_[i];
    if (k == kEmpty) return nullptr;
    if (cacheKeys_[k] == key) return &cache_[k];
  }
}

void ContactSolver::remember() {
  // a key can repeat when two points share a particle pair (raw normals never, planes never): the first
  // in solving order is found
  std::size_t size = 16;
  while (size < 2 * rows_.size()) size *= 2;
  table_.assign(size, kEmpty);
  tableBits_ = std::countr_zero(size);
  for (std::size_t k = 0; k < rows_.size(); ++k) {
    for (std::uint64_t i = hashSlot(keys_[k], tableBits_);; i = (i + 1) & (table_.size() - 1)) {
      if (table_[i] == kEmpty) {
        table_[i] = static_cast<std::uint32_t>(k);
        break;
      }
      if (keys_[table_[i]] == keys_[k]) break;
    }
  }
}

void ContactSolver::solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt,
                          ThreadPool* pool) {
  const std::size_t nb = bodies.size(), np = points.size();
  const int workers = pool && np > 0 && pool->worthSharing(np, 1024) ? 2 : 1;
  barrier_.reset(workers);
  ab_.resize(np);
  const auto setUp = [&](int worker) {
    // the points' bodies, compact (each thread reads its share of the points once; the ordering then
    // works in the cache)
    const auto share = [&](int w) { return np * static_cast<std::size_t>(w) / static_cast<std::size_t>(workers); };
    for (std::size_t i = share(worker); i < share(worker + 1); ++i) ab_[i] = {points[i].a, points[i].b};
    barrier_.wait();
    if (worker == 0) {
      order(bodies);
      v_.resize(slots_);
      w_.resize(slots_);
      pv_.resize(slots_);
      pw_.resize(slots_);
      rows_.resize(np);
      keys_.resize(np);
      impulses_.resize(np);
      nextCache_.resize(np);
    }
    barrier_.wait();
    // each half's velocities in their slots and its points spread, by its own thread; each part's fixed
    // side has an entry of its own, always zero
    const auto load = [&](std::size_t side) {
      for (std::size_t k = side == 0 ? 0 : half_; k < (side == 0 ? half_ : nb); ++k) {
        const std::uint32_t i = byX_[k].second, s = slot_[i];
        v_[s] = narrow(bodies[i].v);
        w_[s] = narrow(bodies[i].w);
        pv_[s] = narrow(bodies[i].pv);
        pw_[s] = narrow(bodies[i].pw);
      }
      const std::uint32_t s = fixedSlot_[side];
      v_[s] = w_[s] = pv_[s] = pw_[s] = V4::Zero();
      spread(side);
    };
    if (workers == 1) {
      load(0);
      load(1);
    } else {
      load(static_cast<std::size_t>(worker));
    }
    if (worker == 0) {
      const std::uint32_t s = fixedSlot_[2];
      v_[s] = w_[s] = pv_[s] = pw_[s] = V4::Zero();
      spread(2);
    }
    barrier_.wait();
  };

  // prepare rows: Jacobians, effective masses, restitution targets
  const auto prepare = [&](std::size_t part) {
    for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) {
      const ContactPointInput& in = points[order_[k]];
      Row& r = rows_[k];
      r.a = in.a == kFixed ? fixedSlot_[part] : slot_[in.a];
      r.b = in.b == kFixed ? fixedSlot_[part] : slot_[in.b];
      const SolverBody* a = in.a == kFixed ? nullptr : &bodies[in.a];
      const SolverBody* b = in.b == kFixed ? nullptr : &bodies[in.b];
      r.invMassA = a ? static_cast<float>(a->invMass) : 0.0f;
      r.invMassB = b ? static_cast<float>(b->invMass) : 0.0f;
      Vec3 t1, t2;
      tangents(in.normal, t1, t2);
      r.massN = prepareAxis(a, b, in.rA, in.rB, in.normal, r.n);
      r.massT1 = prepareAxis(a, b, in.rA, in.rB, t1, r.t1);
      r.massT2 = prepareAxis(a, b, in.rA, in.rB, t2, r.t2);
      keys_[k] = in.key;
      r.friction = static_cast<float>(in.friction);
      // relative velocity of B with respect to A along n: negative when approaching
      const double vn = relative(r.n, v_[r.a], w_[r.a], v_[r.b], w_[r.b]);
      // bounce above the threshold; otherwise a speculative contact may close its gap this step, no more
      const double target = vn < -settings_.restitutionThreshold && in.restitution > 0.0 ? -in.restitution * vn
                            : in.depth < 0.0                                           ? in.depth / dt
                                                                                       : 0.0;
      r.targetN = static_cast<float>(target);
      r.biasP = static_cast<float>(
          std::min(settings_.baumgarte * std::max(in.depth - in.slop, 0.0) / dt, settings_.maxCorrectionSpeed));
      r.lambdaN = r.lambdaT1 = r.lambdaT2 = r.lambdaP = 0.0f;
    }
  };
  // warm start from the last step's impulses, matched by key
  const auto warmStart = [&](std::size_t part) {
    std::size_t started = 0;
    for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) {
      Row& r = rows_[k];
      const Cached* c = cached(keys_[k]);
      if (!c) continue;
      r.lambdaN = c->lambdaN;
      r.lambdaT1 = c->lambdaT.dot(r.t1.d);
      r.lambdaT2 = c->lambdaT.dot(r.t2.d);
      const V4 p = r.lambdaN * r.n.d + r.lambdaT1 * r.t1.d + r.lambdaT2 * r.t2.d;
      v_[r.a] -= r.invMassA * p;
      w_[r.a] -= r.lambdaN * r.n.turnA + r.lambdaT1 * r.t1.turnA + r.lambdaT2 * r.t2.turnA;
      v_[r.b] += r.invMassB * p;
      w_[r.b] += r.lambdaN * r.n.turnB + r.lambdaT1 * r.t1.turnB + r.lambdaT2 * r.t2.turnB;
      ++started;
    }
    return started;
  };

  // the velocities back in double, from the impulses: each point's impulse P, +P on B and -P on A, applied
  // to the bodies' double velocities at the point's double arms. The iterations' own single-precision
  // velocities agree with these to rounding, but only these conserve momentum to double precision (and a
  // body without contacts keeps its velocity bit for bit)
  std::array<double, 3> normalSum{};
  const auto finish = [&](std::size_t part) {
    double sum = 0.0;
    for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) {
      const Row& r = rows_[k];
      const ContactPointInput& in = points[order_[k]];
      nextCache_[k] = Cached{r.lambdaN, r.lambdaT1 * r.t1.d + r.lambdaT2 * r.t2.d};
      const Vec3 impulse = wide(r.lambdaN * r.n.d + r.lambdaT1 * r.t1.d + r.lambdaT2 * r.t2.d);
      impulses_[order_[k]] = impulse;
      sum += static_cast<double>(r.lambdaN);
      if (in.a != kFixed) {
        SolverBody& a = bodies[in.a];
        a.v -= a.invMass * impulse;
        a.w -= a.invInertia * in.rA.cross(impulse);
      }
      if (in.b != kFixed) {
        SolverBody& b = bodies[in.b];
        b.v += b.invMass * impulse;
        b.w += b.invInertia * in.rB.cross(impulse);
      }
    }
    normalSum[part] = sum;
  };

  // everything in the same order of phases, on one thread or two: prepare (after which the approach
  // speeds are taken), warm start, the iterations; in each phase the two halves, then the joining points
  std::array<std::size_t, 3> started{};
  // (two sets used alternately, so a thread deciding to stop never reads a flag the other has
  // already overwritten for the next sweep)
  std::array<std::array<std::uint8_t, 3>, 2> moved{};
  const auto iterate = [&](int worker, std::size_t begin, std::size_t end) {
    setUp(worker);
    for (std::size_t part = begin; part < end; ++part) prepare(part);
    if (worker == 0) prepare(2);
    barrier_.wait();
    if (settings_.warmStart) {
      for (std::size_t part = begin; part < end; ++part) started[part] = warmStart(part);
      barrier_.wait();
      if (worker == 0) started[2] = warmStart(2);
      barrier_.wait();
    }
    for (std::size_t part = begin; part < end; ++part) pack(part);
    if (worker == 0) pack(2);
    for (int it = 0; it < settings_.iterations; ++it) {
      for (std::size_t part = begin; part < end; ++part) velocityPart(part);
      barrier_.wait();
      if (worker == 0) velocityPart(2);
      barrier_.wait();
    }
    // (until no point's pseudo velocity changes by more than the tolerance: the same decision on every
    // thread, from the parts' own results)
    for (int it = 0; it < settings_.positionIterations; ++it) {
      auto& m = moved[static_cast<std::size_t>(it & 1)];
      for (std::size_t part = begin; part < end; ++part) m[part] = positionPart(part);
      barrier_.wait();
      if (worker == 0) m[2] = positionPart(2);
      barrier_.wait();
      if (!m[0] && !m[1] && !m[2]) break;
    }
    for (std::size_t part = begin; part < end; ++part) unpack(part);
    if (worker == 0) unpack(2);
    // impulses to the bodies: the halves at once (they share no body), then the joining points, so every
    // body sums its impulses in row order however many threads there are
    for (std::size_t part = begin; part < end; ++part) finish(part);
    for (std::size_t i = nb * begin / 2; i < nb * end / 2; ++i) {
      bodies[i].pv = wide(pv_[slot_[i]]);
      bodies[i].pw = wide(pw_[slot_[i]]);
    }
    barrier_.wait();
    // (this step's keys for the next step's warm start: found while the joining points finish)
    if (worker == 0) finish(2);
    if (worker == workers - 1) remember();
  };
  if (workers == 2) {
    // exactly two ranges of one half each, whatever the pool's size
    pool->run(static_cast<std::size_t>(pool->workers()), [&](int worker, std::size_t, std::size_t) {
      if (worker < 2) iterate(worker, static_cast<std::size_t>(worker), static_cast<std::size_t>(worker) + 1);
    });
  } else {
    iterate(0, 0, 2);
  }
  warmStarted_ = started[0] + started[1] + started[2];
  totalNormalImpulse_ = normalSum[0] + normalSum[1] + normalSum[2];
  std::swap(cacheKeys_, keys_);  // (keys_ is rewritten by the next step's preparation)
  std::swap(cache_, nextCache_);
}

}  // namespace volpar
