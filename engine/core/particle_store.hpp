#pragma once
// Particle data, structure of arrays. Index i of every array is particle ParticleId(i).
// Arrays of Vec3 are contiguous doubles with the layout of an HDF5 [P,3] array; use
// positions()/velocities() for Eigen [3 x P] views.

#include <cstdint>
#include <vector>

#include "volpar/engine/core/ids.hpp"
#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// Per-particle flag bits: how the body's surface looks at the particle (collision/normal_cache.hpp).
enum ParticleFlag : std::uint8_t {
  kParticleSurface = 1u << 0,  ///< on the body's surface (has a cached normal)
  kParticleEdge = 1u << 1,     ///< on an edge of its shape (its normal averages two faces)
  kParticleCorner = 1u << 2,   ///< on a corner (its normal averages three or more faces)
  kParticleSheet = 1u << 3,    ///< in a layer one particle thick: both sides are surface (the normal is one
                               ///< of them; with kParticleEdge also on the layer's rim, its normal in-plane)
  kParticleLine = 1u << 4,     ///< in a chain one particle thick: every direction across it is surface (the
                               ///< cached "normal" is the chain's direction)
};
/// Flags of particles whose surface has no single normal at them: contacts there take their normal from
/// the other side or from the geometry of the two sides.
inline constexpr std::uint8_t kParticleSharp = kParticleEdge | kParticleCorner | kParticleLine;

struct ParticleStore {
  LargeVector<Vec3> position;          ///< world centre [m], [P]
  LargeVector<Vec3> velocity;          ///< world velocity [m/s], [P]
  LargeVector<Vec3> local;             ///< centre in the owning body's principal frame [m], [P] (rigid/static)
  LargeVector<double> radius;          ///< [m], [P]
  LargeVector<double> mass;            ///< [kg], [P]
  LargeVector<double> invMass;         ///< [1/kg], [P]; 0 for particles of static bodies
  LargeVector<double> ownInertia;      ///< moment of inertia about its centre [kg m^2], [P] (mass_properties.hpp)
  LargeVector<BodyId> body;            ///< owning body, [P]; changes only when a body breaks apart
  LargeVector<std::int32_t> normalIndex;  ///< index into the normal cache, -1 for interior particles, [P]
  LargeVector<std::uint8_t> flags;     ///< ParticleFlag bits, [P]

  [[nodiscard]] std::size_t size() const { return radius.size(); }

  /// Grows every array by `count` default-initialised particles; returns the first new id.
  ParticleId grow(std::size_t count);
  void reserve(std::size_t count);

  [[nodiscard]] Points positions() { return Points(position.data()->data(), 3, static_cast<Eigen::Index>(size())); }
  [[nodiscard]] ConstPoints positions() const {
    return ConstPoints(position.data()->data(), 3, static_cast<Eigen::Index>(size()));
  }
};

}  // namespace volpar
