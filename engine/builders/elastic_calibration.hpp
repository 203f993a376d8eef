#pragma once
// Spring stiffnesses from a material's Young's modulus and Poisson's ratio (deformable bodies given by
// modulus, docs/fracture.md#materials-by-modulus).
//
// A lattice of central springs is an elastic solid whose constants are C_ijkl = (1 / 2V) sum_b k_b L_b^2
// e_i e_j e_k e_l over one particle's springs b (V the volume a particle stands for). volpar gives the
// nearest neighbours one stiffness and the farther ones within the connector reach another, chooses their
// ratio for the Poisson's ratio asked for (a lattice of central springs reaches only part of the range:
// cubic with face diagonals 0 to 1/3; the nearest reachable value is taken) and their scale for the
// Young's modulus along the lattice's x axis (the shape frame's x; the cubic lattice is a cubic crystal, so
// the modulus along its axes).
//
// A particle near the surface misses springs, and the body would be softer there than the solid it stands
// for (a bar 6 particles across by 12 % along its length, 29 % in bending). Each particle's springs are
// weighed as in peridynamics' energy correction (Madenci and Oterkus 2014): its strain energy under a unit
// stretch along each axis is compared with a bulk particle's, and each spring's stiffness is scaled by the
// ratio of its two particles, interpolated over its direction; the test state is a unit uniaxial stress
// (a stretch along the axis and Poisson's contraction across it), the state of a bar's or a beam's fibres.
// Where the particles stand for more volume than a lattice cell (HCP fills a box only where whole
// particles fit, and each particle has its share of the box's mass), the springs are stiffer in proportion,
// so that the particles carry the solid's load at its modulus and waves run at sqrt(E / rho).

#include <span>
#include <vector>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/particle_cloud.hpp"

namespace volpar {

/// The bulk lattice's springs for a material.
struct SpringCalibration {
  double nearest = 0.0;       ///< stiffness of the springs to the nearest neighbours [N/m]
  double farther = 0.0;       ///< of the springs to the farther ones within reach [N/m]
  double poissonRatio = 0.0;  ///< the lattice's (the one asked for, or the nearest it reaches) [-]
  double youngsModulus = 0.0; ///< along x [Pa]
};

/// Calibrates the springs of `lattice` with nearest-neighbour distance `spacing` [m], joined within
/// `reach` x spacing, for Young's modulus `modulus` [Pa] and Poisson's ratio `poisson`.
[[nodiscard]] SpringCalibration calibrateSprings(Lattice lattice, double spacing, double reach, double modulus,
                                                 double poisson);

/// The stiffness of each of `cloud`'s connectors [N/m]: the calibration's, corrected near the surface.
[[nodiscard]] std::vector<double> calibratedStiffness(const ParticleCloud& cloud, const SpringCalibration& springs,
                                                      Lattice lattice, double spacing, double reach);

}  // namespace volpar
