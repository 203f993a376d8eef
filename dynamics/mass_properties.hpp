#pragma once
// Mass, centre of mass and inertia of a set of particles, each a solid sphere
// (inertia 2/5 m r^2 about its centre) moved to the body's centre by the parallel-axis theorem.

#include <span>

#include "engine/core/types.hpp"

namespace volpar {

struct MassProperties {
  double mass = 0.0;            ///< [kg]
  Vec3 centre = Vec3::Zero();   ///< centre of mass, in the frame of the input positions [m]
  Mat3 inertia = Mat3::Zero();  ///< about the centre of mass, in the input frame [kg m^2]
};

/// positions [P] in any frame [m], radii [P] [m], masses [P] [kg].
[[nodiscard]] MassProperties computeMassProperties(std::span<const Vec3> positions, std::span<const double> radii,
                                                   std::span<const double> masses);

/// Principal axes of an inertia tensor.
struct PrincipalAxes {
  Quat rotation = Quat::Identity();  ///< principal-frame -> input-frame coordinates
  Vec3 moments = Vec3::Zero();       ///< principal moments [kg m^2]
};

/// Diagonalises `inertia`. When it is already diagonal (to 1e-12 of its trace) the axes stay those of
/// the input frame, so boxes, spheres and cylinders keep their shape axes as their body axes.
/// Otherwise the rotation is proper (det +1) and deterministic.
[[nodiscard]] PrincipalAxes principalAxes(const Mat3& inertia);

}  // namespace volpar
