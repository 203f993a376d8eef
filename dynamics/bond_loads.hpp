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


#include "volpar/dynamics/frame_multigrid.hpp"
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

/// The frame of one bonded rigid body and the loads of its bonds.
///
/// K u = f is solved by conjugate gradients preconditioned by aggregation multigrid (frame_multigrid.hpp),
/// warm started from the body's last displacements (after a break, the loads change only near it). The
/// iterations stop where the residual is below kTolerance of the load (in the Euclidean norm of forces and
/// moments); the bond loads then agree with a direct solve to 1e-3 of the largest
/// (tests/dynamics/bond_loads_accuracy_test.cpp), well inside the spread of the bonds' strengths. Costs are linear in the bonds: building the frame
/// and its hierarchy, each iteration (about four products with the stiffness), and evaluating the bonds;
/// removing k bonds costs O(k) (the hierarchy changes in place).
class BondLoads {
 public:
  static constexpr double kTolerance = 1e-4;  // relative residual where the iterations stop
  static constexpr int kMaxIterations = 300;

  /// Builds the frame of one rigid body from its unbroken `bonds` (body frame). Returns false where the body
  /// has no bonds.
  bool build(const BodyInfo& body, const ParticleStore& particles, const ConnectorStore& connectors,
             std::span<const ConnectorId> bonds);
  /// Keeps this frame (its parent's, moved here) for the largest piece its body split into: `parentIndex[i]` is
  /// the place in the parent's particles of the piece's particle i, `turn` the parent's body axes to the
  /// piece's. The nodes of the other pieces stay in the frame without bonds or loads (their bonds leave it);
  /// a frame kept while at least half its nodes are the piece's costs at most twice a new one's per
  /// iteration, and the split costs O(the other pieces' bonds) instead of a new frame.
  void keepFor(std::span<const std::uint32_t> parentIndex, const Mat3& turn);
  /// The frame's nodes (particle ids, in the order it was built; a kept frame's include its pieces' left).
  [[nodiscard]] std::span<const std::uint32_t> nodes() const { return nodeParticle_; }
  /// The nodes' positions when it was built, in the axes it was built in.
  [[nodiscard]] std::span<const Vec3> nodePositions() const { return nodePosition_; }
  /// The rotation from the body's axes now to the axes the frame was built in.
  [[nodiscard]] const Mat3& axes() const { return toFrame_; }

  /// The loads of the bonds given to build(), for world loads [N] on the particles (indexed by particle id)
  /// over a step of the body in state `s`.
  /// `pool`, where given, shares the work of a large frame among its workers; the loads are the same bits for
  /// any number of threads.
  void solve(const BodyState& s, const BodyInfo& body, const ParticleStore& particles, std::span<const Vec3> loads,
             std::vector<BondLoad>& out, ThreadPool* pool = nullptr);

  /// Takes broken bonds (entries of bonds()) out of the frame; their loads are zero from then on.
  void remove(std::span<const std::size_t> entries);

  /// After remove(`entries`) under the loads of the last solve(): solves again where the removed bonds
  /// change the displacements. A region, the nodes within kRegionRings bonds of a removed bond's ends, is solved
  /// by conjugate gradients (block Jacobi), the other nodes held; where what is left of the whole frame's
  /// residual, on the region's rim, is above solve()'s tolerance, a region twice as wide goes on from there,
  /// until the whole frame's residual is within it: the displacements are then a solution as good as solve()'s.
  /// The loads of the bonds with an end in the last region are written to `out` and their entries to
  /// `changed`; the other bonds' loads are as they were. Costs O(the region's bonds) an iteration; where the
  /// region would hold a quarter of the nodes or more, it is solve() itself (and every entry changed).
  void solveAround(std::span<const std::size_t> entries, const BodyState& s, const BodyInfo& body,
                   const ParticleStore& particles, std::span<const Vec3> loads, std::vector<BondLoad>& out,
                   std::vector<std::uint32_t>& changed, ThreadPool* pool = nullptr);
  /// Whether the two ends of each of `entries` are still joined through the frame's active bonds, found by
  /// searching at most kJoinSearch nodes out from one end: false where a search ran out or found the end's
  /// piece complete without the other (then the body may have split). O(entries) searches of bounded size.
  [[nodiscard]] bool endsJoined(std::span<const std::size_t> entries);
  static constexpr std::size_t kJoinSearch = 64;
  static constexpr int kRegionRings = 4;
  static constexpr double kPassTolerance = 1e-2;  // of the residual the removed bonds leave, solveAround()'s

  [[nodiscard]] std::span<const ConnectorId> bonds() const { return bonds_; }
  /// The entries removed since build(), in order: with bonds() and displacements(), what makes the same frame
  /// again (replay), bit for bit.
  [[nodiscard]] std::span<const std::uint32_t> removed() const { return removed_; }
  /// The displacements and rotations of the last solve (6 a node, in the frame's axes), from which the
  /// next one starts.
  [[nodiscard]] std::span<const double> displacements() const { return {u_.data(), static_cast<std::size_t>(u_.size())}; }
  /// Starts the next solve from the displacements of `parent`'s particles `parentIndex[i]` (places in the
  /// parent's particles, one for each of this frame's particles), turned by `turn` (the parent's body axes to
  /// this body's): a piece split off a body starts where its parent was.
  void startFrom(const BondLoads& parent, std::span<const std::uint32_t> parentIndex, const Mat3& turn);
  /// The frame of `nodes` at `positions` from `bonds`, with `removed` removed in order, starting from
  /// `displacements` (6 a node), for the body `body` whose axes `axes` turns into the frame's (a checkpoint's
  /// frame, bit for bit). False where a bond's end or a body's particle is not a node, an entry is out of
  /// range, or the sizes do not fit.
  bool replay(const BodyInfo& body, const ConnectorStore& connectors, std::span<const std::uint32_t> nodes,
              std::span<const Vec3> positions, const Mat3& axes, std::span<const ConnectorId> bonds,
              std::span<const std::uint32_t> removed, std::span<const double> displacements);

  /// Conjugate-gradient iterations of the last solve (0 where the last displacements still solved it).
  [[nodiscard]] int iterations() const { return iterations_; }
  /// Bytes the frame holds (matrix, hierarchy, vectors).
  [[nodiscard]] std::size_t bytes() const;

 private:
  struct Beam {
    std::uint32_t a = 0, b = 0;  // local particle indices
    Vec3 e = Vec3::Zero();       // unit, a to b, body frame
    double length = 0.0;
    double axial = 0.0, torsion = 0.0, bending = 0.0;  // E A / L, G J / L, E I / L
    bool active = true;
  };

  /// The loads of an active beam, from the displacements u_.
  [[nodiscard]] BondLoad beamLoad(const Beam& beam) const;
  /// A new mark for mark_ (and that mark + 1), different from every mark the nodes hold.
  std::uint32_t nextStamp();
  /// The frame of `nodes` at `positions` from `bonds` (build() and replay()).
  bool buildFrame(std::span<const std::uint32_t> nodes, std::span<const Vec3> positions, const ConnectorStore& connectors,
                  std::span<const ConnectorId> bonds);

  std::vector<ConnectorId> bonds_;
  std::vector<Beam> beams_;
  std::vector<std::uint32_t> nodeParticle_;  // each node's particle id
  std::vector<Vec3> nodePosition_;           // each node's position when built (the frame's axes)
  std::vector<std::uint32_t> bodyNode_;      // the node of each of the body's particles, in the body's order
  Mat3 toFrame_ = Mat3::Identity();          // the body's axes to the frame's
  FrameStiffness k_;          // the frame's stiffness now
  FrameMultigrid multigrid_;  // of k_, changed with it
  std::vector<std::uint32_t> removed_;  // entries removed since build(), in order
  Eigen::VectorXd f_, u_, r_, z_, p_, q_;
  std::vector<double> partial_;  // (chunkedDot's)
  double loadSquared_ = 0.0;     // f . f of the last solve
  double residualSquared_ = 0.0;  // r_ . r_, kept through remove() and solveAround()
  std::vector<std::uint32_t> beamStart_, nodeBeams_;  // the beams at each node (CSR)
  std::vector<std::uint32_t> mark_;    // per node: regionStamp_ in solveAround()'s region, + 1 on its rim
  std::uint32_t regionStamp_ = 0;
  std::vector<std::uint32_t> region_;  // solveAround()'s region, then its rim
  int iterations_ = 0;
};

}  // namespace volpar
