#include "volpar/dynamics/mass_properties.hpp"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace volpar {

MassProperties computeMassProperties(std::span<const Vec3> positions, std::span<const double> masses,
                                     std::span<const double> ownMoments) {
  MassProperties mp;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    mp.mass += masses[i];
    mp.centre += masses[i] * positions[i];
  }
  if (mp.mass <= 0.0) return mp;
  mp.centre /= mp.mass;
  // own moments plus parallel-axis terms: I = sum (J_i 1 + m (|d|^2 1 - d d^T))
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Vec3 d = positions[i] - mp.centre;
    const double own = ownMoments[i];
    mp.inertia += (own + masses[i] * d.squaredNorm()) * Mat3::Identity() - masses[i] * d * d.transpose();
  }
  return mp;
}

PrincipalAxes principalAxes(const Mat3& inertia) {
  PrincipalAxes pa;
  const double scale = inertia.trace();
  const double off = std::max({std::abs(inertia(0, 1)), std::abs(inertia(0, 2)), std::abs(inertia(1, 2))});
  if (off <= 1e-12 * scale) {
    pa.moments = inertia.diagonal();
    return pa;
  }
  Eigen::SelfAdjointEigenSolver<Mat3> eig(inertia);
  Mat3 axes = eig.eigenvectors();
  // deterministic signs: the largest component of each axis positive, then make the frame right-handed
  for (int c = 0; c < 3; ++c) {
    Eigen::Index k = 0;
    axes.col(c).cwiseAbs().maxCoeff(&k);
    if (axes(k, c) < 0.0) axes.col(c) = -axes.col(c);
  }
  if (axes.determinant() < 0.0) axes.col(2) = -axes.col(2);
  pa.rotation = Quat(axes).normalized();
  pa.moments = eig.eigenvalues();
  return pa;
}

}  // namespace volpar
