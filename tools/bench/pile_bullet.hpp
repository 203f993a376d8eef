#pragma once
// The Bullet world of pile-N for pile_bench (specified at the top of pile_bench.cpp). Bullet's headers stay in
// pile_bullet.cpp.

#include <cstddef>
#include <memory>
#include <string>

#include "tools/bench/pile_spec.hpp"

namespace pile {

enum class BulletSetup {
  Box,             ///< one btBoxShape of half extents 0.15 m per body, static planes
  CompoundPlanes,  ///< one btCompoundShape of 27 btSphereShape(0.05) per body, static planes
  CompoundBoxes,   ///< the compound bodies, ground and walls as static boxes 1 m thick
};

/// A btDiscreteDynamicsWorld holding pile-N in one of the three setups.
class BulletPile {
 public:
  BulletPile(const PileLayout& pile, BulletSetup setup);
  ~BulletPile();
  BulletPile(const BulletPile&) = delete;
  BulletPile& operator=(const BulletPile&) = delete;

  /// Exactly one step of dt (maxSubSteps 0: no fixed-step accumulator, no interpolation).
  void step();
  /// Runs collision detection on the current poses (as the next step would) and returns the deepest
  /// overlap over all manifold points [m].
  double deepest();
  /// Kinetic energy, escaped bodies, the highest centre and the fastest body of the current state.
  void measure(Quality& q) const;

  /// World centres of body i's 27 spheres (the compound setups' children; the lattice sites for boxes) [m].
  [[nodiscard]] Sites sphereCentres(std::size_t i) const;
  /// Body i's mass (the inverse of its inverse mass) [kg].
  [[nodiscard]] double mass(std::size_t i) const;
  /// Body i's inertia in its own frame [kg m^2].
  [[nodiscard]] Mat3 localInertia(std::size_t i) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Bullet's version, its btScalar and the box shape's margin, for pile_bench's header lines.
std::string bulletDescription();

}  // namespace pile
