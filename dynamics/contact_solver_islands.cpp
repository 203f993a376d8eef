// The contact solver's exact normal solve for small islands of bodies whose masses differ widely.
//
// Sequential impulses converge at a rate set by the mass ratio: a heavy box on a light one on the ground
// moves the heavy box by about m_light / m_heavy of its error per iteration (each iteration pushes the light
// box into the ground and the ground pushes it back), so a ratio of 100 needs hundreds of iterations and a
// ratio of 1000 thousands. Warm starting hides this only while the contacts and their loads stay the same.
//
// Here the normal impulses of such an island are found exactly, after the warm start and before the
// iterations: with u0 the points' normal velocities without their normal impulses and A the island's
// Delassus matrix (A_ij: the change of point i's normal velocity per unit normal impulse at point j), the
// impulses solve the linear complementarity problem
//
//     u = u0 + A lambda >= target,   lambda >= 0,   lambda_i (u - target)_i = 0,
//
// by active sets (Murty's least-index rule: the first point whose impulse is negative, or whose velocity is
// below its target while it carries none, changes side, until none is left). A patch's four coplanar points
// make A singular (they share three degrees of freedom), and A is built from the single-precision rows:
// each point's diagonal is raised by 1e-7 of itself (1e-6, 1e-5, 1e-4 if the rule does not end within
// 4n + 8 rounds; an island that does not settle even then is left to the iterations). The iterations then
// go on from the exact impulses (friction, and what the friction changes), so the result is what the
// iterations would reach, at once.
//
// Only islands of at most heavyIslandRows (at most 128) points with a touching pair whose masses differ by
// heavyIslandRatio or more: elsewhere the iterations converge well and cost less. Run by one thread
// between barriers, in the parts' order: the result does not depend on the thread count.

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "volpar/dynamics/contact_solver.hpp"

namespace volpar {

namespace {

constexpr int kMaxRows = 128;  // the largest island solved (a 128 x 128 dense problem)

Eigen::Vector4f narrow(const Vec3& x) {
  return {static_cast<float>(x.x()), static_cast<float>(x.y()), static_cast<float>(x.z()), 0.0f};
}
Vec3 wide(const Eigen::Vector4f& x) { return x.head<3>().cast<double>(); }

std::uint32_t findRoot(LargeVector<std::uint32_t>& parent, std::uint32_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];  // (path halving)
    i = parent[i];
  }
  return i;
}

using Matrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxRows, kMaxRows>;
using Vector = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, kMaxRows, 1>;

}  // namespace

struct ContactSolver::IslandSystem {
  Matrix m;
  Vector rhs, x, lambda;
  Eigen::LDLT<Matrix> ldlt;
};

ContactSolver::ContactSolver() = default;
ContactSolver::~ContactSolver() = default;
ContactSolver::ContactSolver(ContactSolver&&) noexcept = default;
ContactSolver& ContactSolver::operator=(ContactSolver&&) noexcept = default;

void ContactSolver::solveHeavyIslands() {
  heavyIslandsSolved_ = 0;
  const double ratio = settings_.heavyIslandRatio;
  const int maxRows = std::min(settings_.heavyIslandRows, kMaxRows);
  if (!(ratio > 0.0) || maxRows <= 0) return;
  const auto isFixed = [&](std::uint32_t s) { return isFixed_[s] != 0; };
  const auto forEachRow = [&](const auto& f) {
    for (std::size_t part = 0; part < partCount(); ++part) {
      const auto& batches = batches_[part].batches;
      for (std::size_t j = 0; j < batches.size(); ++j)
        for (std::size_t l = 0; l < 4; ++l)
          if (batches[j].row[l] != kNoRow) f(part, j, l, batches[j]);
    }
  };
  const auto heavyPairAt = [&](const Batch& b, std::size_t l) {
    return heavyPair(b.invMassA[static_cast<int>(l)], b.invMassB[static_cast<int>(l)], ratio);
  };
  // (whether any row joins a heavy pair: each part's preparation found out, while its rows were at hand)
  if (std::none_of(partHeavy_.begin(), partHeavy_.end(), [](std::uint8_t h) { return h != 0; })) return;

  // islands: the slots joined by rows between two bodies (the fixed sides join nothing)
  islandOf_.resize(slots_);
  for (std::uint32_t s = 0; s < slots_; ++s) islandOf_[s] = s;
  forEachRow([&](std::size_t, std::size_t, std::size_t l, const Batch& b) {
    if (isFixed(b.a[l]) || isFixed(b.b[l])) return;
    const std::uint32_t ra = findRoot(islandOf_, b.a[l]), rb = findRoot(islandOf_, b.b[l]);
    if (ra != rb) islandOf_[std::max(ra, rb)] = std::min(ra, rb);
  });
  const auto rootOf = [&](const Batch& b, std::size_t l) {
    return findRoot(islandOf_, isFixed(b.a[l]) ? b.b[l] : b.a[l]);
  };
  islandHeavy_.assign(slots_, 0);
  islandStart_.assign(slots_ + 1, 0);
  forEachRow([&](std::size_t, std::size_t, std::size_t l, const Batch& b) {
    const std::uint32_t r = rootOf(b, l);
    if (heavyPairAt(b, l)) islandHeavy_[r] = 1;
    ++islandStart_[r + 1];
  });
  for (std::uint32_t s = 0; s < slots_; ++s) islandStart_[s + 1] += islandStart_[s];
  islandFill_.assign(islandStart_.begin(), islandStart_.end() - 1);
  islandRows_.resize(islandStart_[slots_]);
  // (a row as part in the upper half, lane in bits 30-31, batch below)
  forEachRow([&](std::size_t part, std::size_t j, std::size_t l, const Batch& b) {
    const std::uint32_t r = rootOf(b, l);
    islandRows_[islandFill_[r]++] = std::uint64_t{part} << 32 | std::uint64_t{l} << 30 | j;
  });

  if (!islandSystem_) islandSystem_ = std::make_unique<IslandSystem>();
  IslandSystem& sys = *islandSystem_;
  islandA_.resize(static_cast<std::size_t>(kMaxRows * kMaxRows));
  islandB_.resize(kMaxRows);
  islandLambda_.resize(kMaxRows);
  islandU0_.resize(kMaxRows);
  islandActive_.resize(kMaxRows);
  for (std::uint32_t root = 0; root < slots_; ++root) {
    const std::uint32_t begin = islandStart_[root], end = islandStart_[root + 1];
    const int n = static_cast<int>(end - begin);
    if (!islandHeavy_[root] || n == 0 || n > maxRows) continue;
    const auto rowAt = [&](int i, std::size_t& l) -> Batch& {
      const std::uint64_t code = islandRows_[begin + static_cast<std::uint32_t>(i)];
      l = code >> 30 & 3u;
      return batches_[code >> 32].batches[code & 0x3fffffffu];
    };
    // one side of a row: its slot (none when fixed), sign, inverse mass, and the direction's linear and
    // angular parts
    struct Side {
      std::uint32_t slot;
      double sign, invMass;
      Vec3 d, cross, turn;
    };
    const auto side = [&](const Batch& b, std::size_t l, bool onB) {
      const int k = static_cast<int>(l);
      const AxisBatch& x = b.n;
      Side s;
      s.slot = onB ? b.b[l] : b.a[l];
      s.sign = onB ? 1.0 : -1.0;
      const auto lane = [k](const Eigen::Array4f& a, const Eigen::Array4f& b2, const Eigen::Array4f& c) {
        return Vec3(static_cast<double>(a[k]), static_cast<double>(b2[k]), static_cast<double>(c[k]));
      };
      s.invMass = static_cast<double>(onB ? b.invMassB[k] : b.invMassA[k]);
      s.d = lane(x.dx, x.dy, x.dz);
      s.cross = onB ? lane(x.bx, x.by, x.bz) : lane(x.ax, x.ay, x.az);
      s.turn = onB ? lane(x.tbx, x.tby, x.tbz) : lane(x.tax, x.tay, x.taz);
      return s;
    };
    Eigen::Map<Eigen::MatrixXd> A(islandA_.data(), n, n);
    double largest = 0.0;
    for (int i = 0; i < n; ++i) {
      std::size_t li = 0;
      const Batch& bi = rowAt(i, li);
      for (int k = 0; k <= i; ++k) {
        std::size_t lk = 0;
        const Batch& bk = rowAt(k, lk);
        double aik = 0.0;
        for (const bool si : {false, true}) {
          const Side x = side(bi, li, si);
          if (isFixed(x.slot)) continue;
          for (const bool sk : {false, true}) {
            const Side y = side(bk, lk, sk);
            if (y.slot != x.slot) continue;
            aik += x.sign * y.sign * (x.invMass * x.d.dot(y.d) + x.cross.dot(y.turn));
          }
        }
        A(i, k) = A(k, i) = aik;
      }
      largest = std::max(largest, A(i, i));
      // the normal velocity now (after the warm start), less what the point's own impulse adds
      double u = 0.0;
      for (const bool si : {false, true}) {
        const Side x = side(bi, li, si);
        u += x.sign * (x.d.dot(wide(v_[x.slot])) + x.cross.dot(wide(w_[x.slot])));
      }
      islandU0_[static_cast<std::size_t>(i)] = u;
      islandLambda_[static_cast<std::size_t>(i)] = static_cast<double>(bi.lambdaN[static_cast<int>(li)]);
      islandB_[static_cast<std::size_t>(i)] = static_cast<double>(bi.targetN[static_cast<int>(li)]);
    }
    if (!(largest > 0.0)) continue;
    for (int i = 0; i < n; ++i) {
      double u = islandU0_[static_cast<std::size_t>(i)];
      for (int k = 0; k < n; ++k) u -= A(i, k) * islandLambda_[static_cast<std::size_t>(k)];
      islandU0_[static_cast<std::size_t>(i)] = u;
    }
    double scaleU = 1e-3;
    for (int i = 0; i < n; ++i)
      scaleU = std::max({scaleU, std::abs(islandU0_[static_cast<std::size_t>(i)]), std::abs(islandB_[static_cast<std::size_t>(i)])});
    const double tolU = 1e-9 * scaleU;
    Vector& lambda = sys.lambda;
    lambda.setZero(n);
    bool settled = false;
    // The least-index rule ends for a positive definite A, but the A of coplanar points is singular and,
    // built from single-precision rows, known to about 1e-7: each point's diagonal is raised by a fraction
    // of itself, the smallest of these that lets the rule end (a larger one lets the points sink by that
    // fraction of their load's effect, into the slop)
    for (const double regular : {1e-7, 1e-6, 1e-5, 1e-4}) {
      // active sets, from the points that carried a load in the last step
      for (int i = 0; i < n; ++i) islandActive_[static_cast<std::size_t>(i)] = islandLambda_[static_cast<std::size_t>(i)] > 0.0 ? 1 : 0;
      for (int round = 0; round < 4 * n + 8 && !settled; ++round) {
        int na = 0;
        std::array<int, kMaxRows> act{};
        for (int i = 0; i < n; ++i)
          if (islandActive_[static_cast<std::size_t>(i)]) act[static_cast<std::size_t>(na++)] = i;
        lambda.setZero();
        if (na > 0) {
          sys.m.resize(na, na);
          sys.rhs.resize(na);
          for (int p = 0; p < na; ++p) {
            const int i = act[static_cast<std::size_t>(p)];
            for (int q = 0; q < na; ++q) sys.m(p, q) = A(i, act[static_cast<std::size_t>(q)]);
            sys.m(p, p) *= 1.0 + regular;
            sys.rhs(p) = islandB_[static_cast<std::size_t>(i)] - islandU0_[static_cast<std::size_t>(i)];
          }
          sys.ldlt.compute(sys.m);
          sys.x = sys.ldlt.solve(sys.rhs);
          if (!sys.x.allFinite()) break;
          for (int p = 0; p < na; ++p) lambda(act[static_cast<std::size_t>(p)]) = sys.x(p);
        }
        // Murty's least-index rule: the first point whose impulse is negative (active) or whose velocity
        // is below its target (inactive) changes side
        int flip = -1;
        for (int i = 0; i < n && flip < 0; ++i) {
          if (islandActive_[static_cast<std::size_t>(i)]) {
            if (lambda(i) < 0.0) flip = i;
            continue;
          }
          double u = islandU0_[static_cast<std::size_t>(i)] - islandB_[static_cast<std::size_t>(i)];
          for (int p = 0; p < na; ++p) u += A(i, act[static_cast<std::size_t>(p)]) * lambda(act[static_cast<std::size_t>(p)]);
          if (u < -tolU) flip = i;
        }
        if (flip < 0) settled = true;
        else islandActive_[static_cast<std::size_t>(flip)] ^= 1;
      }
      if (settled) break;
    }
    if (!settled) continue;
    // the change of each point's impulse onto the velocities, and the impulses into the rows
    for (int i = 0; i < n; ++i) {
      std::size_t l = 0;
      Batch& b = rowAt(i, l);
      const int k = static_cast<int>(l);
      const float now = static_cast<float>(lambda(i));
      const float change = now - b.lambdaN[k];
      b.lambdaN[k] = now;
      for (const bool onB : {false, true}) {
        const Side x = side(b, l, onB);
        if (isFixed(x.slot)) continue;
        const float sign = static_cast<float>(x.sign);
        v_[x.slot] += sign * change * static_cast<float>(x.invMass) * narrow(x.d);
        w_[x.slot] += sign * change * narrow(x.turn);
      }
    }
    ++heavyIslandsSolved_;
  }
}

}  // namespace volpar
