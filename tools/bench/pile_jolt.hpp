#pragma once
// The Jolt Physics world of pile-N for pile_bench (specified at the top of pile_bench.cpp). Jolt's headers stay
// in pile_jolt.cpp, which is compiled with Jolt's definitions and instruction sets (tools/bench/CMakeLists.txt).

#include <cstddef>
#include <memory>
#include <string>

#include "tools/bench/pile_spec.hpp"

namespace pile {

enum class JoltShape {
  Box,       ///< one JPH::BoxShape of half extent 0.15 m per body, Jolt's default convex radius
  Compound,  ///< one JPH::StaticCompoundShape of the 27 SphereShape(0.05), shared by all bodies
};

/// A Jolt PhysicsSystem holding pile-N: static planes for the ground and walls, the N bodies in one of the
/// two shapes, stepped by a job system of `threads` threads (the calling thread and threads - 1 workers).
class JoltPile {
 public:
  JoltPile(const PileLayout& pile, JoltShape shape, int threads);
  ~JoltPile();
  JoltPile(const JoltPile&) = delete;
  JoltPile& operator=(const JoltPile&) = delete;

  /// One PhysicsSystem::Update of dt with one collision step; false: Jolt reported an error (error() says which).
  bool step();
  /// The deepest overlap of the current state over all dynamic bodies, each body's shape collided with the
  /// world at its pose (the body itself excluded) [m].
  [[nodiscard]] double deepest() const;
  /// Kinetic energy, escaped bodies, the highest centre and the fastest body of the current state.
  void measure(Quality& q) const;
  /// Not empty: what an Update reported (a buffer too small for the contacts; they were dropped).
  [[nodiscard]] std::string error() const;

  /// World centres of body i's 27 spheres (the compound's children; the lattice sites for boxes) [m].
  [[nodiscard]] Sites sphereCentres(std::size_t i) const;
  /// Body i's mass as Jolt holds it (the inverse of its inverse mass) [kg].
  [[nodiscard]] double mass(std::size_t i) const;
  /// Body i's inertia about its centre of mass in its own frame, from Jolt's inverse inertia [kg m^2].
  [[nodiscard]] Mat3 localInertia(std::size_t i) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Jolt's version, build configuration and the PhysicsSettings it steps with, for pile_bench's header lines.
std::string joltDescription();

}  // namespace pile
