#pragma once
// The loads in the bonds of a rigid body, and when a bond breaks.
//
// A bonded rigid body (ConnectorKind::Bond) is, for its loads, a frame of elastic beams: each bond joins two
// particles like a beam of circular section (radius R, area A = pi R^2, I = pi R^4 / 4, J = 2 I; Young's
// modulus E and shear modulus G = E / (2 (1 + nu)); Euler-Bernoulli bending), and each particle has three
// displacements and three rotations. As for rods (breakage.hpp), the particles' loads over the step (gravity
// and contact forces) made self-equilibrated by the d'Alembert loads of the body's rigid motion are applied
// to the frame, K u = f, and each bond's loads are those of its deformation:
//   axial force  N = (E A / L) e . (u_b - u_a)                          (tension positive)
//   torsion      T = (G J / L) e . (theta_b - theta_a)
//   end moments  M_a = (E I / L) (4 psi_a + 2 psi_b), M_b = (E I / L) (2 psi_a + 4 psi_b)
//   shear force  V = |M_a + M_b| / L
// where psi is an end's rotation across the bond relative to the chord's (e x (u_b - u_a) / L). This is the
// bonded-particle model's parallel bond (Potyondy and Cundall 2004) solved for the whole body at once: a
// statically determinate structure (a chain, a tree of bonds) gets its exact statics, whatever E and nu.
//
// A bond breaks where its largest normal stress over the section, N / A + M R / I (M the larger end moment),
// exceeds its tensile strength, or its largest shear stress exceeds its shear strength; the shear stress
// combines V / A + T R / J with the largest normal stress |N| / A + M R / I by Mohr's circle (Tresca), so a
// bond in pure compression breaks, by shear, where |N| / A reaches twice its shear strength.

#include <span>
#include <vector>

#include <Eigen/SparseCholesky>

#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/particle_store.hpp"

namespace volpar {

/// The loads one bond carries, and its stresses.
struct BondLoad {
  double axial = 0.0;    ///< N [N], tension positive
  double shear = 0.0;    ///< |V| [N]
  double bending = 0.0;  ///< the larger end moment's magnitude [N m]
  double torsion = 0.0;  ///< |T| [N m]
  double energy = 0.0;   ///< elastic energy the bond stores [J]
};

/// Why a bond breaks, if it does.
enum class BondFailure : std::uint8_t { None, Tension, Shear };

/// Largest normal stress (tension positive) and largest shear stress [Pa] of a bond of radius `radius` [m].
struct BondStress {
  double tensile = 0.0;
  double shear = 0.0;
};
[[nodiscard]] BondStress bondStress(const BondLoad& load, double radius);
/// Tension where the tensile stress exceeds the tensile strength, else shear where the shear stress exceeds
/// the shear strength.
[[nodiscard]] BondFailure bondFailure(const BondStress& stress, double tensileStrength, double shearStrength);

class BondLoads {
 public:
  /// Builds the frame of one rigid body from its unbroken `bonds` (body frame). Returns false where the body
  /// has no bonds or the factorisation fails.
  bool build(const BodyInfo& body, const ParticleStore& particles, const ConnectorStore& connectors,
             std::span<const ConnectorId> bonds);

  /// The loads of the bonds given to build(), for world loads [N] on the particles (indexed by particle id)
  /// over a step of the body in state `s`.
  void solve(const BodyState& s, const BodyInfo& body, const ParticleStore& particles, std::span<const Vec3> loads,
             std::vector<BondLoad>& out);

  /// Takes broken bonds (entries of bonds()) out of the frame; their loads are zero from then on. The
  /// factorisation is kept: later solves use it to precondition conjugate gradients on the frame without
  /// them, and factorise again (on the same sparsity pattern) only where that converges slowly.
  void remove(std::span<const std::size_t> entries);

  [[nodiscard]] std::span<const ConnectorId> bonds() const { return bonds_; }
  /// The entries removed since build(), in order, and how many of them were out when the frame was last
  /// factorised: with bonds(), what makes the same frame again (replay), bit for bit.
  [[nodiscard]] std::span<const std::uint32_t> removed() const { return removed_; }
  [[nodiscard]] std::size_t factorisedAt() const { return factorisedAt_; }
  /// Builds the frame from `bonds` and removes `removed` in order, factorising after the first
  /// `factorisedAt` of them as the frame it replays was (a checkpoint's frame). False where an entry is out
  /// of range or the factorisation fails.
  bool replay(const BodyInfo& body, const ParticleStore& particles, const ConnectorStore& connectors,
              std::span<const ConnectorId> bonds, std::span<const std::uint32_t> removed, std::size_t factorisedAt);

 private:
  struct Beam {
    std::uint32_t a = 0, b = 0;  // local particle indices
    Vec3 e = Vec3::Zero();       // unit, a to b, body frame
    double length = 0.0;
    double axial = 0.0, torsion = 0.0, bending = 0.0;  // E A / L, G J / L, E I / L
    bool active = true;
  };
  bool factorise();

  std::vector<ConnectorId> bonds_;
  std::vector<Beam> beams_;
  std::vector<std::uint32_t> local_;  // particle id -> local index (only the body's)
  Eigen::SparseMatrix<double> k_;     // the frame's stiffness now
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;  // of k_ when it was last factorised
  bool stale_ = false;                // k_ changed since
  std::vector<std::uint32_t> removed_;  // entries removed since build(), in order
  std::size_t factorisedAt_ = 0;        // removed_.size() when last factorised
  Eigen::VectorXd f_, u_, r_, z_, p_, q_;
};

}  // namespace volpar
