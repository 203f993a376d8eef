#pragma once
// Axis-aligned bounding boxes. Overlap tests are inclusive: boxes that touch overlap.

#include <algorithm>
#include <limits>

#include "volpar/engine/core/types.hpp"

namespace volpar {

struct Aabb {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());   ///< [m]
  Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());  ///< [m]

  static Aabb sphere(const Vec3& c, double r) { return {c.array() - r, c.array() + r}; }

  [[nodiscard]] bool overlaps(const Aabb& o) const {
    return lo.x() <= o.hi.x() && o.lo.x() <= hi.x() && lo.y() <= o.hi.y() && o.lo.y() <= hi.y() &&
           lo.z() <= o.hi.z() && o.lo.z() <= hi.z();
  }
  [[nodiscard]] bool contains(const Aabb& o) const {
    return lo.x() <= o.lo.x() && lo.y() <= o.lo.y() && lo.z() <= o.lo.z() && o.hi.x() <= hi.x() &&
           o.hi.y() <= hi.y() && o.hi.z() <= hi.z();
  }
  [[nodiscard]] bool valid() const { return (lo.array() <= hi.array()).all(); }
  void extend(const Aabb& o) {
    lo = lo.cwiseMin(o.lo);
    hi = hi.cwiseMax(o.hi);
  }
  [[nodiscard]] Aabb merged(const Aabb& o) const { return {lo.cwiseMin(o.lo), hi.cwiseMax(o.hi)}; }
  [[nodiscard]] Aabb expanded(double margin) const { return {lo.array() - margin, hi.array() + margin}; }
  /// Surface area [m^2] (the SAH cost of a node).
  [[nodiscard]] double area() const {
    const Vec3 d = hi - lo;
    return 2.0 * (d.x() * d.y() + d.y() * d.z() + d.z() * d.x());
  }
  [[nodiscard]] Vec3 centre() const { return 0.5 * (lo + hi); }
};

}  // namespace volpar
