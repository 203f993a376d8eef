#pragma once
// A multigrid preconditioner for the stiffness of a frame whose nodes each have three displacements and three
// rotations (a bonded body's frame of beams, bond_loads.hpp).
//
// Aggregation multigrid (Vanek, Mandel and Brezina 1996, without smoothing of the prolongation): the nodes of
// a level are gathered into aggregates (a node and its free neighbours, greedily in node order), each
// aggregate is one node of the next level at the mean of its members' positions, and a coarse node's six
// freedoms are the aggregate's rigid motion: a member at offset d from the centre moves by U + Theta x d and
// turns by Theta. The coarse stiffness is the Galerkin product P^T K P, so the rigid motions of the whole
// body, which a frame's stiffness barely resists, are represented exactly on every level. The coarsest
// level (at most kCoarsest nodes) is solved directly. A cycle smooths with one symmetric block Gauss-Seidel
// sweep (forward before the coarse correction, backward after) in node order within chunks of a level's
// nodes: up to kSweepChunks chunks of at least kRowsPerWorker nodes, fixed by the level's size, each swept
// on its own (the backward sweep reads the other chunks' values from before it), so that the threads share
// the sweeps and the result is the same bits for any number of them (a level of one chunk is swept by
// Gauss-Seidel itself); the products, restrictions, prolongations and sums around them are shared too.
// Each coarse level is solved by up to two steps of flexible conjugate gradients
// preconditioned by its own cycle (the K-cycle of Notay and Vassilevski, 2008), which keeps the iterations
// of the outer (flexible) conjugate gradients from growing with the number of levels. The preconditioner is
// then not exactly linear, so the outer method must be flexible (BondLoads::solve).
//
// When a beam leaves the frame, its stiffness leaves each level's matrix in place: with one coarse node per
// fine node, the change of a fine block (a, b) changes only the coarse block (A, B) of the nodes' aggregates,
// so removing k beams costs O(k times the levels), not a rebuild. The aggregates stay as they were built;
// where a crack runs through one, the coarse space couples the two sides more than the frame does, which
// slows convergence a little there and changes no result (the preconditioner stays symmetric and positive
// definite).
//
// Costs: building is linear in the blocks of the fine matrix (each level has about a tenth of the nodes of
// the one below it in a three-dimensional lattice); one cycle costs about two products with the fine matrix
// and, with its K-cycle steps, about as much again on the coarse levels.

#include <cstdint>
#include <vector>

#include <Eigen/Dense>

#include "volpar/dynamics/frame_stiffness.hpp"
#include "volpar/engine/core/thread_pool.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// A symmetric matrix of 6 x 6 blocks in compressed rows; every row holds its diagonal block, columns sorted.
struct BlockMatrix6 : BlockPattern {
  std::vector<Block6> block;  // per entry

  /// Entry k of row i.
  [[nodiscard]] const Block6& entry(std::uint32_t /*i*/, std::uint32_t k) const { return block[k]; }
  /// s -= (entry k) x, x the six entries of its column's node (inlined: the products over a row's blocks are
  /// most of a cycle's work, and a call per block costs as much as the product).
  [[gnu::always_inline]] void subtractProduct(std::uint32_t k, const double* x, Vec6& s) const {
    for (int j = 0; j < 6; ++j) s -= block[k].col(j) * x[j];
  }
  /// y = A x (6 entries a row), the rows shared among `pool`'s workers where it is given.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool = nullptr) const;
  /// The pattern of rows whose off-diagonal columns are `neighbours` (CSR: neighbourStart, sorted, no
  /// duplicates, no diagonal), every block zero.
  void setPattern(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours);
};

/// a . b summed in chunks of kDotChunk entries, the chunks' sums added in order: the same bits for any number
/// of threads (`pool`, where given, shares the chunks). `partial` is scratch.
inline constexpr std::size_t kDotChunk = 3072;
double chunkedDot(const Eigen::VectorXd& a, const Eigen::VectorXd& b, ThreadPool* pool, std::vector<double>& partial);

class FrameMultigrid {
 public:
  /// The hierarchy of `fine` (a frame's stiffness, kept by the caller, which tells of every change through
  /// change()), whose nodes lie at `positions`.
  void build(const FrameStiffness& fine, const std::vector<Vec3>& positions);
  /// Tells the hierarchy that block (i, j) of the fine matrix changed by `delta` (and block (j, i) by its
  /// transpose, where i != j): the coarse levels change with it.
  void change(const FrameStiffness& fine, std::uint32_t i, std::uint32_t j, const Block6& delta);
  /// z = B r, B the cycle: an approximation of the fine matrix's inverse. `pool`, where given, shares the
  /// work of each level of more than kRowsPerWorker rows a worker; z is the same bits for any number of threads.
  void apply(const FrameStiffness& fine, const Eigen::VectorXd& r, Eigen::VectorXd& z, ThreadPool* pool = nullptr);

  [[nodiscard]] std::size_t levels() const { return levels_.size() + 1; }
  /// The inverse of the fine matrix's diagonal block of `node` (the smoother's); only where levels() > 1.
  [[nodiscard]] const Block6& fineDiagonalInverse(std::uint32_t node) const { return levels_[0].diagonalInverse[node]; }
  /// Bytes the hierarchy holds (its coarse matrices and aggregates).
  [[nodiscard]] std::size_t bytes() const;

  static constexpr std::size_t kCoarsest = 32;        // nodes of a level solved directly
  static constexpr std::size_t kRowsPerWorker = 1024;  // rows worth handing to a worker
  static constexpr std::size_t kSweepChunks = 8;       // chunks a level's sweeps are cut into, at most

 private:
  /// The vectors of a K-cycle's steps on one level.
  struct Krylov {
    Eigen::VectorXd c, v, r, d, w;
  };
  /// One level below the coarsest: its nodes' aggregates, their offsets, and the next level's matrix.
  struct Level {
    std::vector<std::uint32_t> aggregate;   // node -> node of the next level
    std::vector<Vec3> offset;               // node's position less its aggregate's centre
    std::vector<Block6> diagonalInverse;    // of this level's diagonal blocks (the smoother's)
    std::vector<std::uint32_t> memberStart, members;     // the nodes of each aggregate, in node order
    BlockMatrix6 coarse;                    // the next level's matrix (unused below the coarsest: coarsest_)
    std::size_t sweepRows = 0;              // nodes of a chunk of the sweeps
    Eigen::VectorXd residual, coarseRhs, coarseSolution;
    Eigen::VectorXd before;                 // z before the backward sweep (where there is more than one chunk)
    Krylov krylov;  // (levels above the finest: the K-cycle's steps on this level)
  };
  /// Adds the level below `a` (the fine matrix or the last coarse one, its nodes at `at`, which become the
  /// next level's): false where there is nothing to coarsen.
  template <class Matrix>
  bool coarsen(const Matrix& a, std::vector<Vec3>& at);
  /// z = the cycle of `level` on r: smoothing, the coarse correction, smoothing (the direct solve, at the coarsest).
  template <class Matrix>
  void cycle(std::size_t level, const Matrix& a, const Eigen::VectorXd& r, Eigen::VectorXd& z);
  /// x = an approximate solution of level `level`'s a x = b: the K-cycle (or the direct solve, at the coarsest).
  void coarseCorrection(std::size_t level, const BlockMatrix6& a, const Eigen::VectorXd& b, Eigen::VectorXd& x);
  /// The diagonal block of `node` on level `level`.
  [[nodiscard]] const Block6& diagonalOf(std::size_t level, const FrameStiffness& fine, std::uint32_t node) const {
    if (level == 0) return fine.diagonalBlock[node];
    const BlockMatrix6& a = levels_[level - 1].coarse;
    return a.block[a.diagonal[node]];
  }
  void refreshDiagonalInverse(std::size_t level, const FrameStiffness& fine, std::uint32_t node);
  template <class Matrix>
  void factorise(const Matrix& coarsest);

  std::vector<Level> levels_;  // levels_[l] smooths on level l's matrix and restricts to level l + 1
  Eigen::MatrixXd coarsestDense_;
  Eigen::LDLT<Eigen::MatrixXd> coarsestLdlt_;
  bool coarsestStale_ = true;
  ThreadPool* pool_ = nullptr;  // (during apply())
  std::vector<double> partial_;  // chunkedDot's scratch
};

}  // namespace volpar
