#pragma once
// What a builder produces: particles in the shape frame, ready to become a body.

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "volpar/engine/builders/solid_mass.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

struct ParticleCloud {
  std::vector<Vec3> positions;    ///< centres in the shape frame [m], [P]
  std::vector<double> radii;      ///< [m], [P]
  std::vector<double> volumes;    ///< volume each particle stands for [m^3], [P] (share of the shape, or sphere volume)
  /// Moment of inertia per unit mass of the volume each particle stands for, about its centre [m^2], [P]:
  /// its lattice cell's (cubic s^2 / 6, HCP s^2 / 8) or its sphere's (2/5 r^2); empty means the sphere's
  std::vector<double> ownInertia;
  /// The filled solid's exact mass properties at unit density (shapes.hpp); none for explicit particle lists
  std::optional<SolidMass> solid;
  /// The size of the filled solid's bounds along the shape frame's axes [m]; zero for explicit particle lists
  Vec3 solidSize = Vec3::Zero();
  std::vector<Vec3> normals;      ///< outward unit normal of surface particles, zero otherwise, shape frame, [P]
  /// ParticleFlag bits (engine/core/particle_store.hpp), 0 for interior particles, [P]
  std::vector<std::uint8_t> flags;
  /// How many exact face normals are in featureNormals: 0 interior or unknown, 1 face, 2 edge, 3 corner, [P]
  std::vector<std::uint8_t> features;
  /// The exact normals of those features (the first min(features, 3) entries are set), shape frame, [P]
  std::vector<std::array<Vec3, 3>> featureNormals;
  std::vector<std::array<std::uint32_t, 2>> connectors;  ///< joined particle pairs (i < j), ascending
  /// Stiffness of each connector [N/m] where it is not the body's one (springs calibrated from a modulus,
  /// elastic_calibration.hpp), or empty
  std::vector<double> connectorStiffness;
  std::vector<std::uint8_t> pinned;  ///< 1 for particles held fixed in space (deformable bodies), [P] or empty
  double spacing = 0.0;           ///< lattice spacing [m]; 0 for explicit particle lists

  [[nodiscard]] std::size_t size() const { return positions.size(); }
};

}  // namespace volpar
