#include "volpar/dynamics/contact_solver.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "volpar/engine/core/processor.hpp"
#include "volpar/engine/core/status.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define VOLPAR_WIDE_LANES 1
#else
#define VOLPAR_WIDE_LANES 0
#endif

namespace volpar {

/// The solver's innermost pieces are always inlined: whether GCC inlines them otherwise changes with the
/// size of their callers, and a call per row costs a few per cent of the whole step.
#define VOLPAR_ALWAYS_INLINE [[gnu::always_inline]] inline

namespace {

constexpr std::uint32_t kFixed = ContactPointInput::kFixed;

/// Relative velocity of a point's B side with respect to its A side along its normal (negative: approaching).
double normalVelocity(const ContactPointInput& in, const SolverBody* a, const SolverBody* b) {
  double vn = 0.0;
  if (b) vn += in.normal.dot(b->v) + in.rB.cross(in.normal).dot(b->w);
  if (a) vn -= in.normal.dot(a->v) + in.rA.cross(in.normal).dot(a->w);
  return vn;
}

/// Whether a point whose sides approach at -vn bounces, and whether it does so only once its gap has closed:
/// a speculative point that closes its gap within the step arrives at contact this step and bounces in the
/// next (with the speed it arrived with, kept with its warm-starting impulses), so that it bounces from the
/// surface and not from where its gap was found.
bool bounces(const ContactPointInput& in, double vn, double threshold) { return vn < -threshold && in.restitution > 0.0; }
bool arrives(const ContactPointInput& in, double vn, double dt) { return in.depth < 0.0 && -vn * dt >= -in.depth; }
using V4 = Eigen::Vector4f;

/// A deterministic tangent basis for a unit normal.
void tangents(const Vec3& n, Vec3& t1, Vec3& t2) {
  const Vec3 e = std::abs(n.x()) < 0.57735 ? Vec3::UnitX() : (std::abs(n.y()) < 0.57735 ? Vec3::UnitY() : Vec3::UnitZ());
  t1 = n.cross(e).normalized();
  t2 = n.cross(t1);
}

V4 narrow(const Vec3& x) { return V4(static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z()), 0.0f); }
Vec3 wide(const V4& x) { return x.head<3>().cast<double>(); }

/// The Jacobian of direction d at arms rA, rB into lane l of an axis batch, and its effective mass
/// (computed in double).
template <class AxisBatch>
VOLPAR_ALWAYS_INLINE float prepareAxis(const SolverBody* a, const SolverBody* b, const Vec3& rA, const Vec3& rB,
                                        const Vec3& d, AxisBatch& x, int l) {
  const Vec3 crossA = rA.cross(d), crossB = rB.cross(d);
  const Vec3 turnA = a ? Vec3(a->invInertia * crossA) : Vec3::Zero();
  const Vec3 turnB = b ? Vec3(b->invInertia * crossB) : Vec3::Zero();
  const double k = (a ? a->invMass : 0.0) + (b ? b->invMass : 0.0) + crossA.dot(turnA) + crossB.dot(turnB);
  const auto put = [l](const Vec3& v, auto& lx, auto& ly, auto& lz) {
    lx[l] = static_cast<float>(v.x()), ly[l] = static_cast<float>(v.y()), lz[l] = static_cast<float>(v.z());
  };
  put(d, x.dx, x.dy, x.dz);
  put(crossA, x.ax, x.ay, x.az);
  put(crossB, x.bx, x.by, x.bz);
  put(turnA, x.tax, x.tay, x.taz);
  put(turnB, x.tbx, x.tby, x.tbz);
  return k > 0.0 ? static_cast<float>(1.0 / k) : 0.0f;
}

/// v . d for lane l of an axis batch's direction d (in scalars: a vector built lane by lane goes
/// through memory).
template <class AxisBatch>
float dotDirection(const V4& v, const AxisBatch& x, int l) {
  return v.x() * x.dx[l] + v.y() * x.dy[l] + v.z() * x.dz[l];
}

using F4 = Eigen::Array4f;

/// The x, y and z of four bodies' vectors, lane by lane.
inline void gather(const V4* base, const std::array<std::uint32_t, 4>& slot, F4& x, F4& y, F4& z) {
#if defined(__SSE2__)
  // (a 4 x 4 transpose of the four vectors: their x, y, z and w)
  __m128 r0 = _mm_load_ps(base[slot[0]].data()), r1 = _mm_load_ps(base[slot[1]].data());
  __m128 r2 = _mm_load_ps(base[slot[2]].data()), r3 = _mm_load_ps(base[slot[3]].data());
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  _mm_store_ps(x.data(), r0);
  _mm_store_ps(y.data(), r1);
  _mm_store_ps(z.data(), r2);
#else
  const V4& p0 = base[slot[0]];
  const V4& p1 = base[slot[1]];
  const V4& p2 = base[slot[2]];
  const V4& p3 = base[slot[3]];
  x = F4(p0.x(), p1.x(), p2.x(), p3.x());
  y = F4(p0.y(), p1.y(), p2.y(), p3.y());
  z = F4(p0.z(), p1.z(), p2.z(), p3.z());
#endif
}

/// The inverse of gather (lane by lane, in order: a padding lane writes the fixed side's zero back).
inline void scatter(V4* base, const std::array<std::uint32_t, 4>& slot, const F4& x, const F4& y, const F4& z) {
#if defined(__SSE2__)
  __m128 r0 = _mm_load_ps(x.data()), r1 = _mm_load_ps(y.data()), r2 = _mm_load_ps(z.data()), r3 = _mm_setzero_ps();
  _MM_TRANSPOSE4_PS(r0, r1, r2, r3);
  _mm_store_ps(base[slot[0]].data(), r0);
  _mm_store_ps(base[slot[1]].data(), r1);
  _mm_store_ps(base[slot[2]].data(), r2);
  _mm_store_ps(base[slot[3]].data(), r3);
#else
  for (int i = 0; i < 4; ++i) base[slot[static_cast<std::size_t>(i)]] = V4(x[i], y[i], z[i], 0.0f);
#endif
}

/// Slot of a key in a table of 2^bits entries (Fibonacci hashing: the top bits of the product, which
/// depend on every bit of the key; a key's two particle ids live in its two halves).
inline std::uint64_t hashSlot(std::uint64_t key, int bits) { return (key * 0x9E3779B97F4A7C15ull) >> (64 - bits); }

}  // namespace

void ContactSolver::bisect(std::span<const SolverBody> bodies, std::size_t begin, std::size_t end, int level,
                           std::size_t node) {
  if (level == depth_) {
    leafStart_[node] = begin;
    for (std::size_t k = begin; k < end; ++k) leafOf_[byLeaf_[k].second] = static_cast<std::uint32_t>(node);
    return;
  }
  // the longest side of the node's bodies' bounds (the first of equal sides)
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (std::size_t k = begin; k < end; ++k) {
    const Vec3& x = bodies[byLeaf_[k].second].position;
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  int axis = 0;
  if (end > begin) {
    const Vec3 side = hi - lo;
    if (side.y() > side[axis]) axis = 1;
    if (side.z() > side[axis]) axis = 2;
  }
  for (std::size_t k = begin; k < end; ++k) byLeaf_[k].first = bodies[byLeaf_[k].second].position[axis];
  // split at the median (ties by index: the halves are the same sets whatever the order before)
  const std::size_t mid = begin + (end - begin) / 2;
  if (end - begin >= 2)
    std::nth_element(byLeaf_.begin() + static_cast<std::ptrdiff_t>(begin), byLeaf_.begin() + static_cast<std::ptrdiff_t>(mid),
                     byLeaf_.begin() + static_cast<std::ptrdiff_t>(end));
  bisect(bodies, begin, mid, level + 1, 2 * node);
  bisect(bodies, mid, end, level + 1, 2 * node + 1);
}

int ContactSolver::depthFor(std::size_t bodies, int bodiesPerLeaf) {
  const auto perLeaf = static_cast<std::size_t>(std::max(bodiesPerLeaf, 1));
  int depth = 1;
  while (depth < kMaxDepth && (bodies >> (depth + 1)) >= perLeaf) ++depth;
  return depth;
}

void ContactSolver::order(std::span<const SolverBody> bodies) {
  const std::size_t nb = bodies.size(), np = ab_.size();
  const std::size_t leaves = std::size_t{1} << depth_;
  levelStart_.resize(static_cast<std::size_t>(depth_) + 1);
  levelStart_[static_cast<std::size_t>(depth_)] = 0;
  for (int l = depth_; l > 0; --l)
    levelStart_[static_cast<std::size_t>(l) - 1] = levelStart_[static_cast<std::size_t>(l)] + (std::size_t{1} << l);
  const std::size_t nParts = partCount();
  // the tree: the bodies bisected down to the leaves, byLeaf_ then holding them leaf by leaf
  byLeaf_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) byLeaf_[i] = {0.0, static_cast<std::uint32_t>(i)};
  leafOf_.resize(nb);
  leafStart_.resize(leaves + 1);
  bisect(bodies, 0, nb, 0, 0);
  leafStart_[leaves] = nb;
  // each leaf's velocities contiguous (in the bodies' order), then its fixed entry and a gap (threads solving
  // different nodes must not share a cache line); then every other node's fixed entry, each with a gap
  constexpr std::size_t kGap = 8;
  fixedSlot_.resize(nParts);
  slotBegin_.resize(nParts);
  slotEnd_.resize(nParts);
  leafNext_.resize(leaves);
  std::size_t at = 0;
  for (std::size_t k = 0; k < leaves; ++k) {
    slotBegin_[k] = leafNext_[k] = static_cast<std::uint32_t>(at);
    at += leafStart_[k + 1] - leafStart_[k];
    fixedSlot_[k] = static_cast<std::uint32_t>(at);
    slotEnd_[k] = static_cast<std::uint32_t>(at + 1);
    at += 1 + kGap;
  }
  for (int l = depth_ - 1; l >= 0; --l) {
    for (std::size_t k = 0; k < (std::size_t{1} << l); ++k) {
      const std::size_t p = levelStart(l) + k, shift = static_cast<std::size_t>(depth_ - l);
      slotBegin_[p] = slotBegin_[k << shift];
      slotEnd_[p] = slotEnd_[((k + 1) << shift) - 1];
      fixedSlot_[p] = static_cast<std::uint32_t>(at);
      at += 1 + kGap;
    }
  }
  slots_ = at;
  slot_.resize(nb);
  for (std::size_t i = 0; i < nb; ++i) slot_[i] = leafNext_[leafOf_[i]]++;
  isFixed_.assign(slots_, 0);
  for (const std::uint32_t s : fixedSlot_) isFixed_[s] = 1;
  used_.resize(static_cast<std::size_t>(depth_) + 1);
  for (auto& u : used_) u.resize(slots_);
  // a point belongs to the leaf of its body (the fixed side belongs to every leaf), else to the smallest
  // node holding both its bodies
  const auto partOf = [&](const std::pair<std::uint32_t, std::uint32_t>& p) -> std::size_t {
    if (p.first == kFixed) return leafOf_[p.second];
    if (p.second == kFixed) return leafOf_[p.first];
    std::uint32_t ka = leafOf_[p.first], kb = leafOf_[p.second];
    int level = depth_;
    while (ka != kb) ka >>= 1, kb >>= 1, --level;
    return levelStart(level) + ka;
  };
  parts_.assign(nParts + 1, 0);
  for (const auto& p : ab_) ++parts_[partOf(p) + 1];
  for (std::size_t part = 0; part < nParts; ++part) parts_[part + 1] += parts_[part];
  // (a part's batches hold at most four lanes per row: one, plus at most three of padding per colour or
  // three beside an uncoloured row)
  posBase_.resize(nParts + 1);
  posBase_[0] = 0;
  for (std::size_t part = 0; part < nParts; ++part) posBase_[part + 1] = posBase_[part] + 4 * (parts_[part + 1] - parts_[part]);
  partNext_.assign(parts_.begin(), parts_.end() - 1);
  order_.resize(np);
  for (std::size_t i = 0; i < np; ++i) order_[partNext_[partOf(ab_[i])]++] = static_cast<std::uint32_t>(i);
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
  const auto& from = scratch_;
  std::uint32_t ranks = 0;
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) ranks = std::max(ranks, rank_[from[k]] + 1);
  start.assign(ranks + 1, 0);
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) ++start[rank_[from[k]] + 1];
  for (std::size_t q = 1; q <= ranks; ++q) start[q] += start[q - 1];
  for (std::size_t k = parts_[part]; k < parts_[part + 1]; ++k) order_[parts_[part] + start[rank_[from[k]]]++] = from[k];
}

void ContactSolver::colour(std::size_t part) {
  PartBatches& pb = batches_[part];
  const auto begin = static_cast<std::uint32_t>(parts_[part]);
  const auto count = static_cast<std::uint32_t>(parts_[part + 1] - parts_[part]);
  const std::uint32_t fixed = fixedSlot_[part];
  // (the colours taken, per slot: the node's own slots in its level's table, which no other node of the
  // level touches)
  std::vector<std::uint64_t>& used = used_[static_cast<std::size_t>(levelOf(part))];
  std::fill(used.begin() + slotBegin_[part], used.begin() + slotEnd_[part], 0);
  pb.colour.resize(count);
  // each row's slots (the fixed side: the part's own entry), then a greedy colouring in row order: the
  // first colour neither body has taken (the fixed side takes none)
  std::array<std::uint32_t, 64> perColour{};
  std::uint32_t rest = 0;
  for (std::uint32_t i = 0; i < count; ++i) {
    const auto [ia, ib] = ab_[order_[begin + i]];
    const std::uint32_t a = ia == kFixed ? fixed : slot_[ia], b = ib == kFixed ? fixed : slot_[ib];
    rowSlots_[begin + i] = {a, b};
    const std::uint64_t taken = (a == fixed ? 0 : used[a]) | (b == fixed ? 0 : used[b]);
    if (taken == ~std::uint64_t{0}) {
      pb.colour[i] = 64;
      ++rest;
      continue;
    }
    const auto c = static_cast<std::uint8_t>(std::countr_one(taken));
    pb.colour[i] = c;
    ++perColour[c];
    if (a != fixed) used[a] |= std::uint64_t{1} << c;
    if (b != fixed) used[b] |= std::uint64_t{1} << c;
  }
  // rows by colour (in row order within a colour), four to a batch, a colour's last batch padded; then
  // the uncoloured rows in row order, one to a batch
  pb.start[0] = 0;
  for (std::size_t c = 0; c < 64; ++c) pb.start[c + 1] = pb.start[c] + (perColour[c] + 3) / 4 * 4;
  pb.sorted.assign(pb.start[64] + 4 * rest, kNoRow);
  std::array<std::uint32_t, 64> next{};
  std::copy(pb.start.begin(), pb.start.begin() + 64, next.begin());
  std::uint32_t restNext = pb.start[64];
  for (std::uint32_t i = 0; i < count; ++i) {
    if (pb.colour[i] < 64) {
      pb.sorted[next[pb.colour[i]]++] = begin + i;
    } else {
      pb.sorted[restNext] = begin + i;
      restNext += 4;
    }
  }
  pb.restBegin = pb.start[64] / 4;
  pb.batches.resize(pb.sorted.size() / 4);
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

/// Lane by lane, the correctly rounded square root. (Eigen 3.4's sqrt of four floats, under its default
/// EIGEN_FAST_MATH, is the processor's approximate reciprocal square root refined by one Newton step; that
/// approximation differs between processor makers, and so would the trajectory.)
inline F4 exactSqrt(const F4& x) {
#if defined(__SSE2__)
  F4 out;
  _mm_store_ps(out.data(), _mm_sqrt_ps(_mm_load_ps(x.data())));
  return out;
#else
  return F4(std::sqrt(x[0]), std::sqrt(x[1]), std::sqrt(x[2]), std::sqrt(x[3]));
#endif
}

/// J v of an axis, lane by lane.
struct Motion {
  F4 vax, vay, vaz, wax, way, waz, vbx, vby, vbz, wbx, wby, wbz;
  [[nodiscard]] VOLPAR_ALWAYS_INLINE F4 along(const auto& x) const {
    return x.dx * (vbx - vax) + x.dy * (vby - vay) + x.dz * (vbz - vaz) + (x.bx * wbx + x.by * wby + x.bz * wbz) -
           (x.ax * wax + x.ay * way + x.az * waz);
  }
  /// An impulse lam along the axis: -lam on A, +lam on B.
  VOLPAR_ALWAYS_INLINE void push(const auto& x, const F4& lam, const F4& invMassA, const F4& invMassB) {
    const F4 ia = invMassA * lam, ib = invMassB * lam;
    vax -= ia * x.dx, vay -= ia * x.dy, vaz -= ia * x.dz;
    vbx += ib * x.dx, vby += ib * x.dy, vbz += ib * x.dz;
    wax -= lam * x.tax, way -= lam * x.tay, waz -= lam * x.taz;
    wbx += lam * x.tbx, wby += lam * x.tby, wbz += lam * x.tbz;
  }
  VOLPAR_ALWAYS_INLINE void load(const V4* v, const V4* w, const std::array<std::uint32_t, 4>& a, const std::array<std::uint32_t, 4>& b) {
    gather(v, a, vax, vay, vaz);
    gather(w, a, wax, way, waz);
    gather(v, b, vbx, vby, vbz);
    gather(w, b, wbx, wby, wbz);
  }
  VOLPAR_ALWAYS_INLINE void store(V4* v, V4* w, const std::array<std::uint32_t, 4>& a, const std::array<std::uint32_t, 4>& b) const {
    scatter(v, a, vax, vay, vaz);
    scatter(w, a, wax, way, waz);
    scatter(v, b, vbx, vby, vbz);
    scatter(w, b, wbx, wby, wbz);
  }
};

/// The velocity step of a batch whose bodies' velocities are in m.
template <class Batch>
VOLPAR_ALWAYS_INLINE void velocityBatch(Batch& b, Motion& m) {
  const F4 old1 = b.lambdaT1, old2 = b.lambdaT2;
  F4 l1 = old1 - b.massT1 * m.along(b.t1);
  F4 l2 = old2 - b.massT2 * m.along(b.t2);
  const F4 limit = b.friction * b.lambdaN;
  const F4 mag2 = l1 * l1 + l2 * l2;
  // (limit / |l| where that is below 1: the cone's bound, without a lane-by-lane select)
  const F4 scale = (limit / exactSqrt(mag2.max(1e-30f))).min(1.0f);
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

#if VOLPAR_WIDE_LANES
// Two batches of one colour in the eight lanes of AVX registers, the first batch in the low four, the second
// in the high four. Every lane does exactly the arithmetic of velocityBatch, operation for operation in the
// same order (no fused multiply-adds), so the result is the same bit for bit as two calls of velocityBatch:
// only the number of instructions differs. Compiled for AVX whatever the build's baseline, and run only
// where the processor has it (ContactSolver::wideLanesAvailable()).
#define VOLPAR_WIDE [[gnu::target("avx"), gnu::always_inline]] inline

/// Two aligned fours of floats (F4 lanes, or V4 rows) as one register, lo in the low half.
template <class Four>
VOLPAR_WIDE __m256 join(const Four& lo, const Four& hi) {
  return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_load_ps(lo.data())), _mm_load_ps(hi.data()), 1);
}
VOLPAR_WIDE void split(__m256 x, F4& lo, F4& hi) {
  _mm_store_ps(lo.data(), _mm256_castps256_ps128(x));
  _mm_store_ps(hi.data(), _mm256_extractf128_ps(x, 1));
}

/// gather() of two batches' bodies at once: two 4 x 4 transposes side by side (AVX shuffles work within each
/// half).
VOLPAR_WIDE void gatherWide(const V4* base, const std::array<std::uint32_t, 4>& lo, const std::array<std::uint32_t, 4>& hi,
                            __m256& x, __m256& y, __m256& z) {
  const __m256 r0 = join(base[lo[0]], base[hi[0]]), r1 = join(base[lo[1]], base[hi[1]]);
  const __m256 r2 = join(base[lo[2]], base[hi[2]]), r3 = join(base[lo[3]], base[hi[3]]);
  const __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1);
  const __m256 t2 = _mm256_unpacklo_ps(r2, r3), t3 = _mm256_unpackhi_ps(r2, r3);
  x = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
  y = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
  z = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
}

/// scatter() of two batches' bodies, the first batch's lanes in order, then the second's.
VOLPAR_WIDE void scatterWide(V4* base, const std::array<std::uint32_t, 4>& lo, const std::array<std::uint32_t, 4>& hi,
                             __m256 x, __m256 y, __m256 z) {
  const __m256 t0 = _mm256_unpacklo_ps(x, y), t1 = _mm256_unpackhi_ps(x, y);
  const __m256 t2 = _mm256_unpacklo_ps(z, _mm256_setzero_ps()), t3 = _mm256_unpackhi_ps(z, _mm256_setzero_ps());
  const __m256 r0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0)), r1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
  const __m256 r2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0)), r3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
  _mm_store_ps(base[lo[0]].data(), _mm256_castps256_ps128(r0));
  _mm_store_ps(base[lo[1]].data(), _mm256_castps256_ps128(r1));
  _mm_store_ps(base[lo[2]].data(), _mm256_castps256_ps128(r2));
  _mm_store_ps(base[lo[3]].data(), _mm256_castps256_ps128(r3));
  _mm_store_ps(base[hi[0]].data(), _mm256_extractf128_ps(r0, 1));
  _mm_store_ps(base[hi[1]].data(), _mm256_extractf128_ps(r1, 1));
  _mm_store_ps(base[hi[2]].data(), _mm256_extractf128_ps(r2, 1));
  _mm_store_ps(base[hi[3]].data(), _mm256_extractf128_ps(r3, 1));
}

/// Motion, eight lanes.
struct WideMotion {
  __m256 vax, vay, vaz, wax, way, waz, vbx, vby, vbz, wbx, wby, wbz;
};

/// Motion::along of two batches' axes.
template <class AxisBatch>
VOLPAR_WIDE __m256 alongWide(const WideMotion& m, const AxisBatch& lo, const AxisBatch& hi) {
  const __m256 linear = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(join(lo.dx, hi.dx), _mm256_sub_ps(m.vbx, m.vax)),
                                                    _mm256_mul_ps(join(lo.dy, hi.dy), _mm256_sub_ps(m.vby, m.vay))),
                                      _mm256_mul_ps(join(lo.dz, hi.dz), _mm256_sub_ps(m.vbz, m.vaz)));
  const __m256 turnB = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(join(lo.bx, hi.bx), m.wbx), _mm256_mul_ps(join(lo.by, hi.by), m.wby)),
                                     _mm256_mul_ps(join(lo.bz, hi.bz), m.wbz));
  const __m256 turnA = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(join(lo.ax, hi.ax), m.wax), _mm256_mul_ps(join(lo.ay, hi.ay), m.way)),
                                     _mm256_mul_ps(join(lo.az, hi.az), m.waz));
  return _mm256_sub_ps(_mm256_add_ps(linear, turnB), turnA);
}

/// Motion::push of two batches' axes.
template <class AxisBatch>
VOLPAR_WIDE void pushWide(WideMotion& m, const AxisBatch& lo, const AxisBatch& hi, __m256 lam, __m256 invMassA, __m256 invMassB) {
  const __m256 ia = _mm256_mul_ps(invMassA, lam), ib = _mm256_mul_ps(invMassB, lam);
  const __m256 dx = join(lo.dx, hi.dx), dy = join(lo.dy, hi.dy), dz = join(lo.dz, hi.dz);
  m.vax = _mm256_sub_ps(m.vax, _mm256_mul_ps(ia, dx));
  m.vay = _mm256_sub_ps(m.vay, _mm256_mul_ps(ia, dy));
  m.vaz = _mm256_sub_ps(m.vaz, _mm256_mul_ps(ia, dz));
  m.vbx = _mm256_add_ps(m.vbx, _mm256_mul_ps(ib, dx));
  m.vby = _mm256_add_ps(m.vby, _mm256_mul_ps(ib, dy));
  m.vbz = _mm256_add_ps(m.vbz, _mm256_mul_ps(ib, dz));
  m.wax = _mm256_sub_ps(m.wax, _mm256_mul_ps(lam, join(lo.tax, hi.tax)));
  m.way = _mm256_sub_ps(m.way, _mm256_mul_ps(lam, join(lo.tay, hi.tay)));
  m.waz = _mm256_sub_ps(m.waz, _mm256_mul_ps(lam, join(lo.taz, hi.taz)));
  m.wbx = _mm256_add_ps(m.wbx, _mm256_mul_ps(lam, join(lo.tbx, hi.tbx)));
  m.wby = _mm256_add_ps(m.wby, _mm256_mul_ps(lam, join(lo.tby, hi.tby)));
  m.wbz = _mm256_add_ps(m.wbz, _mm256_mul_ps(lam, join(lo.tbz, hi.tbz)));
}

/// velocityBatch of two batches of one colour (they share no body but the fixed side), with their bodies'
/// velocities loaded and stored.
template <class Batch>
VOLPAR_WIDE void velocityBatchPair(Batch& lo, Batch& hi, V4* v, V4* w) {
  WideMotion m;
  gatherWide(v, lo.a, hi.a, m.vax, m.vay, m.vaz);
  gatherWide(w, lo.a, hi.a, m.wax, m.way, m.waz);
  gatherWide(v, lo.b, hi.b, m.vbx, m.vby, m.vbz);
  gatherWide(w, lo.b, hi.b, m.wbx, m.wby, m.wbz);
  const __m256 invMassA = join(lo.invMassA, hi.invMassA), invMassB = join(lo.invMassB, hi.invMassB);
  const __m256 old1 = join(lo.lambdaT1, hi.lambdaT1), old2 = join(lo.lambdaT2, hi.lambdaT2);
  __m256 l1 = _mm256_sub_ps(old1, _mm256_mul_ps(join(lo.massT1, hi.massT1), alongWide(m, lo.t1, hi.t1)));
  __m256 l2 = _mm256_sub_ps(old2, _mm256_mul_ps(join(lo.massT2, hi.massT2), alongWide(m, lo.t2, hi.t2)));
  const __m256 limit = _mm256_mul_ps(join(lo.friction, hi.friction), join(lo.lambdaN, hi.lambdaN));
  const __m256 mag2 = _mm256_add_ps(_mm256_mul_ps(l1, l1), _mm256_mul_ps(l2, l2));
  // (Eigen's max(a, b) and min(a, b) of packets are _mm_max_ps(b, a) and _mm_min_ps(b, a))
  const __m256 scale =
      _mm256_min_ps(_mm256_set1_ps(1.0f), _mm256_div_ps(limit, _mm256_sqrt_ps(_mm256_max_ps(_mm256_set1_ps(1e-30f), mag2))));
  l1 = _mm256_mul_ps(l1, scale);
  l2 = _mm256_mul_ps(l2, scale);
  split(l1, lo.lambdaT1, hi.lambdaT1);
  split(l2, lo.lambdaT2, hi.lambdaT2);
  pushWide(m, lo.t1, hi.t1, _mm256_sub_ps(l1, old1), invMassA, invMassB);
  pushWide(m, lo.t2, hi.t2, _mm256_sub_ps(l2, old2), invMassA, invMassB);
  const __m256 oldN = join(lo.lambdaN, hi.lambdaN);
  const __m256 lambdaN = _mm256_max_ps(
      _mm256_setzero_ps(),
      _mm256_add_ps(oldN, _mm256_mul_ps(join(lo.massN, hi.massN), _mm256_sub_ps(join(lo.targetN, hi.targetN), alongWide(m, lo.n, hi.n)))));
  split(lambdaN, lo.lambdaN, hi.lambdaN);
  pushWide(m, lo.n, hi.n, _mm256_sub_ps(lambdaN, oldN), invMassA, invMassB);
  scatterWide(v, lo.a, hi.a, m.vax, m.vay, m.vaz);
  scatterWide(w, lo.a, hi.a, m.wax, m.way, m.waz);
  scatterWide(v, lo.b, hi.b, m.vbx, m.vby, m.vbz);
  scatterWide(w, lo.b, hi.b, m.wbx, m.wby, m.wbz);
}

/// The pairs of batches [j, end) of one colour, two at a time, each pair followed by after(j), after(j + 1);
/// returns the batch left over (end when none).
template <class Batch, class After>
[[gnu::target("avx")]] std::size_t velocityPairs(Batch* batches, std::size_t j, std::size_t end, V4* v, V4* w,
                                                 const After& after) {
  for (; j + 1 < end; j += 2) {
    velocityBatchPair(batches[j], batches[j + 1], v, w);
    // (the upper halves cleared before code without AVX runs: left dirty, they slow every SSE instruction
    // after them, and GCC does not always clear them where a target("avx") function returns or calls out)
    _mm256_zeroupper();
    after(j);
    after(j + 1);
  }
  return j;
}
#undef VOLPAR_WIDE
#endif

}  // namespace

bool ContactSolver::wideLanesAvailable() { return VOLPAR_WIDE_LANES && processorHasAvx(); }

template <class After>
void ContactSolver::velocityPart(std::size_t part, const After& after) {
  // four rows at once; and two batches of one colour at once, since they share no body (other than the
  // fixed side, which stays zero): each one's work then overlaps the other's waiting for its results
  V4* const v = v_.data();
  V4* const w = w_.data();
  PartBatches& pb = batches_[part];
  const auto one = [&](std::size_t j) {
    Batch& b = pb.batches[j];
    Motion m;
    m.load(v, w, b.a, b.b);
    velocityBatch(b, m);
    m.store(v, w, b.a, b.b);
    after(j);
  };
  [[maybe_unused]] const bool wide = settings_.wideLanes && wideLanesAvailable();
  for (std::size_t c = 0; c < 64; ++c) {
    std::size_t j = pb.start[c] / 4;
    const std::size_t end = pb.start[c + 1] / 4;
#if VOLPAR_WIDE_LANES
    if (wide) j = velocityPairs(pb.batches.data(), j, end, v, w, after);
#endif
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
      after(j);
      after(j + 1);
    }
    if (j < end) one(j);
  }
  // (the uncoloured rows, one after another)
  for (std::size_t j = pb.restBegin; j < pb.batches.size(); ++j) one(j);
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
  return moved;
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
  while (size < 2 * (parts_.back() + 1)) size *= 2;
  table_.assign(size, kEmpty);
  tableBits_ = std::countr_zero(size);
  for (std::size_t part = 0; part < partCount(); ++part) {
    const auto& sorted = batches_[part].sorted;
    for (std::size_t j = 0; j < sorted.size(); ++j) {
      if (sorted[j] == kNoRow) continue;
      const std::size_t k = posBase_[part] + j;
      for (std::uint64_t i = hashSlot(keys_[k], tableBits_);; i = (i + 1) & (table_.size() - 1)) {
        if (table_[i] == kEmpty) {
          table_[i] = static_cast<std::uint32_t>(k);
          break;
        }
        if (keys_[table_[i]] == keys_[k]) break;
      }
    }
  }
}

void ContactSolver::solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt,
                          ThreadPool* pool) {
  const std::size_t nb = bodies.size(), np = points.size();
  const bool planned = std::exchange(planned_, false);
  VOLPAR_ASSERT(!planned || ab_.size() == np, "a solve of other points than its plan's");
  if (!planned) depth_ = depthFor(nb, settings_.bodiesPerLeaf);
  const std::size_t leaves = std::size_t{1} << depth_;
  // (threads take whole nodes: at most one per leaf)
  const int workers = pool && np > 0 && pool->worthSharing(np, 1024)
                          ? static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(pool->workers()), leaves))
                          : 1;
  barrier_.reset(workers);
  if (!planned) ab_.resize(np);
  // calls f(part) for `worker`'s share of a level's nodes, of all of them (work every process does, such as
  // the set-up, in shares fixed by the worker's number)
  const int ranks = processes_ ? processes_->size() : 1, me = processes_ ? processes_->rank() : 0;
  const auto forShare = [&](int worker, int level, const auto& f) {
    const std::size_t n = std::size_t{1} << level;
    for (std::size_t k = firstShare(worker, workers, n); k < firstShare(worker + 1, workers, n); ++k) f(levelStart(level) + k);
  };
  // The sweeps over a level's nodes (preparing them, the iterations) go by claims: each worker takes the
  // nodes of its own range in turn, from its front, and then any nodes still left in the others' ranges, from
  // their backs. Threads that run at one speed keep their own nodes, sweep after sweep (and their batches in
  // their caches); a thread that runs slower (another process on its core, an uneven processor) hands its
  // last nodes to one that is done. Which thread solves a node never changes its arithmetic, so the result
  // is the same. Each worker's range is one word on a cache line of its own: the sweep's number (every
  // worker numbers the sweeps alike, from phase_), and the range's front and back, taken by compare and
  // swap. A word of another sweep is a range with nothing left to take. Where a level has fewer than
  // kClaimedNodesPerWorker nodes per worker, the workers take their own ranges without claims: with two
  // nodes each, one worker could only gain by taking over a node while running at more than twice the
  // other's speed, and the claims' cache lines would pass between the cores in every sweep for nothing.
  constexpr std::size_t kClaimedNodesPerWorker = 3;
  if (phase_ > 0xf0000000u) {
    for (Claims::Range& r : claims_->range) r.word.store(0, std::memory_order_relaxed);
    phase_ = 0;
  }
  claims_->takenOver.store(0, std::memory_order_relaxed);
  const std::uint32_t firstPhase = phase_;
  std::uint32_t lastPhase = firstPhase;
  const auto forClaimed = [&](int worker, std::uint32_t& phase, int level, std::size_t first, std::size_t end, const auto& f) {
    ++phase;
    const std::size_t n = end - first;
    const auto pack = [&](std::size_t front, std::size_t back) {
      return (std::uint64_t{phase} << 32) | (static_cast<std::uint64_t>(front) << 16) | static_cast<std::uint64_t>(back);
    };
    // takes a node from range r's front (its owner) or back (another worker); false once none is left
    const auto take = [&](Claims::Range& r, bool front) {
      std::uint64_t w = r.word.load(std::memory_order_acquire);
      for (;;) {
        const std::size_t f0 = (w >> 16) & 0xffffu, b0 = w & 0xffffu;
        if ((w >> 32) != phase || f0 >= b0) return false;
        const std::size_t k = front ? f0 : b0 - 1;
        if (r.word.compare_exchange_weak(w, front ? pack(f0 + 1, b0) : pack(f0, b0 - 1), std::memory_order_acq_rel,
                                         std::memory_order_acquire)) {
          f(levelStart(level) + k);
          return true;
        }
      }
    };
    const std::size_t mineBegin = first + firstShare(worker, workers, n), mineEnd = first + firstShare(worker + 1, workers, n);
    if (workers == 1 || n < kClaimedNodesPerWorker * static_cast<std::size_t>(workers)) {
      // (one worker, or too few nodes for a faster worker to gain by taking one over: each takes its own
      // range, and no claims are made)
      for (std::size_t k = mineBegin; k < mineEnd; ++k) f(levelStart(level) + k);
      return;
    }
    Claims::Range& own = claims_->range[static_cast<std::size_t>(worker)];
    own.word.store(pack(mineBegin, mineEnd), std::memory_order_release);
    while (take(own, true)) {
    }
    for (int k = 1; k < workers; ++k)
      while (take(claims_->range[static_cast<std::size_t>((worker + k) % workers)], false))
        claims_->takenOver.fetch_add(1, std::memory_order_relaxed);
  };
  const auto setUp = [&](int worker) {
    // the points' bodies, compact (each thread reads its share of the points once; the ordering then
    // works in the cache), and the plan, unless plan() made them
    const auto share = [&](int w) { return np * static_cast<std::size_t>(w) / static_cast<std::size_t>(workers); };
    if (!planned)
      for (std::size_t i = share(worker); i < share(worker + 1); ++i) ab_[i] = {points[i].a, points[i].b};
    barrier_.wait();
    if (worker == 0) {
      if (!planned) planSolve(bodies);
      v_.resize(slots_);
      w_.resize(slots_);
      pv_.resize(slots_);
      pw_.resize(slots_);
      dp_.resize(slots_);
      dl_.resize(slots_);
      rowSlots_.resize(np);
      keys_.resize(posBase_.back());
      impulses_.resize(np);
      nextCache_.resize(posBase_.back());
      batches_.resize(partCount());
      rankStart_.resize(partCount());
      started_.assign(partCount(), 0);
      normalSum_.assign(partCount(), 0.0);
      partHeavy_.assign(partCount(), 0);
      for (auto& m : moved_) m.assign(partCount(), 0);
    }
    barrier_.wait();
    // each leaf's velocities in their slots, by the thread solving it; each part's fixed side has an entry
    // of its own, always zero; each part's points spread by its thread
    forShare(worker, depth_, [&](std::size_t leaf) {
      for (std::size_t k = leafStart_[leaf]; k < leafStart_[leaf + 1]; ++k) {
        const std::uint32_t i = byLeaf_[k].second, s = slot_[i];
        v_[s] = narrow(bodies[i].v);
        w_[s] = narrow(bodies[i].w);
        pv_[s] = narrow(bodies[i].pv);
        pw_[s] = narrow(bodies[i].pw);
        dp_[s] = dl_[s] = Vec3::Zero();
      }
    });
    for (int l = depth_; l >= 0; --l) {
      forShare(worker, l, [&](std::size_t part) {
        const std::uint32_t s = fixedSlot_[part];
        v_[s] = w_[s] = pv_[s] = pw_[s] = V4::Zero();
        spread(part);
      });
    }
    barrier_.wait();
  };

  // warm start of a batch from the last step's impulses, matched by key (its lanes share no body)
  const auto warmStart = [&](std::size_t part, std::size_t j) {
    Batch& b = batches_[part].batches[j];
    const std::uint64_t* keys = keys_.data() + posBase_[part] + 4 * j;
    std::size_t started = 0;
    for (int l = 0; l < 4; ++l) {
      const Cached* c = b.row[static_cast<std::size_t>(l)] == kNoRow ? nullptr : cached(keys[l]);
      if (!c) continue;
      // (a point that arrived at contact in the last step bounces now, with the speed it arrived with)
      if (c->lambdaT.w() > 0.0f) {
        const ContactPointInput& in = points[order_[b.row[static_cast<std::size_t>(l)]]];
        b.targetN[l] = std::max(b.targetN[l], static_cast<float>(in.restitution) * c->lambdaT.w());
      }
      b.lambdaN[l] = c->lambdaN;
      b.lambdaT1[l] = dotDirection(c->lambdaT, b.t1, l);
      b.lambdaT2[l] = dotDirection(c->lambdaT, b.t2, l);
      ++started;
    }
    if (started == 0) return started;
    Motion m;
    m.load(v_.data(), w_.data(), b.a, b.b);
    m.push(b.n, b.lambdaN, b.invMassA, b.invMassB);
    m.push(b.t1, b.lambdaT1, b.invMassA, b.invMassB);
    m.push(b.t2, b.lambdaT2, b.invMassA, b.invMassB);
    m.store(v_.data(), w_.data(), b.a, b.b);
    return started;
  };
  // prepare rows straight into their batches' lanes: Jacobians, effective masses, restitution targets
  // (from the bodies' double velocities, which the warm start leaves alone); then, if `warm`, warm start
  // each batch while it is in the cache
  const auto prepare = [&](std::size_t part, bool warm) {
    PartBatches& pb = batches_[part];
    const std::uint32_t fixed = fixedSlot_[part];
    std::uint64_t* const keys = keys_.data() + posBase_[part];
    Cached* const next = nextCache_.data() + posBase_[part];
    std::size_t started = 0;
    bool heavy = false;  // (whether a row joins a heavy pair, for solveHeavyIslands(), while the masses are at hand)
    constexpr std::size_t kAhead = 2;  // batches whose input points are fetched ahead of their use
    const auto fetch = [&](std::size_t j) {
      for (std::size_t lane = 0; lane < 4; ++lane) {
        const std::uint32_t k = pb.sorted[4 * j + lane];
        if (k == kNoRow) continue;
        const char* at = reinterpret_cast<const char*>(&points[order_[k]]);
        __builtin_prefetch(at);
        __builtin_prefetch(at + sizeof(ContactPointInput) - 1);
      }
    };
    for (std::size_t j = 0; j < std::min(kAhead, pb.batches.size()); ++j) fetch(j);
    for (std::size_t j = 0; j < pb.batches.size(); ++j) {
      if (j + kAhead < pb.batches.size()) fetch(j + kAhead);
      Batch& b = pb.batches[j];
      b.lambdaN = b.lambdaT1 = b.lambdaT2 = b.lambdaP = F4::Zero();
      for (int l = 0; l < 4; ++l) {
        const auto lane = static_cast<std::size_t>(l);
        const std::uint32_t k = pb.sorted[4 * j + lane];
        b.row[lane] = k;
        if (k == kNoRow) {  // padding: all zero on the fixed side
          b.a[lane] = b.b[lane] = fixed;
          for (AxisBatch* x : {&b.n, &b.t1, &b.t2})
            for (F4* f : {&x->dx, &x->dy, &x->dz, &x->ax, &x->ay, &x->az, &x->bx, &x->by, &x->bz, &x->tax, &x->tay, &x->taz,
                          &x->tbx, &x->tby, &x->tbz})
              (*f)[l] = 0.0f;
          b.massN[l] = b.massT1[l] = b.massT2[l] = b.invMassA[l] = b.invMassB[l] = 0.0f;
          b.targetN[l] = b.friction[l] = b.biasP[l] = 0.0f;
          continue;
        }
        const ContactPointInput& in = points[order_[k]];
        b.a[lane] = rowSlots_[k].first;
        b.b[lane] = rowSlots_[k].second;
        const SolverBody* sa = in.a == kFixed ? nullptr : &bodies[in.a];
        const SolverBody* sb = in.b == kFixed ? nullptr : &bodies[in.b];
        b.invMassA[l] = sa ? static_cast<float>(sa->invMass) : 0.0f;
        b.invMassB[l] = sb ? static_cast<float>(sb->invMass) : 0.0f;
        heavy = heavy || heavyPair(b.invMassA[l], b.invMassB[l], settings_.heavyIslandRatio);
        Vec3 t1, t2;
        tangents(in.normal, t1, t2);
        b.massN[l] = prepareAxis(sa, sb, in.rA, in.rB, in.normal, b.n, l);
        const Vec3 fA = in.rA + in.frictionOffset, fB = in.rB + in.frictionOffset;
        b.massT1[l] = prepareAxis(sa, sb, fA, fB, t1, b.t1, l);
        b.massT2[l] = prepareAxis(sa, sb, fA, fB, t2, b.t2, l);
        keys[4 * j + lane] = in.key;
        b.friction[l] = static_cast<float>(in.friction);
        // relative velocity of B with respect to A along n: negative when approaching
        const double vn = normalVelocity(in, sa, sb);
        // bounce above the threshold (a gap first closes: see bounces()); otherwise a speculative contact
        // may close its gap this step, no more
        const bool deferred = settings_.warmStart && in.depth < 0.0;
        const double target = bounces(in, vn, settings_.restitutionThreshold) && !deferred ? -in.restitution * vn
                              : in.depth < 0.0                                              ? in.depth / dt
                                                                                            : 0.0;
        b.targetN[l] = static_cast<float>(target);
        // (the speed a point arriving at contact within this step arrives with, for its bounce in the next:
        // finish() keeps it with the point's impulses)
        next[4 * j + lane].lambdaT.w() =
            deferred && bounces(in, vn, settings_.restitutionThreshold) && arrives(in, vn, dt) ? static_cast<float>(-vn) : 0.0f;
        b.biasP[l] = static_cast<float>(
            std::min(settings_.baumgarte * std::max(in.depth - in.slop, 0.0) / dt, settings_.maxCorrectionSpeed));
      }
      if (warm) started += warmStart(part, j);
    }
    partHeavy_[part] = heavy ? 1 : 0;
    return started;
  };

  // the velocities back in double, from the impulses: each point's impulse P, +P on B and -P on A, and its
  // moment at the point's double arm, summed per body in double; at the end each body's velocity takes
  // its sums times its inverse mass and inertia. The iterations' own single-precision velocities agree
  // with these to rounding, but only these conserve momentum to double precision (and a body without
  // contacts keeps its velocity bit for bit). Run on each batch right after its last velocity iteration.
  const auto finish = [&](std::size_t part, std::size_t j) {
    const Batch& b = batches_[part].batches[j];
    double sum = 0.0;  // (normal impulses; summed on the thread's own stack)
    Cached* next = nextCache_.data() + posBase_[part] + 4 * j;
    for (int l = 0; l < 4; ++l) {
      const std::uint32_t k = b.row[static_cast<std::size_t>(l)];
      if (k == kNoRow) continue;
      const ContactPointInput& in = points[order_[k]];
      const float l1 = b.lambdaT1[l], l2 = b.lambdaT2[l], ln = b.lambdaN[l];
      const float tx = l1 * b.t1.dx[l] + l2 * b.t2.dx[l], ty = l1 * b.t1.dy[l] + l2 * b.t2.dy[l],
                  tz = l1 * b.t1.dz[l] + l2 * b.t2.dz[l];
      next[l] = Cached{ln, V4(tx, ty, tz, next[l].lambdaT.w())};  // (w: the arrival speed prepare() put there)
      const Vec3 impulse(static_cast<double>(ln * b.n.dx[l] + tx), static_cast<double>(ln * b.n.dy[l] + ty),
                         static_cast<double>(ln * b.n.dz[l] + tz));
      const Vec3 tangential(static_cast<double>(tx), static_cast<double>(ty), static_cast<double>(tz));
      impulses_[order_[k]] = impulse;
      sum += static_cast<double>(ln);
      // (into the slots' double sums: each leaf's slots lie apart from the others', so two threads never write
      // one cache line; the friction acts at its own arms)
      const Vec3 moment = in.frictionOffset.cross(tangential);
      if (in.a != kFixed) {
        dp_[b.a[static_cast<std::size_t>(l)]] -= impulse;
        dl_[b.a[static_cast<std::size_t>(l)]] -= in.rA.cross(impulse) + moment;
      }
      if (in.b != kFixed) {
        dp_[b.b[static_cast<std::size_t>(l)]] += impulse;
        dl_[b.b[static_cast<std::size_t>(l)]] += in.rB.cross(impulse) + moment;
      }
    }
    return sum;
  };

  // everything in the same order of phases, on any number of threads: prepare and warm start, the velocity
  // iterations (the last handing the impulses back), the position iterations; in each phase the leaves,
  // then the nodes a level up, and so on to the root
  const auto iterate = [&](int worker) {
    setUp(worker);
    std::uint32_t phase = firstPhase;  // (this worker's count of claimed sweeps: the same on every worker)
    const auto forOwnClaimed = [&](int l, const auto& f) {
      const std::size_t n = std::size_t{1} << l;
      forClaimed(worker, phase, l, firstShare(me, ranks, n), firstShare(me + 1, ranks, n), f);
    };
    // (with processes: after each level, the velocities of the bodies other processes' nodes touch too, as
    // the level's nodes left them, from worker 0 while the others wait)
    const auto handsOver = [&](int l) { return ranks > 1 && !boundary_[static_cast<std::size_t>(l)].index.empty(); };
    // the nodes whose preparation and warm start this worker does: with processes its process's own, unless
    // the exact solve of heavy islands needs every part's rows on every process
    const auto forPrepared = [&](int l, const auto& f) {
      if (divideSetUp_) forOwnClaimed(l, f);
      else forClaimed(worker, phase, l, 0, std::size_t{1} << l, f);
    };
    // every part prepared at once (the leaves warm started as they go, since they share no body); the other
    // nodes warm started after, level by level, so every body's velocity takes the warm-starting impulses in
    // the same order however many threads there are
    for (int l = depth_; l >= 0; --l)
      forPrepared(l, [&](std::size_t part) { colour(part), started_[part] = prepare(part, l == depth_ && settings_.warmStart); });
    barrier_.wait();
    if (settings_.warmStart) {
      if (divideSetUp_ && handsOver(depth_)) {
        if (worker == 0) handOver(boundary_[static_cast<std::size_t>(depth_)], v_, w_);
        barrier_.wait();
      }
      for (int l = depth_ - 1; l >= 0; --l) {
        forPrepared(l, [&](std::size_t part) {
          std::size_t count = 0;
          for (std::size_t j = 0; j < batches_[part].batches.size(); ++j) count += warmStart(part, j);
          started_[part] = count;
        });
        barrier_.wait();
        if (divideSetUp_ && handsOver(l)) {
          if (worker == 0) handOver(boundary_[static_cast<std::size_t>(l)], v_, w_);
          barrier_.wait();
        }
      }
    }
    if (worker == 0) {
      if (divideSetUp_) heavyIslandsSolved_ = 0;  // (there are none: see heavyPairs())
      else solveHeavyIslands();
    }
    barrier_.wait();
    // the velocity iterations; the last one hands each batch's impulses to the bodies as it goes (level by
    // level: every body sums its impulses in the same order)
    const auto none = [](std::size_t) {};
    for (int it = 0; it < settings_.iterations; ++it) {
      const bool last = it + 1 == settings_.iterations;
      for (int l = depth_; l >= 0; --l) {
        forOwnClaimed(l, [&](std::size_t part) {
          if (last) {
            // (summed on this thread's stack and stored once: the parts' sums share cache lines, which two
            // threads writing them batch by batch would pass back and forth)
            double sum = normalSum_[part];
            velocityPart(part, [&](std::size_t j) { sum += finish(part, j); });
            normalSum_[part] = sum;
          } else {
            velocityPart(part, none);
          }
        });
        barrier_.wait();
        if (handsOver(l)) {
          if (worker == 0) {
            Handover& h = boundary_[static_cast<std::size_t>(l)];
            if (last) handOver(h, v_, w_, dp_, dl_);
            else handOver(h, v_, w_);
          }
          barrier_.wait();
        }
      }
    }
    if (settings_.iterations <= 0) {
      for (int l = depth_; l >= 0; --l) {
        forOwnClaimed(l, [&](std::size_t part) {
          for (std::size_t j = 0; j < batches_[part].batches.size(); ++j) normalSum_[part] += finish(part, j);
        });
        barrier_.wait();
        if (handsOver(l)) {
          if (worker == 0) handOver(boundary_[static_cast<std::size_t>(l)], dp_, dl_);
          barrier_.wait();
        }
      }
    }
    // (until no point's pseudo velocity changes by more than the tolerance: the same decision on every
    // thread, from the parts' own results; two sets of flags used alternately, so a thread deciding to stop
    // never reads a flag another has already overwritten for the next sweep)
    for (int it = 0; it < settings_.positionIterations; ++it) {
      std::vector<std::uint8_t>& m = moved_[static_cast<std::size_t>(it & 1)];
      for (int l = depth_; l >= 0; --l) {
        forOwnClaimed(l, [&](std::size_t part) { m[part] = positionPart(part) ? 1 : 0; });
        barrier_.wait();
        if (handsOver(l)) {
          if (worker == 0) handOver(boundary_[static_cast<std::size_t>(l)], pv_, pw_);
          barrier_.wait();
        }
      }
      if (ranks > 1) {
        // (whether any process's nodes moved: each process's own flags, then one share of the answers)
        if (worker == 0) {
          const auto mine = static_cast<std::size_t>(me);
          std::uint8_t any = 0;
          for (std::size_t k = partsOf_.start[mine]; k < partsOf_.start[mine + 1]; ++k) any |= m[partsOf_.index[k]];
          movedBy_[mine] = any;
          handOver(eachProcess_, movedBy_);
        }
        barrier_.wait();
        if (std::none_of(movedBy_.begin(), movedBy_.end(), [](std::uint8_t x) { return x != 0; })) break;
      } else if (std::none_of(m.begin(), m.end(), [](std::uint8_t x) { return x != 0; })) {
        break;
      }
    }
    // (with processes: every process's final velocities of the bodies its nodes alone touch, and the
    // impulses of its rows, for every process to hold what one process alone would)
    if (ranks > 1) {
      if (worker == 0) {
        if (divideSetUp_) shareLanes();
        planEndHandovers();
        handOver(interior_, dp_, dl_, pv_, pw_);
        handOver(points_, impulses_);
        handOver(lanes_, nextCache_);
        handOver(partsOf_, normalSum_, started_);
      }
      barrier_.wait();
    }
    // the velocities and pseudo velocities back to the bodies, each leaf's by its thread
    forShare(worker, depth_, [&](std::size_t leaf) {
      for (std::size_t k = leafStart_[leaf]; k < leafStart_[leaf + 1]; ++k) {
        const std::uint32_t i = byLeaf_[k].second, s = slot_[i];
        bodies[i].v += bodies[i].invMass * dp_[s];
        bodies[i].w += bodies[i].invInertia * dl_[s];
        bodies[i].pv = wide(pv_[s]);
        bodies[i].pw = wide(pw_[s]);
      }
    });
    // (this step's keys for the next step's warm start)
    if (worker == workers - 1) remember();
    if (worker == 0) lastPhase = phase;
  };
  if (workers > 1) {
    // one range of nodes per worker, whatever the pool's size
    pool->run(static_cast<std::size_t>(pool->workers()), [&](int worker, std::size_t, std::size_t) {
      if (worker < workers) iterate(worker);
    });
  } else {
    iterate(0);
  }
  phase_ = lastPhase;
  warmStarted_ = 0;
  totalNormalImpulse_ = 0.0;
  for (std::size_t part = 0; part < partCount(); ++part) {
    warmStarted_ += started_[part];
    totalNormalImpulse_ += normalSum_[part];
  }
  std::swap(cacheKeys_, keys_);  // (keys_ is rewritten by the next step's preparation)
  std::swap(cache_, nextCache_);
}

void ContactSolver::planSolve(std::span<const SolverBody> bodies) {
  const int ranks = processes_ ? processes_->size() : 1;
  order(bodies);
  if (ranks > 1) planHandovers();
  divideSetUp_ = ranks > 1 && !heavyPairs(bodies);
}

void ContactSolver::plan(std::span<const SolverBody> bodies,
                         std::span<const std::pair<std::uint32_t, std::uint32_t>> pointBodies) {
  depth_ = depthFor(bodies.size(), settings_.bodiesPerLeaf);
  ab_.assign(pointBodies.begin(), pointBodies.end());
  planSolve(bodies);
  planned_ = true;
  // the points of this process's nodes' rows (a node's rows are scratch_[parts_[part]] on until its
  // preparation spreads them into order_), or every point where every process prepares every node
  pointsRead_.assign(ab_.size(), divideSetUp_ ? 0 : 1);
  if (!divideSetUp_) return;
  const auto me = static_cast<std::size_t>(processes_->rank());
  for (std::size_t k = partsOf_.start[me]; k < partsOf_.start[me + 1]; ++k) {
    const std::uint32_t part = partsOf_.index[k];
    for (std::size_t row = parts_[part]; row < parts_[part + 1]; ++row) pointsRead_[scratch_[row]] = 1;
  }
}

void ContactSolver::planHandovers() {
  const int ranks = processes_->size();
  const auto nRanks = static_cast<std::size_t>(ranks);
  // calls f(slot) for each body of each row of process r's nodes of a level (the nodes in runs, process by
  // process, as forOwn() takes them; a part's rows are scratch_[parts_[part]] on, until spread() reorders
  // them into order_)
  const auto eachBody = [&](int level, int r, const auto& f) {
    const std::size_t n = std::size_t{1} << level;
    for (std::size_t k = firstShare(r, ranks, n); k < firstShare(r + 1, ranks, n); ++k) {
      const std::size_t part = levelStart(level) + k;
      for (std::size_t row = parts_[part]; row < parts_[part + 1]; ++row) {
        const auto [a, b] = ab_[scratch_[row]];
        if (a != kFixed) f(slot_[a]);
        if (b != kFixed) f(slot_[b]);
      }
    }
  };
  // which processes' nodes touch each slot: one (its number), several (-2) or none (-1)
  slotProcess_.assign(slots_, -1);
  for (int l = 0; l <= depth_; ++l)
    for (int r = 0; r < ranks; ++r)
      eachBody(l, r, [&](std::uint32_t s) { slotProcess_[s] = slotProcess_[s] == -1 || slotProcess_[s] == r ? r : -2; });
  boundary_.resize(static_cast<std::size_t>(depth_) + 1);
  listed_.assign(slots_, 0);
  for (int l = 0; l <= depth_; ++l) {
    Handover& h = boundary_[static_cast<std::size_t>(l)];
    h.index.clear();
    h.start.resize(nRanks + 1);
    for (int r = 0; r < ranks; ++r) {
      h.start[static_cast<std::size_t>(r)] = h.index.size();
      eachBody(l, r, [&](std::uint32_t s) {
        if (slotProcess_[s] != -2 || listed_[s] == l + 1) return;
        listed_[s] = static_cast<std::uint8_t>(l + 1);
        h.index.push_back(s);
      });
    }
    h.start[nRanks] = h.index.size();
  }
  // the slots one process alone touches, process by process (counted, then placed)
  interior_.start.assign(nRanks + 1, 0);
  for (std::size_t s = 0; s < slots_; ++s)
    if (slotProcess_[s] >= 0) ++interior_.start[static_cast<std::size_t>(slotProcess_[s]) + 1];
  for (std::size_t r = 0; r < nRanks; ++r) interior_.start[r + 1] += interior_.start[r];
  interior_.index.resize(interior_.start[nRanks]);
  interiorNext_.assign(interior_.start.begin(), interior_.start.end() - 1);
  for (std::size_t s = 0; s < slots_; ++s)
    if (slotProcess_[s] >= 0) interior_.index[interiorNext_[static_cast<std::size_t>(slotProcess_[s])]++] = static_cast<std::uint32_t>(s);
  // each process's parts, leaves first; and one entry per process
  partsOf_.index.clear();
  partsOf_.start.resize(nRanks + 1);
  for (int r = 0; r < ranks; ++r) {
    partsOf_.start[static_cast<std::size_t>(r)] = partsOf_.index.size();
    for (int l = depth_; l >= 0; --l) {
      const std::size_t n = std::size_t{1} << l;
      for (std::size_t k = firstShare(r, ranks, n); k < firstShare(r + 1, ranks, n); ++k)
        partsOf_.index.push_back(static_cast<std::uint32_t>(levelStart(l) + k));
    }
  }
  partsOf_.start[nRanks] = partsOf_.index.size();
  eachProcess_.index.resize(nRanks);
  eachProcess_.start.resize(nRanks + 1);
  for (std::size_t r = 0; r <= nRanks; ++r) {
    if (r < nRanks) eachProcess_.index[r] = static_cast<std::uint32_t>(r);
    eachProcess_.start[r] = r;
  }
  movedBy_.assign(nRanks, 0);
}

bool ContactSolver::heavyPairs(std::span<const SolverBody> bodies) const {
  // (the test solveHeavyIslands() makes of each row, from the same single-precision masses)
  const double ratio = settings_.heavyIslandRatio;
  if (!(ratio > 0.0) || settings_.heavyIslandRows <= 0) return false;
  for (const auto& [a, b] : ab_) {
    if (a == kFixed || b == kFixed) continue;
    if (heavyPair(static_cast<float>(bodies[a].invMass), static_cast<float>(bodies[b].invMass), ratio)) return true;
  }
  return false;
}

void ContactSolver::shareLanes() {
  // each process's parts' lanes (their rows in colour order) and their rows' warm-starting keys, in the order
  // of partsOf_ (the keys travel: a process need not hold the points of other processes' rows)
  const int ranks = processes_->size();
  const auto mine = static_cast<std::size_t>(processes_->rank());
  lanesMine_.clear();
  for (std::size_t k = partsOf_.start[mine]; k < partsOf_.start[mine + 1]; ++k) {
    const std::uint32_t part = partsOf_.index[k];
    const auto& sorted = batches_[part].sorted;
    appendBytes(lanesMine_, sorted);
    keysScratch_.clear();
    for (std::size_t j = 0; j < sorted.size(); ++j)
      if (sorted[j] != kNoRow) keysScratch_.push_back(keys_[posBase_[part] + j]);
    appendBytes(lanesMine_, keysScratch_);
  }
  processes_->gather(lanesMine_, lanesAll_);
  const std::byte* at = lanesAll_.data();
  for (std::size_t r = 0; r < static_cast<std::size_t>(ranks); ++r) {
    for (std::size_t k = partsOf_.start[r]; k < partsOf_.start[r + 1]; ++k) {
      const std::uint32_t part = partsOf_.index[k];
      auto& sorted = r == mine ? lanesScratch_ : batches_[part].sorted;
      readBytes(at, sorted);
      readBytes(at, keysScratch_);
      if (r == mine) continue;
      std::size_t next = 0;
      for (std::size_t j = 0; j < sorted.size(); ++j)
        if (sorted[j] != kNoRow) keys_[posBase_[part] + j] = keysScratch_[next++];
    }
  }
}

void ContactSolver::planEndHandovers() {
  // each process's parts' real lanes (their batches, once coloured) and their rows' input points (order_,
  // once spread)
  const auto nRanks = static_cast<std::size_t>(processes_->size());
  lanes_.index.clear();
  points_.index.clear();
  lanes_.start.resize(nRanks + 1);
  points_.start.resize(nRanks + 1);
  for (std::size_t r = 0; r < nRanks; ++r) {
    lanes_.start[r] = lanes_.index.size();
    points_.start[r] = points_.index.size();
    for (std::size_t k = partsOf_.start[r]; k < partsOf_.start[r + 1]; ++k) {
      const std::uint32_t part = partsOf_.index[k];
      const auto& sorted = batches_[part].sorted;
      for (std::size_t j = 0; j < sorted.size(); ++j)
        if (sorted[j] != kNoRow) lanes_.index.push_back(static_cast<std::uint32_t>(posBase_[part] + j));
      points_.index.insert(points_.index.end(), order_.begin() + static_cast<std::ptrdiff_t>(parts_[part]),
                           order_.begin() + static_cast<std::ptrdiff_t>(parts_[part + 1]));
    }
  }
  lanes_.start[nRanks] = lanes_.index.size();
  points_.start[nRanks] = points_.index.size();
}

template <class... T>
void ContactSolver::handOver(const Handover& h, LargeVector<T>&... arrays) {
  if (h.index.empty()) return;  // (the same lists on every process: none of them shares)
  const int ranks = processes_->size(), me = processes_->rank();
  constexpr std::size_t per = (sizeof(T) + ...);
  handoverBytes_.resize(h.index.size() * per);
  shareOffset_.resize(static_cast<std::size_t>(ranks));
  shareCount_.resize(static_cast<std::size_t>(ranks));
  for (std::size_t r = 0; r < static_cast<std::size_t>(ranks); ++r) {
    shareOffset_[r] = h.start[r] * per;
    shareCount_[r] = (h.start[r + 1] - h.start[r]) * per;
  }
  const auto mine = static_cast<std::size_t>(me);
  std::byte* out = handoverBytes_.data() + shareOffset_[mine];
  for (std::size_t k = h.start[mine]; k < h.start[mine + 1]; ++k) {
    const std::uint32_t i = h.index[k];
    ((std::memcpy(out, static_cast<const void*>(&arrays[i]), sizeof(T)), out += sizeof(T)), ...);
  }
  processes_->share(handoverBytes_, shareOffset_, shareCount_);
  for (std::size_t r = 0; r < static_cast<std::size_t>(ranks); ++r) {
    if (r == mine) continue;
    const std::byte* in = handoverBytes_.data() + shareOffset_[r];
    for (std::size_t k = h.start[r]; k < h.start[r + 1]; ++k) {
      const std::uint32_t i = h.index[k];
      ((std::memcpy(static_cast<void*>(&arrays[i]), in, sizeof(T)), in += sizeof(T)), ...);
    }
  }
}

void ContactSolver::saveWarmStart(StateArchive& archive) const {
  // the entries the table finds, by lane: one per key (the first in solving order, as remember() kept it)
  std::vector<std::uint32_t> lanes;
  for (const std::uint32_t k : table_)
    if (k != kEmpty) lanes.push_back(k);
  std::sort(lanes.begin(), lanes.end());
  std::vector<std::int64_t> keys;
  std::vector<float> impulses;
  for (const std::uint32_t k : lanes) {
    keys.push_back(static_cast<std::int64_t>(cacheKeys_[k]));
    const Cached& c = cache_[k];
    impulses.insert(impulses.end(), {c.lambdaN, c.lambdaT[0], c.lambdaT[1], c.lambdaT[2], c.lambdaT[3]});
  }
  archive.put("solver/keys", std::span<const std::int64_t>(keys));
  archive.put("solver/impulses", std::span<const float>(impulses), 5);
  archive.putScalar("solver/table_bits", static_cast<std::int64_t>(table_.empty() ? 0 : tableBits_));
}

bool ContactSolver::restoreWarmStart(StateReader& r) {
  const std::vector<std::int64_t> keys = r.get<std::int64_t>("solver/keys");
  const std::vector<float> impulses = r.get<float>("solver/impulses", 5, keys.size());
  const std::int64_t bits = r.i64("solver/table_bits");
  if (!r.ok()) return false;
  if (bits < 0 || bits > 31 || (bits == 0 && !keys.empty()) || (bits > 0 && 2 * keys.size() > (std::size_t{1} << bits))) {
    r.fail("the checkpoint's warm-start table of 2^" + std::to_string(bits) + " entries cannot hold " +
           std::to_string(keys.size()) + " keys");
    return false;
  }
  cacheKeys_.assign(keys.size(), 0);
  cache_.assign(keys.size(), Cached{});
  table_.clear();
  tableBits_ = static_cast<int>(bits);
  if (bits > 0) table_.assign(std::size_t{1} << bits, kEmpty);
  for (std::size_t k = 0; k < keys.size(); ++k) {
    cacheKeys_[k] = static_cast<std::uint64_t>(keys[k]);
    const float* f = impulses.data() + 5 * k;
    cache_[k].lambdaN = f[0];
    cache_[k].lambdaT = V4(f[1], f[2], f[3], f[4]);
    for (std::uint64_t i = hashSlot(cacheKeys_[k], tableBits_);; i = (i + 1) & (table_.size() - 1)) {
      if (table_[i] == kEmpty) {
        table_[i] = static_cast<std::uint32_t>(k);
        break;
      }
      if (cacheKeys_[table_[i]] == cacheKeys_[k]) {
        r.fail("the checkpoint's warm-start keys repeat");
        return false;
      }
    }
  }
  return true;
}

}  // namespace volpar
