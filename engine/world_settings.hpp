#pragma once

#include <cstdint>

#include "volpar/collision/separating_plane.hpp"
#include "volpar/dynamics/contact_solver.hpp"
#include "volpar/engine/core/plane.hpp"
#include "volpar/engine/core/types.hpp"

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
  SolverSettings solver;                     ///< the contact solver (solver.iterations: the scene's)
  /// Use each particle pair's centre-line normal instead of its patch's separating plane (for comparison).
  bool rawNormals = false;
  /// Penetration left uncorrected, as a fraction of the sum of the two particles' radii [-] (against a
  /// plane, of the particle's radius). Position correction pushes overlapping bodies apart down to this
  /// overlap and no further (bodies that come to rest gently may touch less deeply); what the solver's
  /// iterations leave under a deep stack comes on top (docs/benchmarks.md: 0.75 % keeps pile-8000's
  /// deepest overlap under 1 mm at 5 cm radii).
  double slop = 0.0075;
  /// Speculative contact reach, as a fraction of the sum of the two particles' radii [-]: pairs this close
  /// to touching are contacts with a negative depth (gap) that the solver lets close but not overlap. 0.25
  /// covers a particle riding over the hollow between four others of a lattice of touching particles
  /// (sqrt(1 + 1/2) = 1.2247), so a face sliding over a face never loses its contacts.
  double contactMargin = 0.25;
  /// Of the speculative contacts, those the solver takes [-]: a gap below this fraction of r_a + r_b, or
  /// one the pair's approach speed closes within the step. A farther gap could only close if the solver
  /// itself drove the pair together faster than this distance per step, and its point is left out.
  double speculativeDistance = 0.0;
  /// A rigid patch of more than four contacts goes to the solver as a manifold of four points (the deepest,
  /// the farthest from it, ...: docs/architecture.md). Where a choice's best contact was not a point in the
  /// last step, the best one that was is taken instead if its depth is within manifoldDepthTies x (r_a +
  /// r_b) of the deepest's (the first choice; against a plane, x r_a), or its score within the fraction
  /// manifoldScoreTies of the best (the others). A resting face's contacts are all about as deep: without
  /// this its points change from step to step, their warm start is lost, and the load they carried is
  /// rebuilt from nothing by the iterations, so that a deep pile creeps and never comes to rest.
  double manifoldDepthTies = 5e-4;
  double manifoldScoreTies = 0.05;
  /// A deformable body's normals follow its shape: around a connector that has stretched by this strain [-]
  /// or turned (relative to the body's best-fit rotation) by more than normalTurnThreshold [rad] since its
  /// particles' normals were last estimated, they are estimated again.
  double normalStrainThreshold = 0.05;
  double normalTurnThreshold = 0.035;
  /// Seeds what is drawn at random when bodies are made (bond strengths with a Weibull modulus): the same
  /// seed gives the same draws.
  std::uint64_t seed = 0;
  /// Worker threads for the step (1 = none). The results do not depend on it: bit for bit the same.
  int threads = 1;
};

}  // namespace volpar
