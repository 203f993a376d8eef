#include "volpar/dynamics/frame_multigrid.hpp"

#include <algorithm>
#include <limits>

namespace volpar {

namespace {

constexpr std::uint32_t kFree = 0xffffffffu;
constexpr std::size_t kMaxLevels = 32;

/// The rigid motion of an aggregate seen from a member at offset d: u = U + Theta x d, theta = Theta.
Block6 prolongation(const Vec3& d) {
  Block6 p = Block6::Identity();
  p.block<3, 3>(0, 3) << 0.0, d.z(), -d.y(), -d.z(), 0.0, d.x(), d.y(), -d.x(), 0.0;  // -[d]x
  return p;
}

/// f(begin, end) over [0, n), shared among the pool's workers where there are enough rows (each row's
/// result never depends on which worker computes it).
template <class F>
void forRows(ThreadPool* pool, std::size_t n, F&& f) {
  if (pool && pool->worthSharing(n, FrameMultigrid::kRowsPerWorker)) pool->run(n, [&](int, std::size_t b, std::size_t e) { f(b, e); });
  else f(0, n);
}

/// f(chunk) for every chunk of [0, chunks), the chunks shared among the pool's workers where it is given
/// (each chunk's result never depends on which worker computes it).
template <class F>
void forChunks(ThreadPool* pool, std::size_t chunks, F&& f) {
  if (pool && chunks > 1 && pool->worthSharing(chunks, 1))
    pool->run(chunks, [&](int, std::size_t b, std::size_t e) {
      for (std::size_t c = b; c < e; ++c) f(c);
    });
  else
    for (std::size_t c = 0; c < chunks; ++c) f(c);
}

}  // namespace

double chunkedDot(const Eigen::VectorXd& a, const Eigen::VectorXd& b, ThreadPool* pool, std::vector<double>& partial) {
  const auto n = static_cast<std::size_t>(a.size());
  const std::size_t chunks = (n + kDotChunk - 1) / kDotChunk;
  partial.resize(chunks);
  forRows(pool, chunks, [&](std::size_t from, std::size_t to) {
    for (std::size_t c = from; c < to; ++c) {
      const auto begin = static_cast<Eigen::Index>(c * kDotChunk);
      const auto size = static_cast<Eigen::Index>(std::min(kDotChunk, n - c * kDotChunk));
      partial[c] = a.segment(begin, size).dot(b.segment(begin, size));
    }
  });
  double sum = 0.0;
  for (const double p : partial) sum += p;
  return sum;
}

void BlockMatrix6::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool) const {
  forRows(pool, rows(), [&](std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i) {
      Vec6 s = Vec6::Zero();
      for (std::uint32_t k = start[i]; k < start[i + 1]; ++k) subtractProduct(k, x.data() + 6 * column[k], s);
      y.segment<6>(6 * static_cast<Eigen::Index>(i)) = -s;  // (s is -y: the products subtract)
    }
  });
}

void BlockMatrix6::setPattern(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours) {
  setRows(neighbourStart, neighbours);
  block.assign(column.size(), Block6::Zero());
}

void FrameMultigrid::build(const FrameStiffness& fine, const std::vector<Vec3>& positions) {
  levels_.clear();
  levels_.reserve(kMaxLevels);
  std::vector<Vec3> at = positions;
  if (fine.rows() > kCoarsest && coarsen(fine, at))
    while (levels_.size() < kMaxLevels && levels_.back().coarse.rows() > kCoarsest && coarsen(levels_.back().coarse, at)) {
    }
  coarsestStale_ = true;
}

template <class Matrix>
bool FrameMultigrid::coarsen(const Matrix& a, std::vector<Vec3>& at) {
  std::vector<Vec3> centres;
  std::vector<std::uint32_t> members, memberStart, mark, neighbourStart, neighbours;
  std::vector<std::uint32_t> nearStart, near;
  std::vector<std::uint8_t> rooted;
  constexpr double kNear = 1.2;  // neighbours within 1.2 x the nearest's distance are near
  {
    const auto n = static_cast<std::uint32_t>(a.rows());
    // the graph aggregates follow: each node's nearest neighbours (within kNear of the nearest's distance),
    // so that an aggregate is a node and the ring around it, not everything a block joins it to
    nearStart.assign(n + 1, 0);
    near.clear();
    for (std::uint32_t i = 0; i < n; ++i) {
      double nearest = std::numeric_limits<double>::infinity();
      for (std::uint32_t k = a.start[i]; k < a.start[i + 1]; ++k)
        if (a.column[k] != i) nearest = std::min(nearest, (at[a.column[k]] - at[i]).squaredNorm());
      for (std::uint32_t k = a.start[i]; k < a.start[i + 1]; ++k)
        if (a.column[k] != i && (at[a.column[k]] - at[i]).squaredNorm() <= kNear * kNear * nearest) near.push_back(a.column[k]);
      nearStart[i + 1] = static_cast<std::uint32_t>(near.size());
    }
    // aggregates: (1) a node whose near neighbours are all free, with them; (2) a node left joins the
    // aggregate of its first near neighbour placed in (1); (3) what is still left, with its free near neighbours
    std::vector<std::uint32_t> aggregate(n, kFree);
    rooted.assign(n, 0);
    std::uint32_t count = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      if (aggregate[i] != kFree) continue;
      bool free = true;
      for (std::uint32_t k = nearStart[i]; k < nearStart[i + 1] && free; ++k) free = aggregate[near[k]] == kFree;
      if (!free) continue;
      aggregate[i] = count;
      rooted[i] = 1;
      for (std::uint32_t k = nearStart[i]; k < nearStart[i + 1]; ++k) {
        aggregate[near[k]] = count;
        rooted[near[k]] = 1;
      }
      ++count;
    }
    for (std::uint32_t i = 0; i < n; ++i) {
      if (aggregate[i] != kFree) continue;
      for (std::uint32_t k = nearStart[i]; k < nearStart[i + 1]; ++k)
        if (rooted[near[k]]) {
          aggregate[i] = aggregate[near[k]];
          break;
        }
    }
    for (std::uint32_t i = 0; i < n; ++i) {
      if (aggregate[i] != kFree) continue;
      aggregate[i] = count;
      for (std::uint32_t k = nearStart[i]; k < nearStart[i + 1]; ++k)
        if (aggregate[near[k]] == kFree) aggregate[near[k]] = count;
      ++count;
    }
    if (count == n) return false;  // no node has a neighbour: nothing to coarsen
    // members of each aggregate, in node order, and the aggregates' centres
    memberStart.assign(count + 1, 0);
    for (std::uint32_t i = 0; i < n; ++i) ++memberStart[aggregate[i] + 1];
    for (std::uint32_t c = 0; c < count; ++c) memberStart[c + 1] += memberStart[c];
    members.resize(n);
    {
      std::vector<std::uint32_t> fill(memberStart.begin(), memberStart.end() - 1);
      for (std::uint32_t i = 0; i < n; ++i) members[fill[aggregate[i]]++] = i;
    }
    centres.assign(count, Vec3::Zero());
    for (std::uint32_t c = 0; c < count; ++c) {
      for (std::uint32_t m = memberStart[c]; m < memberStart[c + 1]; ++m) centres[c] += at[members[m]];
      centres[c] /= static_cast<double>(memberStart[c + 1] - memberStart[c]);
    }
    Level level;
    level.offset.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) level.offset[i] = at[i] - centres[aggregate[i]];
    // the coarse pattern: aggregates joined by a block of this level
    mark.assign(count, kFree);
    neighbourStart.assign(count + 1, 0);
    neighbours.clear();
    for (std::uint32_t c = 0; c < count; ++c) {
      const std::size_t first = neighbours.size();
      for (std::uint32_t m = memberStart[c]; m < memberStart[c + 1]; ++m) {
        const std::uint32_t i = members[m];
        for (std::uint32_t k = a.start[i]; k < a.start[i + 1]; ++k) {
          const std::uint32_t d = aggregate[a.column[k]];
          if (d == c || mark[d] == c) continue;
          mark[d] = c;
          neighbours.push_back(d);
        }
      }
      std::sort(neighbours.begin() + static_cast<std::ptrdiff_t>(first), neighbours.end());
      neighbourStart[c + 1] = static_cast<std::uint32_t>(neighbours.size());
    }
    level.coarse.setPattern(neighbourStart, neighbours);
    // the Galerkin product, block by block
    for (std::uint32_t i = 0; i < n; ++i) {
      const Block6 pi = prolongation(level.offset[i]);
      const std::uint32_t ci = aggregate[i];
      for (std::uint32_t k = a.start[i]; k < a.start[i + 1]; ++k) {
        const std::uint32_t j = a.column[k];
        level.coarse.block[level.coarse.find(ci, aggregate[j])].noalias() += pi.transpose() * a.entry(i, k) * prolongation(level.offset[j]);
      }
    }
    level.memberStart = memberStart;
    level.members = members;
    level.aggregate = std::move(aggregate);
    level.diagonalInverse.resize(n);
    level.sweepRows = std::max<std::size_t>(kRowsPerWorker, (n + kSweepChunks - 1) / kSweepChunks);
    if (level.sweepRows < n) level.before.resize(6 * static_cast<Eigen::Index>(n));
    level.residual.resize(6 * static_cast<Eigen::Index>(n));
    level.coarseRhs.resize(6 * static_cast<Eigen::Index>(count));
    level.coarseSolution.resize(6 * static_cast<Eigen::Index>(count));
    if (!levels_.empty())  // (the finest level takes no K-cycle steps)
      for (Eigen::VectorXd* v : {&level.krylov.c, &level.krylov.v, &level.krylov.r, &level.krylov.d, &level.krylov.w})
        v->resize(6 * static_cast<Eigen::Index>(n));
    levels_.push_back(std::move(level));
    for (std::uint32_t i = 0; i < n; ++i)
      levels_.back().diagonalInverse[i] = a.entry(i, a.diagonal[i]).ldlt().solve(Block6::Identity());
    at.swap(centres);
  }
  return true;
}

void FrameMultigrid::refreshDiagonalInverse(std::size_t level, const FrameStiffness& fine, std::uint32_t node) {
  levels_[level].diagonalInverse[node] = diagonalOf(level, fine, node).ldlt().solve(Block6::Identity());
}

void FrameMultigrid::change(const FrameStiffness& fine, std::uint32_t i, std::uint32_t j, const Block6& delta) {
  Block6 d = delta;
  for (std::size_t l = 0; l < levels_.size(); ++l) {
    Level& level = levels_[l];
    if (i == j) refreshDiagonalInverse(l, fine, i);
    const std::uint32_t ci = level.aggregate[i], cj = level.aggregate[j];
    Block6 dc = prolongation(level.offset[i]).transpose() * d * prolongation(level.offset[j]);
    if (ci == cj) {
      if (i != j) dc += dc.transpose().eval();
      level.coarse.block[level.coarse.diagonal[ci]] += dc;
    } else {
      level.coarse.block[level.coarse.find(ci, cj)] += dc;
      level.coarse.block[level.coarse.find(cj, ci)] += dc.transpose();
    }
    i = ci;
    j = cj;
    d = dc;
  }
  coarsestStale_ = true;
}

template <class Matrix>
void FrameMultigrid::factorise(const Matrix& a) {
  const auto n = static_cast<Eigen::Index>(a.rows());
  coarsestDense_.setZero(6 * n, 6 * n);
  for (Eigen::Index i = 0; i < n; ++i)
    for (std::uint32_t k = a.start[static_cast<std::size_t>(i)]; k < a.start[static_cast<std::size_t>(i) + 1]; ++k)
      coarsestDense_.block<6, 6>(6 * i, 6 * static_cast<Eigen::Index>(a.column[k])) = a.entry(static_cast<std::uint32_t>(i), k);
  coarsestLdlt_.compute(coarsestDense_);
  coarsestStale_ = false;
}

void FrameMultigrid::apply(const FrameStiffness& fine, const Eigen::VectorXd& r, Eigen::VectorXd& z, ThreadPool* pool) {
  if (coarsestStale_) {
    if (levels_.empty()) factorise(fine);
    else factorise(levels_.back().coarse);
  }
  pool_ = pool;
  cycle(0, fine, r, z);
  pool_ = nullptr;
}

void FrameMultigrid::coarseCorrection(std::size_t l, const BlockMatrix6& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  if (l == levels_.size()) {
    cycle(l, a, b, x);
    return;
  }
  // the K-cycle (Notay and Vassilevski 2008): up to two steps of flexible conjugate gradients on this level,
  // each preconditioned by this level's cycle; the second only where the first left more than a quarter of b
  Krylov& k = levels_[l].krylov;
  cycle(l, a, b, k.c);
  a.multiply(k.c, k.v, pool_);
  const double rho1 = chunkedDot(k.c, k.v, pool_, partial_), alpha1 = chunkedDot(k.c, b, pool_, partial_);
  if (!(rho1 > 0.0)) {
    x = k.c;
    return;
  }
  k.r = b - (alpha1 / rho1) * k.v;
  if (chunkedDot(k.r, k.r, pool_, partial_) <= 0.0625 * chunkedDot(b, b, pool_, partial_)) {
    x = (alpha1 / rho1) * k.c;
    return;
  }
  cycle(l, a, k.r, k.d);
  a.multiply(k.d, k.w, pool_);
  const double gamma = chunkedDot(k.d, k.v, pool_, partial_), beta = chunkedDot(k.d, k.w, pool_, partial_),
               alpha2 = chunkedDot(k.d, k.r, pool_, partial_);
  const double rho2 = beta - gamma * gamma / rho1;
  if (!(rho2 > 0.0)) {
    x = (alpha1 / rho1) * k.c;
    return;
  }
  x = (alpha1 / rho1 - gamma * alpha2 / (rho1 * rho2)) * k.c + (alpha2 / rho2) * k.d;
}

template <class Matrix>
void FrameMultigrid::cycle(std::size_t l, const Matrix& a, const Eigen::VectorXd& r, Eigen::VectorXd& z) {
  if (l == levels_.size()) {
    z = coarsestLdlt_.solve(r);
    return;
  }
  Level& level = levels_[l];
  const auto n = static_cast<std::uint32_t>(a.rows());
  const auto rows = static_cast<std::uint32_t>(level.sweepRows);
  const std::size_t chunks = (n + rows - 1) / rows;
  // the forward sweep from zero, chunk by chunk (sweepRows nodes each), in node order within a chunk:
  // z_i = D_i^-1 (r_i - sum_{chunk start <= j < i} A_ij z_j). The chunks are fixed by the level's size, not by
  // the threads, so the result is the same bits for any number; with one chunk it is Gauss-Seidel itself
  forChunks(pool_, chunks, [&](std::size_t c) {
    const auto lo = static_cast<std::uint32_t>(c) * rows, hi = std::min(n, lo + rows);
    for (std::uint32_t i = lo; i < hi; ++i) {
      Vec6 s = r.segment<6>(6 * static_cast<Eigen::Index>(i));
      std::uint32_t k = a.start[i];
      while (k < a.diagonal[i] && a.column[k] < lo) ++k;
      for (; k < a.diagonal[i]; ++k) a.subtractProduct(k, z.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      z.segment<6>(6 * static_cast<Eigen::Index>(i)) = level.diagonalInverse[i] * s;
    }
  });
  // its residual r - A z: what is left of each row is - sum A_ij z_j over the j the sweep left out (those
  // after i, and those before its chunk)
  forRows(pool_, n, [&](std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i) {
      const std::uint32_t lo = static_cast<std::uint32_t>(i) / rows * rows;
      Vec6 s = Vec6::Zero();
      for (std::uint32_t k = a.start[i]; k < a.diagonal[i] && a.column[k] < lo; ++k) a.subtractProduct(k, z.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      for (std::uint32_t k = a.diagonal[i] + 1; k < a.start[i + 1]; ++k) a.subtractProduct(k, z.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      level.residual.segment<6>(6 * static_cast<Eigen::Index>(i)) = s;
    }
  });
  // restriction: each aggregate's force and moment about its centre, its members in node order
  forRows(pool_, level.memberStart.size() - 1, [&](std::size_t from, std::size_t to) {
    for (std::size_t c = from; c < to; ++c) {
      Vec6 sum = Vec6::Zero();
      for (std::uint32_t m = level.memberStart[c]; m < level.memberStart[c + 1]; ++m) {
        const std::uint32_t i = level.members[m];
        const Vec3 f = level.residual.segment<3>(6 * static_cast<Eigen::Index>(i));
        sum.head<3>() += f;
        sum.tail<3>() += level.residual.segment<3>(6 * static_cast<Eigen::Index>(i) + 3) + level.offset[i].cross(f);
      }
      level.coarseRhs.segment<6>(6 * static_cast<Eigen::Index>(c)) = sum;
    }
  });
  coarseCorrection(l + 1, level.coarse, level.coarseRhs, level.coarseSolution);
  // prolongation: each node moves with its aggregate's rigid motion
  forRows(pool_, n, [&](std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i) {
      const auto c = 6 * static_cast<Eigen::Index>(level.aggregate[i]);
      const Vec3 turn = level.coarseSolution.segment<3>(c + 3);
      z.segment<3>(6 * static_cast<Eigen::Index>(i)) += level.coarseSolution.segment<3>(c) + turn.cross(level.offset[i]);
      z.segment<3>(6 * static_cast<Eigen::Index>(i) + 3) += turn;
    }
  });
  // the backward sweep, the forward one's transpose: z_i = D_i^-1 (r_i - sum_{j != i} A_ij z_j) in reverse
  // node order within each chunk, the other chunks' z as they were before it (`before`)
  if (chunks > 1) level.before = z;
  forChunks(pool_, chunks, [&](std::size_t c) {
    const auto lo = static_cast<std::uint32_t>(c) * rows, hi = std::min(n, lo + rows);
    for (std::uint32_t i = hi; i-- > lo;) {
      // (columns sorted: those of other chunks first and last, this chunk's between)
      const std::uint32_t first = a.start[i], last = a.start[i + 1];
      std::uint32_t inside = first, after = last;
      while (inside < last && a.column[inside] < lo) ++inside;
      while (after > inside && a.column[after - 1] >= hi) --after;
      Vec6 s = r.segment<6>(6 * static_cast<Eigen::Index>(i));
      for (std::uint32_t k = first; k < inside; ++k) a.subtractProduct(k, level.before.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      for (std::uint32_t k = inside; k < a.diagonal[i]; ++k) a.subtractProduct(k, z.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      for (std::uint32_t k = a.diagonal[i] + 1; k < after; ++k) a.subtractProduct(k, z.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      for (std::uint32_t k = after; k < last; ++k) a.subtractProduct(k, level.before.data() + 6 * static_cast<std::size_t>(a.column[k]), s);
      z.segment<6>(6 * static_cast<Eigen::Index>(i)) = level.diagonalInverse[i] * s;
    }
  });
}

std::size_t FrameMultigrid::bytes() const {
  std::size_t b = static_cast<std::size_t>(coarsestDense_.size()) * sizeof(double) * 2;
  for (const Level& l : levels_)
    b += l.aggregate.size() * 4 + l.offset.size() * sizeof(Vec3) + l.diagonalInverse.size() * sizeof(Block6) +
         l.coarse.block.size() * sizeof(Block6) + l.coarse.column.size() * 4 + l.coarse.start.size() * 4 +
         l.coarse.diagonal.size() * 4 + (l.memberStart.size() + l.members.size()) * 4 +
         static_cast<std::size_t>(l.residual.size() + l.coarseRhs.size() + l.coarseSolution.size() + l.before.size() + l.krylov.c.size() +
                                  l.krylov.v.size() + l.krylov.r.size() + l.krylov.d.size() + l.krylov.w.size()) * 8;
  return b;
}

}  // namespace volpar
