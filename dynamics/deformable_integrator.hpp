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

#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/particle_store.hpp"

namespace volpar {

/// A non-penetration constraint on a deformable particle `p`, held in every substep (contacts found at the
/// end of the previous step). Against another particle it keeps normal . (x_p - x_other) >= separation
/// (the separating plane's normal, pointing from the other side towards p), or with `centreLine` the
/// centres at least `separation` apart along their current centre line; against a plane (`other` invalid)
/// normal . x_p >= separation.
struct DeformableContact {
  ParticleId p;
  ParticleId other;
  Vec3 normal = Vec3::UnitZ();
  double separation = 0.0;  ///< [m]
  bool centreLine = false;
  /// `other` is a particle of a rigid or static body: it stays where its body's pose puts it (the contact
  /// solver already exchanged momentum with the body), only `p` is moved
  bool otherFixed = false;
  double friction = 0.0;  ///< Coulomb coefficient, applied to the pair's sliding within each substep
};

struct DeformableStepInput {
  std::span<const ParticleId> particles;    ///< particles of deformable bodies
  std::span<const ConnectorId> connectors;  ///< unbroken connectors between them
  Vec3 gravity = Vec3::Zero();              ///< [m/s^2], applied in every substep (0 when the caller already did)
  double dt = 0.0;                          ///< [s]
  int substeps = 1;
  /// Position corrections [m] per particle (indexed like the particle store) that move particles without
  /// giving them velocity (split impulses); empty for none.
  std::span<const Vec3> shift;
  /// If not empty (sized like the connector store): the force [N] of largest magnitude each listed connector
  /// carried in any substep, tension positive (rods: their constraint force; springs: k x stretch).
  std::span<double> forces;
  /// Contacts kept in every substep: a contact's position correction is left out of the velocity, and the
  /// relative velocity of its particles into it is removed (inelastically, conserving momentum).
  std::span<const DeformableContact> contacts;
  /// If not empty (sized like `contacts`): the impulse [N s] each contact with a fixed other particle gave
  /// its deformable particle by stopping it; the rigid body of the other particle owes the opposite one.
  std::span<Vec3> contactImpulses;
  /// If not empty (sized like `contacts`): the angular momentum [kg m^2/s] about the origin that each such
  /// contact gave its deformable particle: the moments x x J of its impulses where the particle was when
  /// each acted, and the moment of momentum its position corrections carried (a particle moved by dx
  /// without momentum gains m dx x v). The rigid body owes the opposite, so that the pair keeps its angular
  /// momentum as it keeps its momentum.
  std::span<Vec3> contactMoments;
};

/// Buffers kept between steps (sized once).
struct DeformableScratch {
  std::vector<Vec3> previous, push, touchNormal, pushed;
  std::vector<std::uint8_t> touching;
};

/// Advances the listed particles by one step.
void integrateDeformables(ParticleStore& particles, const ConnectorStore& connectors, const DeformableStepInput& in,
                          DeformableScratch& scratch);

/// Elastic energy sum 1/2 k (|xb - xa| - L0)^2 of the listed springs [J]. Rods store none.
[[nodiscard]] double springEnergy(const ParticleStore& particles, const ConnectorStore& connectors,
                                  std::span<const ConnectorId> ids);

}  // namespace volpar
