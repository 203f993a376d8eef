#pragma once
// What a builder produces: particles in the shape frame, ready to become a body.

#include <array>
#include <cstdint>
#include <vector>

#include "engine/core/types.hpp"

namespace volpar {

struct ParticleCloud {
  std::vector<Vec3> positions;    ///< centres in the shape frame [m], [P]
  std::vector<double> radii;      ///< [m], [P]
  std::vector<double> volumes;    ///< volume each particle stands for [m^3], [P] (share of the shape, or sphere volume)
  std::vector<Vec3> normals;      ///< outward unit normal of surface particles, zero otherwise, shape frame, [P]
  /// ParticleFlag bits (engine/core/particle_store.hpp), 0 for interior particles, [P]
  std::vector<std::uint8_t> flags;
  /// How many exact face normals are in featureNormals: 0 interior or unknown, 1 face, 2 edge, 3 corner, [P]
  std::vector<std::uint8_t> features;
  /// The exact normals of those features (the first min(features, 3) entries are set), shape frame, [P]
  std::vector<std::array<Vec3, 3>> featureNormals;
  std::vector<std::array<std::uint32_t, 2>> connectors;  ///< joined particle pairs (i < j), ascending
  std::vector<std::uint8_t> pinned;  ///< 1 for particles held fixed in space (deformable bodies), [P] or empty
  double spacing = 0.0;           ///< lattice spacing [m]; 0 for explicit particle lists

  [[nodiscard]] std::size_t size() const { return positions.size(); }
};

}  // namespace volpar
