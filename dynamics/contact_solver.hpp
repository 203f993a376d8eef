#pragma once
// Sequential-impulse contact solver (DESIGN section 6), after Erin Catto's "Iterative Dynamics with
// Temporal Coherence" (GDC 2005) and "Modeling and Solving Constraints" (GDC 2009), with split impulses
// for position correction (Catto, Box2D; Bullet's m_splitImpulse).
//
// Per contact point: a normal impulse with accumulated clamping (>= 0); Coulomb friction in two tangent
// directions, the pair clamped to the cone |lambda_t| <= mu lambda_n; restitution as a velocity target
// -e v_n for approach speeds above a threshold; warm starting from the previous step's impulses, matched by
// the point's key (the pair of particle ids, exact because ids are stable). Penetration is removed by
// separate "pseudo" velocities that move positions but carry no momentum, so position correction adds no
// energy (no Baumgarte bounce) and stacks rest without sinking or jitter.
//
// Bodies are rigid bodies (mass, world inverse inertia) or point masses (particles of deformable bodies);
// static bodies and planes are the fixed side (index kFixed).
//
// Order and threads: the bodies are split at their median x into two halves; the points within the left
// half are solved first, then those within the right half, then those joining the halves, in every
// iteration. The two halves share no body, so two threads can solve them at once (a spin barrier between
// the phases) with exactly the arithmetic of one thread: the result does not depend on the thread count.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/thread_pool.hpp"
#include "engine/core/types.hpp"

namespace volpar {

struct SolverSettings {
  int iterations = 10;                  ///< velocity iterations
  int positionIterations = 10;          ///< split-impulse (pseudo-velocity) iterations, at most
  /// [m/s] position iterations stop once no point's pseudo velocity changed by more than this in one
  double positionTolerance = 1e-4;
  double restitutionThreshold = 0.2;    ///< [m/s] approach speed below which contacts do not bounce
  double baumgarte = 0.2;               ///< [-] fraction of the penetration (beyond the slop) removed per step
  double maxCorrectionSpeed = 1.0;      ///< [m/s] cap on the pseudo velocity of position correction
  bool warmStart = true;
};

/// A body as the solver sees it.
struct SolverBody {
  Vec3 position = Vec3::Zero();  ///< centre of mass [m] (only orders the work)
  Vec3 v = Vec3::Zero();         ///< linear velocity [m/s]
  Vec3 w = Vec3::Zero();         ///< angular velocity [rad/s] (0 for point masses)
  Vec3 pv = Vec3::Zero();        ///< pseudo linear velocity (position correction only)
  Vec3 pw = Vec3::Zero();        ///< pseudo angular velocity
  Mat3 invInertia = Mat3::Zero();  ///< world [1/(kg m^2)]; zero for point masses
  double invMass = 0.0;          ///< [1/kg]
};

/// One contact point between two solver bodies (or one body and the fixed world).
struct ContactPointInput {
  static constexpr std::uint32_t kFixed = 0xffffffffu;
  std::uint32_t a = kFixed;      ///< solver body on side A
  std::uint32_t b = kFixed;      ///< solver body on side B
  Vec3 rA = Vec3::Zero();        ///< contact point minus A's centre of mass [m]
  Vec3 rB = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();   ///< unit, from A towards B
  double depth = 0.0;            ///< penetration along the normal [m] (> 0 overlapping; < 0 the gap of a
                                 ///< speculative contact, which may close but not overlap within the step)
  double slop = 0.0;             ///< penetration left uncorrected [m]
  double friction = 0.5;         ///< combined Coulomb coefficient
  double restitution = 0.0;      ///< combined coefficient
  std::uint64_t key = 0;         ///< identity for warm starting
};

class ContactSolver {
 public:
  void setSettings(const SolverSettings& s) { settings_ = s; }
  [[nodiscard]] const SolverSettings& settings() const { return settings_; }

  /// Solves the contacts for velocities and pseudo velocities of `bodies` over a step of dt. With a
  /// `pool` the two halves of the contact graph are solved on two threads; the result is the same.
  void solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt,
             ThreadPool* pool = nullptr);

  /// Sum of the normal impulses applied in the last solve [N s].
  [[nodiscard]] double totalNormalImpulse() const { return totalNormalImpulse_; }
  [[nodiscard]] std::size_t warmStarted() const { return warmStarted_; }
  /// The impulse [N s] each point of the last solve applied to its B side (A got the opposite), world.
  [[nodiscard]] std::span<const Vec3> impulses() const { return impulses_; }

 private:
  /// One constraint direction of a point: the unit direction d and, per side, the angular part of the
  /// Jacobian (r x d) and the angular velocity change per unit impulse I^-1 (r x d).
  struct Axis {
    Vec3 d, crossA, crossB, turnA, turnB;
    double mass;  // 1 / (J M^-1 J^T)
  };
  struct Row {
    Axis n, t1, t2;
    double invMassA, invMassB;
    double targetN;                // velocity target along n (restitution, speculative gap)
    double friction;
    double biasP;                  // pseudo-velocity target
    double lambdaN, lambdaT1, lambdaT2, lambdaP;
    std::uint32_t a, b;            // indices into the velocity arrays (the fixed body: the last)
  };
  struct Cached {
    std::uint64_t key;
    double lambdaN;
    Vec3 lambdaT;  // world tangential impulse
  };

  SolverSettings settings_;
  /// Rows in solving order: the rows within the left half of the bodies (by x), then those within the
  /// right half, then those joining the two; `parts_` holds the three ranges' boundaries.
  void order(std::span<const SolverBody> bodies, std::span<const ContactPointInput> points);
  /// One sweep of the velocity (or pseudo-velocity) iteration over rows [begin, end).
  void velocitySweep(std::size_t begin, std::size_t end);
  /// Returns whether a point's pseudo velocity changed by more than the tolerance.
  bool positionSweep(std::size_t begin, std::size_t end);

  std::vector<Row> rows_;
  std::vector<std::uint64_t> keys_;  // per row: its warm-starting key
  std::vector<std::uint32_t> order_;  // per row: the index of its input point
  std::array<std::size_t, 4> parts_{};
  std::vector<std::uint8_t> side_;    // per solver body: 0 left, 1 right
  std::vector<std::uint32_t> slot_;   // per solver body: its entry in the velocity arrays
  std::array<std::uint32_t, 3> fixedSlot_{};  // per part: the fixed side's entry
  std::size_t slots_ = 0;
  std::vector<std::pair<double, std::uint32_t>> byX_;
  SpinBarrier barrier_;
  // velocities of the solver bodies and, last, of the fixed world (always zero)
  std::vector<Vec3> v_, w_, pv_, pw_;
  std::vector<Cached> cache_, nextCache_;  // sorted by key
  std::vector<Vec3> impulses_;
  double totalNormalImpulse_ = 0.0;
  std::size_t warmStarted_ = 0;
};

}  // namespace volpar
