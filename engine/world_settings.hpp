#pragma once

#include "collision/separating_plane.hpp"
#include "engine/core/plane.hpp"
#include "engine/core/types.hpp"

namespace volpar {

/// Constant settings of a World.
struct WorldSettings {
  double dt = 1.0 / 240.0;                   ///< time step [s]
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);      ///< [m/s^2]
  int solverIterations = 10;                 ///< contact solver iterations per step
  int substeps = 4;                          ///< XPBD substeps per step for deformable bodies
  /// How far the broadphase's fat boxes reach beyond the bodies [m]; 0 = the largest particle radius.
  double broadphaseMargin = 0.0;
  PlaneSettings planes;                      ///< the separating-plane narrow phase
};

}  // namespace volpar
