#pragma once

#include "volpar/engine/core/ids.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// A static half-space: points x with normal . x <= offset are solid.
struct Plane {
  Vec3 normal = Vec3::UnitZ();  ///< unit outward normal (world)
  double offset = 0.0;          ///< [m]
  MaterialId material;
};

}  // namespace volpar
