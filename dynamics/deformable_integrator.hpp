#pragma once
// Deformable bodies: particles are point masses joined by springs and rods.
//
// Integration is XPBD with small steps (Macklin et al., "Small Steps in Physics Simulation", SCA 2019):
// each step is split into `substeps` substeps of h = dt / substeps, each doing one predict - project - update
// pass. Springs are compliant distance constraints with compliance 1/k; rods have compliance 0 (hard).
// Spring damping follows XPBD's constraint damping (Macklin et al., "XPBD", MIG 2016, eq. 26), which
// damps only the relative velocity along the connector, so a freely moving body keeps its momentum.
// Stiff springs stay stable at any time step: the projection is unconditionally stable, and a spring
// stiffer than the step can resolve behaves like a rod.

#include <span>
#include <vector>

#include "engine/core/connector_store.hpp"
#include "engine/core/particle_store.hpp"

namespace volpar {

struct DeformableStepInput {
  std::span<const ParticleId> particles;    ///< particles of deformable bodies
  std::span<const ConnectorId> connectors;  ///< unbroken connectors between them
  Vec3 gravity = Vec3::Zero();              ///< [m/s^2], applied in every substep (0 when the caller already did)
  double dt = 0.0;                          ///< [s]
  int substeps = 1;
  /// Position corrections [m] per particle (indexed like the particle store) that move particles without
  /// giving them velocity (split impulses); empty for none.
  std::span<const Vec3> shift;
};

/// Advances the listed particles by one step. `scratch` is resized once and reused.
void integrateDeformables(ParticleStore& particles, const ConnectorStore& connectors, const DeformableStepInput& in,
                          std::vector<Vec3>& scratch);

/// Elastic energy sum 1/2 k (|xb - xa| - L0)^2 of the listed springs [J]. Rods store none.
[[nodiscard]] double springEnergy(const ParticleStore& particles, const ConnectorStore& connectors,
                                  std::span<const ConnectorId> ids);

}  // namespace volpar
