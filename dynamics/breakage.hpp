#pragma once
// Breakage (docs/fracture.md, docs/architecture.md): forces in the rods of rigid bodies, and splitting a body into the
// connected components of its unbroken connectors.
//
// A rigid body's rods are rigid, so the force each carries is not determined by the motion alone (a
// lattice with diagonals is statically indeterminate). volpar takes the forces of the linear elastic lattice
// with equal axial stiffness in every rod (the usual lattice model of a solid): the loads on the body's
// particles over the step (gravity and contact impulses), made self-equilibrated by the d'Alembert forces of
// the body's rigid motion (-m (a + alpha x r + w x (w x r))), are applied to the lattice, K u = f, and each
// rod's force is its stretch e . (u_b - u_a) (the stiffness cancels). A statically determinate structure (a
// column, a chain) gets its exact forces. K is factored once per body and again only after rods break.

#include <span>
#include <vector>

#include <Eigen/SparseCholesky>

#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/particle_store.hpp"

namespace volpar {

/// The rigid motion that world loads [N] on a body's particles (indexed by particle id) give it over a step
/// in state `s`: a = F / M and alpha = I^-1 (tau - w x I w), world frame. A particle's share of it, its
/// d'Alembert force, is m (a + alpha x r + w x (w x r)) (inertialForce); the loads less these are
/// self-equilibrated.
struct RigidAcceleration {
  Vec3 linear = Vec3::Zero();
  Vec3 angular = Vec3::Zero();

  [[nodiscard]] Vec3 inertialForce(const BodyState& s, double mass, const Vec3& arm) const {
    return mass * (linear + angular.cross(arm) + s.angularVelocity.cross(s.angularVelocity.cross(arm)));
  }
};
[[nodiscard]] RigidAcceleration rigidAcceleration(const BodyState& s, const BodyInfo& body, const ParticleStore& particles,
                                                  std::span<const Vec3> loads);

class RodForces {
 public:
  /// Builds the lattice of one rigid body from its unbroken `rods` (body frame). Returns false if the body
  /// has no rods.
  bool build(const BodyInfo& body, const ParticleStore& particles, const ConnectorStore& connectors,
             std::span<const ConnectorId> rods);

  /// Axial forces [N] of the rods given to build() (tension positive), for world loads [N] on the
  /// particles (indexed by particle id) over a step of the body in state `s`.
  void solve(const BodyState& s, const BodyInfo& body, const ParticleStore& particles, std::span<const Vec3> loads,
             std::vector<double>& forces);

  [[nodiscard]] std::span<const ConnectorId> rods() const { return rods_; }

 private:
  std::vector<ConnectorId> rods_;
  std::vector<Vec3> directions_;                   // unit, body frame, per rod
  std::vector<std::pair<std::uint32_t, std::uint32_t>> ends_;  // local particle indices per rod
  std::vector<std::uint32_t> local_;               // particle id -> local index (only the body's)
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
  Eigen::VectorXd f_, u_;
};

/// The connected components of `particles` under the unbroken `connectors` between them: component[i]
/// for particles[i], numbered 0.. in order of first appearance. Returns the number of components.
std::size_t connectedComponents(std::span<const ParticleId> particles, const ConnectorStore& connectors,
                                std::span<const ConnectorId> ids, std::vector<std::uint32_t>& component);

}  // namespace volpar
