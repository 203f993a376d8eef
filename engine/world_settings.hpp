#pragma once

#include "engine/core/ids.hpp"
#include "engine/core/types.hpp"

namespace volpar {

/// Constant settings of a World.
struct WorldSettings {
  double dt = 1.0 / 240.0;                   ///< time step [s]
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);      ///< [m/s^2]
  int solverIterations = 10;                 ///< contact solver iterations per step
  int substeps = 4;                          ///< XPBD substeps per step for deformable bodies
};

/// A static half-space: points x with normal . x <= offset are solid.
struct Plane {
  Vec3 normal = Vec3::UnitZ();  ///< unit outward normal (world)
  double offset = 0.0;          ///< [m]
  MaterialId material;
};

}  // namespace volpar
