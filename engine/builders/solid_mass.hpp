#pragma once
// The mass properties of a solid shape at unit density (shapes.hpp), which a body filled from it takes
// (world.hpp, MassModel).

#include "volpar/engine/core/types.hpp"

namespace volpar {

/// Volume [m^3], centroid [m] and inertia tensor about the centroid [m^5] (times the density: kg m^2) of a
/// solid of unit density, in its shape frame.
struct SolidMass {
  double volume = 0.0;
  Vec3 centroid = Vec3::Zero();
  Mat3 inertia = Mat3::Zero();
};

}  // namespace volpar
