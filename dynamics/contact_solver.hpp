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

#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/types.hpp"

namespace volpar {

struct SolverSettings {
  int iterations = 10;                  ///< velocity iterations
  int positionIterations = 10;          ///< split-impulse (pseudo-velocity) iterations
  double restitutionThreshold = 0.2;    ///< [m/s] approach speed below which contacts do not bounce
  double baumgarte = 0.2;               ///< [-] fraction of the penetration (beyond the slop) removed per step
  double maxCorrectionSpeed = 1.0;      ///< [m/s] cap on the pseudo velocity of position correction
  bool warmStart = true;
};

/// A body as the solver sees it.
struct SolverBody {
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

  /// Solves the contacts for velocities and pseudo velocities of `bodies` over a step of dt.
  void solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt);

  /// Sum of the normal impulses applied in the last solve [N s].
  [[nodiscard]] double totalNormalImpulse() const { return totalNormalImpulse_; }
  [[nodiscard]] std::size_t warmStarted() const { return warmStarted_; }
  /// The impulse [N s] each point of the last solve applied to its B side (A got the opposite), world.
  [[nodiscard]] std::span<const Vec3> impulses() const { return impulses_; }

 private:
  struct Row {
    Vec3 rA, rB, n, t1, t2;
    double massN, massT1, massT2;  // effective masses
    double targetN;                // velocity target along n (restitution)
    double friction;
    double lambdaN = 0.0, lambdaT1 = 0.0, lambdaT2 = 0.0, lambdaP = 0.0;
    double biasP;                  // pseudo-velocity target
    std::uint32_t a, b;
    std::uint64_t key;
  };
  struct Cached {
    std::uint64_t key;
    double lambdaN;
    Vec3 lambdaT;  // world tangential impulse
  };

  SolverSettings settings_;
  std::vector<Row> rows_;
  std::vector<Cached> cache_, nextCache_;  // sorted by key
  std::vector<Vec3> impulses_;
  double totalNormalImpulse_ = 0.0;
  std::size_t warmStarted_ = 0;
};

}  // namespace volpar
