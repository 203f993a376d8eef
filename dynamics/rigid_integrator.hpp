#pragma once
// Rigid-body time integration.
//
// Velocities: semi-implicit (symplectic) Euler, v += g dt.
// Positions: x += v dt, and the rotation is advanced by the splitting method of Dullweber, Leimkuhler and
// McLachlan, "Symplectic splitting methods for rigid body molecular dynamics" (J. Chem. Phys. 107, 1997):
// the free-rigid-body Hamiltonian sum_k L_k^2 / (2 I_k) is split into its three principal-axis terms, each
// of which is an exact rotation about that axis, composed symmetrically (Strang):
//   R1(dt/2) R2(dt/2) R3(dt) R2(dt/2) R1(dt/2).
// Each sub-flow rotates body-frame angular momentum and orientation in opposite senses, so the world-frame
// angular momentum is conserved to round-off, and the energy error is bounded (O(dt^2), no drift). This is
// the gyroscopic treatment: omega is recovered from the conserved momentum, so the intermediate-axis
// instability appears as it should.

#include "volpar/engine/core/body_store.hpp"

namespace volpar {

/// v += gravity dt for a body with finite mass.
void integrateRigidVelocity(BodyState& s, const Vec3& gravity, double dt);

/// Advances position and orientation by dt (torque free within the step) and updates
/// invInertiaWorld and angularVelocity from the conserved angular momentum. The pseudo velocities of
/// position correction (split impulses) move the body too but change none of its velocities.
void integrateRigidPose(BodyState& s, double dt, const Vec3& pseudoLinear = Vec3::Zero(),
                        const Vec3& pseudoAngular = Vec3::Zero());

/// invInertiaWorld = R diag(invInertiaLocal) R^T.
void updateWorldInertia(BodyState& s);

/// Rotational kinetic energy 1/2 w . I w and world angular momentum I w about the centre of mass.
[[nodiscard]] double rotationalEnergy(const BodyState& s, const Vec3& inertiaLocal);
[[nodiscard]] Vec3 angularMomentum(const BodyState& s, const Vec3& inertiaLocal);

}  // namespace volpar
