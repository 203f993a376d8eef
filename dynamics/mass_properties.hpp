#pragma once
// Mass, centre of mass and inertia of a set of particles, each with its own moment of inertia about its
// centre (the volume it stands for: a lattice cell, or a solid sphere's 2/5 m r^2), moved to the body's
// centre by the parallel-axis theorem.

#include <span>

#include "volpar/engine/core/types.hpp"

namespace volpar {

struct MassProperties {
  double mass = 0.0;            ///< [kg]
  Vec3 centre = Vec3::Zero();   ///< centre of mass, in the frame of the input positions [m]
  Mat3 inertia = Mat3::Zero();  ///< about the centre of mass, in the input frame [kg m^2]
};

/// positions [P] in any frame [m], masses [P] [kg], ownMoments [P]: each particle's moment of inertia about
/// its centre [kg m^2] (isotropic).
[[nodiscard]] MassProperties computeMassProperties(std::span<const Vec3> positions, std::span<const double> masses,
                                                   std::span<const double> ownMoments);

/// The moment of inertia of a solid sphere about its centre, 2/5 m r^2 [kg m^2].
[[nodiscard]] inline double sphereMoment(double mass, double radius) { return 0.4 * mass * radius * radius; }

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
