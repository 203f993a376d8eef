#pragma once
// Basic numeric types. Units are SI throughout; scalars are double.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace volpar {

using Scalar = double;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;

/// Column-major view of a `std::vector<Vec3>`: the same bytes as an HDF5 `[P,3]` row-major array.
using Points = Eigen::Map<Eigen::Matrix3Xd>;
using ConstPoints = Eigen::Map<const Eigen::Matrix3Xd>;

/// Cross-product matrix: skew(a) * b == a.cross(b).
inline Mat3 skew(const Vec3& a) {
  Mat3 m;
  m << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return m;
}

}  // namespace volpar
