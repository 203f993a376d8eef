#include "volpar/engine/core/source_shape.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace volpar {

SourceShape fittedCore(const SourceShape& shape, std::span<const Vec3> centres) {
  SourceShape core = shape;
  if (!shape.isConvexSolid() || centres.empty()) return core;
  switch (shape.kind) {
    case SourceShape::Kind::Box: {
      Vec3 lo = centres.front(), hi = centres.front();
      for (const Vec3& x : centres) {
        lo = lo.cwiseMin(x);
        hi = hi.cwiseMax(x);
      }
      core.size = hi - lo;
      core.centre = 0.5 * (hi + lo);
      break;
    }
    case SourceShape::Kind::Sphere: {
      double r = 0.0;
      for (const Vec3& x : centres) r = std::max(r, x.norm());
      core.radius = r;
      break;
    }
    case SourceShape::Kind::Cylinder: {
      double r = 0.0, lo = centres.front().z(), hi = lo;
      for (const Vec3& x : centres) {
        r = std::max(r, std::hypot(x.x(), x.y()));
        lo = std::min(lo, x.z());
        hi = std::max(hi, x.z());
      }
      core.radius = r;
      core.length = hi - lo;
      core.centre = Vec3(0.0, 0.0, 0.5 * (hi + lo));
      break;
    }
    case SourceShape::Kind::Capsule: {
      double r = 0.0;
      const double half = 0.5 * shape.length;
      for (const Vec3& x : centres) r = std::max(r, (x - Vec3(0.0, 0.0, std::clamp(x.z(), -half, half))).norm());
      core.radius = r;
      break;
    }
    case SourceShape::Kind::Mesh:
      for (auto& [n, d] : core.facePlanes) {
        d = -std::numeric_limits<double>::infinity();
        for (const Vec3& x : centres) d = std::max(d, n.dot(x));
      }
      break;
    default: break;
  }
  return core;
}

}  // namespace volpar
