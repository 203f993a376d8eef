#include "volpar/dynamics/frame_stiffness.hpp"

namespace volpar {

void FrameStiffness::setPattern(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours) {
  setRows(neighbourStart, neighbours);
  coupling.assign(column.size(), BeamCoupling{});
  diagonalBlock.assign(rows(), Block6::Zero());
}

void FrameStiffness::addCoupling(std::uint32_t a, std::uint32_t b, const Vec3& e, double length, double axial,
                                 double torsion, double bending, double sign) {
  const double shear = 12.0 * bending / (length * length);  // 12 EI/L^3
  const auto add = [&](BeamCoupling& c, const Vec3& direction) {
    c.e = direction;
    c.move -= sign * shear;
    c.stretch += sign * (shear - axial);
    c.turn += sign * 2.0 * bending;
    c.twist -= sign * (torsion + 2.0 * bending);
  };
  BeamCoupling& ab = coupling[find(a, b)];
  BeamCoupling& ba = coupling[find(b, a)];
  add(ab, e);
  add(ba, -e);
  // e x theta from a's side, (-e) x theta from b's: the same coefficient, -6 EI/L^2, on the direction each sees
  ab.couple -= sign * 6.0 * bending / length;
  ba.couple -= sign * 6.0 * bending / length;
}

Block6 FrameStiffness::entry(std::uint32_t i, std::uint32_t k) const {
  if (k == diagonal[i]) return diagonalBlock[i];
  const BeamCoupling& c = coupling[k];
  Block6 m;
  const Mat3 along = c.e * c.e.transpose(), across = c.couple * skew(c.e);
  m.block<3, 3>(0, 0) = c.move * Mat3::Identity() + c.stretch * along;
  m.block<3, 3>(0, 3) = across;
  m.block<3, 3>(3, 0) = across;
  m.block<3, 3>(3, 3) = c.turn * Mat3::Identity() + c.twist * along;
  return m;
}

void FrameStiffness::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, ThreadPool* pool) const {
  const auto rowsOf = [&](std::size_t from, std::size_t to) {
    // (s is -y until the row's end: the entries' products subtract)
    for (std::size_t i = from; i < to; ++i) {
      Vec6 s = -(diagonalBlock[i] * x.segment<6>(6 * static_cast<Eigen::Index>(i)));
      for (std::uint32_t k = start[i]; k < diagonal[i]; ++k) subtractProduct(k, x.data() + 6 * column[k], s);
      for (std::uint32_t k = diagonal[i] + 1; k < start[i + 1]; ++k) subtractProduct(k, x.data() + 6 * column[k], s);
      y.segment<6>(6 * static_cast<Eigen::Index>(i)) = -s;
    }
  };
  if (pool && pool->worthSharing(rows(), kRowsPerWorker)) pool->run(rows(), [&](int, std::size_t b, std::size_t e) { rowsOf(b, e); });
  else rowsOf(0, rows());
}

std::size_t FrameStiffness::bytes() const {
  return (start.size() + column.size() + diagonal.size()) * 4 + coupling.size() * sizeof(BeamCoupling) +
         diagonalBlock.size() * sizeof(Block6);
}

}  // namespace volpar
