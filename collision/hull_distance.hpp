#pragma once
// Closest points of the convex hulls of two small point sets: the Gilbert-Johnson-Keerthi algorithm
// (Gilbert, Johnson and Keerthi 1988) on the Minkowski difference B - A, with the closest point of each
// simplex found by region tests (Ericson, Real-Time Collision Detection, 5.1.2-5.1.6).
//
// The separating-plane narrow phase uses it on the particle centres local to a contact: when the hulls
// are apart, the direction from A's closest point to B's is the plane normal across which those particles
// are farthest apart (the largest-margin plane of the paper's choice, found over all directions instead of
// a list of candidates), and the simplex says which particles carry the closest features (a vertex, an
// edge or a face of each hull). Particle lattices are full of collinear and coplanar points; degenerate
// simplices are reduced to their best lower-dimensional face instead of being divided by zero. Ties in the
// support function go to the lowest index, so the result depends only on the input order.

#include <array>
#include <cstdint>
#include <span>

#include "volpar/engine/core/types.hpp"

namespace volpar {

struct HullDistance {
  bool separated = false;     ///< the hulls are apart (distance > 0)
  double distance = 0.0;      ///< between the hulls [m]; 0 when they touch or overlap
  Vec3 direction = Vec3::Zero();  ///< unit, from A's closest point towards B's (when separated)
  Vec3 pointA = Vec3::Zero();     ///< the closest points [m]
  Vec3 pointB = Vec3::Zero();
  /// The final simplex: `count` vertices, each a pair of input indices (A, B) with its barycentric weight;
  /// pointA = sum weight[k] a[indexA[k]], likewise B.
  std::array<std::uint32_t, 4> indexA{}, indexB{};
  std::array<double, 4> weight{};
  int count = 0;
  int iterations = 0;
};

/// Closest points of hull(a) and hull(b); both sets non-empty.
[[nodiscard]] HullDistance hullDistance(std::span<const Vec3> a, std::span<const Vec3> b);

}  // namespace volpar
