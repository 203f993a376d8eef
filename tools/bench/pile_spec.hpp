#pragma once
// pile-N, the scene of pile_bench (specified at the top of pile_bench.cpp), shared by its worlds: the
// constants, the lattice of a body, the start layout, and what a run measures at its end.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "volpar/engine/core/types.hpp"

namespace pile {

using volpar::Mat3;
using volpar::Quat;
using volpar::Vec3;

constexpr int kLatticeSide = 3;                       // spheres per body edge
constexpr int kSpheresPerBody = 27;
constexpr double kRadius = 0.05;                      // [m] sphere radius
constexpr double kSpacing = 0.1;                      // [m] between sphere centres
constexpr double kSphereMass = 0.1;                   // [kg]
constexpr double kBodyMass = kSpheresPerBody * kSphereMass;  // [kg]
constexpr double kBoxHalf = 0.15;                     // [m] half side of the box the spheres fill
constexpr double kGridSpacing = 0.45;                 // [m] between body centres at start
constexpr double kLowestCentre = 0.5;                 // [m] height of the lowest layer of centres
constexpr double kWallGap = 0.3;                      // [m] from the outermost grid half width to a wall
constexpr double kTurnZ = 0.37;                       // [rad] per body index, about world z ...
constexpr double kTurnX = 0.11;                       // [rad] ... then about world x
constexpr double kDt = 1.0 / 240.0;                   // [s]
constexpr int kIterations = 10;
constexpr double kRestitution = 0.1;
constexpr double kFriction = 0.5;
constexpr double kGravity = 9.81;                     // [m/s^2], along -z

/// Steps of the collapse [steps], timed on their own as well as within the whole run: the first 2 s, in which
/// the layers fall, land on each other and spread (the top layer of pile-1000 starts 4.55 m up; a free fall from
/// there takes under 1 s). The rest of a 2000-step run is mostly the pile coming to rest, where the cost is
/// resting contact rather than impacts.
constexpr int kCollapseSteps = 480;

using Sites = std::array<Vec3, kSpheresPerBody>;

/// Offsets of the 27 sphere centres from the body centre, x fastest, then y, then z [m].
inline Sites latticeOffsets() {
  Sites out;
  for (int c = 0; c < kSpheresPerBody; ++c)
    out[static_cast<std::size_t>(c)] = kSpacing * Vec3(c % kLatticeSide - 1, (c / kLatticeSide) % kLatticeSide - 1,
                                                       c / (kLatticeSide * kLatticeSide) - 1);
  return out;
}

/// Principal moments of the crate about its centre [kg m^2]: each of the 27 particles stands for its lattice
/// cell, a cube of side s (own moment m s^2 / 6), plus m d^2, d the particle's distance from the axis; the cells
/// tile the solid 0.3 m cube, whose moments these are (all three equal: 0.0405).
inline Vec3 latticeInertia() {
  Vec3 inertia = Vec3::Zero();
  for (const Vec3& o : latticeOffsets()) {
    const Vec3 sq = o.cwiseProduct(o);
    inertia += kSphereMass * Vec3(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
    inertia += Vec3::Constant(kSphereMass * kSpacing * kSpacing / 6.0);
  }
  return inertia;
}

/// k = ceil(cbrt(n)), the smallest k with k^3 >= n, in integers.
inline int gridSide(int n) {
  auto k = static_cast<std::int64_t>(std::llround(std::cbrt(static_cast<double>(n))));
  while (k * k * k < n) ++k;
  while (k > 1 && (k - 1) * (k - 1) * (k - 1) >= n) --k;
  return static_cast<int>(k);
}

/// The start state of pile-N, shared by every variant.
struct PileLayout {
  int n = 0;
  int k = 0;              ///< bodies per grid row
  double wall = 0.0;      ///< walls at x, y = +-wall [m]
  std::vector<Vec3> centre;       ///< [N] body centres [m]
  std::vector<Quat> orientation;  ///< [N] body frame -> world

  explicit PileLayout(int bodies) : n(bodies), k(gridSide(bodies)), wall(kGridSpacing * k / 2.0 + kWallGap) {
    const double half = (k - 1) / 2.0;
    for (int i = 0; i < n; ++i) {
      centre.emplace_back((i % k - half) * kGridSpacing, ((i / k) % k - half) * kGridSpacing,
                          kLowestCentre + (i / (k * k)) * kGridSpacing);
      orientation.push_back(Quat(Eigen::AngleAxisd(kTurnX * i, Vec3::UnitX())) *
                            Quat(Eigen::AngleAxisd(kTurnZ * i, Vec3::UnitZ())));
    }
  }
  [[nodiscard]] std::size_t particles() const { return static_cast<std::size_t>(n) * kSpheresPerBody; }
};

/// The end state of a run (and its start overlap).
struct Quality {
  double kinetic = 0.0;             ///< [J]
  double maxPenetration = 0.0;      ///< deepest overlap of the end state [m]
  double initialPenetration = 0.0;  ///< deepest overlap before the first step [m]
  int escaped = 0;                  ///< bodies outside the walls or below the ground
  double highest = 0.0;             ///< highest body centre [m]
  double maxSpeed = 0.0;            ///< fastest body centre [m/s]
  bool finite = true;               ///< false: a step produced NaN/inf (the run stopped there)
  std::string error;                ///< not empty: the engine reported an error and the run stopped there
};

/// Body-centre counts of a state: escaped bodies, the highest centre and the fastest one.
struct CentreTally {
  explicit CentreTally(double wallHalfWidth) : wall(wallHalfWidth) {}
  double wall = 0.0;  ///< walls at x, y = +-wall [m]
  int escaped = 0;
  double highest = -1e300;  ///< [m]
  double maxSpeed = 0.0;    ///< [m/s]
  bool finite = true;
  /// A body with centre `c` [m] moving at `v` [m/s].
  void add(const Vec3& c, const Vec3& v) {
    if (!c.allFinite() || !v.allFinite()) finite = false;
    if (!(std::abs(c.x()) <= wall && std::abs(c.y()) <= wall && c.z() >= 0.0)) ++escaped;
    highest = std::max(highest, c.z());
    maxSpeed = std::max(maxSpeed, v.norm());
  }
  /// Copies the counts into `q` (a non-finite state stays marked).
  void into(Quality& q) const {
    q.escaped = escaped;
    q.highest = highest;
    q.maxSpeed = maxSpeed;
    q.finite = q.finite && finite;
  }
};

/// Kinetic energy of a rigid body of mass `mass` [kg] moving at `v` [m/s] and turning at `w` [rad/s] (world
/// frame), with principal moments `inertia` [kg m^2] along the columns of `basis` (body frame -> world) [J].
inline double kineticEnergy(double mass, const Vec3& v, const Vec3& w, const Mat3& basis, const Vec3& inertia) {
  const Vec3 wLocal = basis.transpose() * w;
  return 0.5 * mass * v.squaredNorm() + 0.5 * wLocal.dot(inertia.cwiseProduct(wLocal));
}

}  // namespace pile
