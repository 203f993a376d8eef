#pragma once
// The stiffness of a frame of beams (bond_loads.hpp), kept as the beams' numbers rather than as blocks.
//
// K is symmetric, of 6 x 6 blocks in compressed rows (columns sorted, every row holding its diagonal). A row's
// diagonal block is stored whole; an off-diagonal block (i, j), the coupling of the node pair's beams, is stored
// as the eight numbers it is made of: the unit vector e from node i to node j and five coefficients, its
// product with (u_j, theta_j) being
//   force  = move u_j + stretch (e . u_j) e + couple e x theta_j
//   moment = turn theta_j + twist (e . theta_j) e + couple e x u_j
// For one Euler-Bernoulli beam (axial EA/L, torsion GJ/L, bending EI/L, length L):
//   move = -12 EI/L^3, stretch = -EA/L + 12 EI/L^3, couple = -6 EI/L^2, turn = 2 EI/L, twist = -GJ/L - 2 EI/L;
// beams between the same two nodes share e, so their coefficients add. 64 bytes an off-diagonal block instead
// of 288: the products that are most of the frame's solve (bond_loads.hpp, frame_multigrid.hpp) read a quarter
// of the memory, which is what bounds them. Costs: a product is O(the blocks); adding or removing a beam O(1)
// once the pattern is set (setPattern, O(the blocks)).

#include <cstdint>
#include <vector>

#include <Eigen/Dense>

#include "volpar/dynamics/block_pattern.hpp"
#include "volpar/engine/core/thread_pool.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

using Block6 = Eigen::Matrix<double, 6, 6>;
using Vec6 = Eigen::Matrix<double, 6, 1>;

/// The coupling of the beams between two nodes, seen from the row's node (see the file's comment).
struct BeamCoupling {
  Vec3 e = Vec3::Zero();  // unit, from the row's node to the column's
  double move = 0.0, stretch = 0.0, couple = 0.0, turn = 0.0, twist = 0.0;
};

class FrameStiffness : public BlockPattern {
 public:
  std::vector<BeamCoupling> coupling;   // per entry (zero at the diagonal entries)
  std::vector<Block6> diagonalBlock;    // per row

  /// The pattern of rows whose off-diagonal columns are `neighbours` (CSR: neighbourStart, sorted, no
  /// duplicates, no diagonal), every block zero.
  void setPattern(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours);
  /// Adds `sign` (1 to add, -1 to remove) times a beam from node a to node b (unit direction e, length, and its
  /// axial EA/L, torsion GJ/L and bending EI/L stiffnesses) to the off-diagonal entries (a, b) and (b, a); the
  /// diagonal blocks are the caller's (`diagonalBlock`).
  void addCoupling(std::uint32_t a, std::uint32_t b, const Vec3& e, double length, double axial, double torsion,
                   double bending, double sign);
  /// Entry k of row i as a block.
  [[nodiscard]] Block6 entry(std::uint32_t i, std::uint32_t k) const;
  /// s -= (off-diagonal entry k) x, x the six entries of its column's node.
  [[gnu::always_inline]] void subtractProduct(std::uint32_t k, const double* x, Vec6& s) const {
    const BeamCoupling& c = coupling[k];
    const Vec3 u(x[0], x[1], x[2]), t(x[3], x[4], x[5]);
    s.head<3>() -= c.move * u + (c.stretch * c.e.dot(u)) * c.e + c.couple * c.e.cross(t);
    s.tail<3>() -= c.turn * t + (c.twist * c.e.dot(t)) * c.e + c.couple * c.e.cross(u);
  }
  /// y = K x (6 entries a row), the rows shared among `pool`'s workers where it is given.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool = nullptr) const;
  /// Bytes it holds.
  [[nodiscard]] std::size_t bytes() const;

  static constexpr std::size_t kRowsPerWorker = 1024;  // rows worth handing to a worker
};

}  // namespace volpar
