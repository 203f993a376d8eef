#pragma once
// Connectors (rods and springs) between particles of one body, structure of arrays.

#include <cstdint>
#include <limits>
#include <vector>

#include "engine/core/ids.hpp"

namespace volpar {

enum class ConnectorKind : std::uint8_t {
  Rod,     ///< hard distance constraint (compliance 0)
  Spring,  ///< Hookean spring with damping
};

/// Parameters shared by the connectors a builder creates for one body.
struct ConnectorParams {
  ConnectorKind kind = ConnectorKind::Rod;
  double stiffness = 0.0;  ///< [N/m], springs only
  double damping = 0.0;    ///< [N s/m], springs only
  /// Breaking threshold: tensile force [N] for rods, strain [-] for springs; infinity = unbreakable.
  double breakLimit = std::numeric_limits<double>::infinity();
  /// Rods only: the compressive force [N] above which they break (crush); infinity = never in compression.
  double compressionLimit = std::numeric_limits<double>::infinity();
};

struct ConnectorStore {
  std::vector<ParticleId> a;        ///< first particle, [C]
  std::vector<ParticleId> b;        ///< second particle, [C]
  std::vector<ConnectorKind> kind;  ///< [C]
  std::vector<double> restLength;   ///< [m], [C]
  std::vector<double> stiffness;    ///< [N/m], [C]
  std::vector<double> damping;      ///< [N s/m], [C]
  std::vector<double> breakLimit;   ///< tensile force [N] (rod) or strain [-] (spring), [C]
  std::vector<double> compressionLimit;  ///< compressive force [N] (rod; infinity for springs), [C]
  std::vector<std::uint8_t> broken; ///< 1 once broken, [C]

  [[nodiscard]] std::size_t size() const { return a.size(); }

  ConnectorId add(ParticleId pa, ParticleId pb, double rest, const ConnectorParams& params);
  void reserve(std::size_t count);
};

}  // namespace volpar
