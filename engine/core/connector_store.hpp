#pragma once
// Connectors (rods and springs) between particles of one body, structure of arrays.

#include <cstdint>
#include <limits>
#include <vector>

#include "volpar/engine/core/ids.hpp"

namespace volpar {

enum class ConnectorKind : std::uint8_t {
  Rod,     ///< hard distance constraint (compliance 0)
  Spring,  ///< Hookean spring with damping
  /// A rigid body's connector that carries axial and shear forces, bending and twisting moments like an
  /// elastic beam of circular section, and breaks by its tensile or shear stress (dynamics/bond_loads.hpp)
  Bond,
};

/// How a bond is made and when it breaks (ConnectorKind::Bond).
struct BondParams {
  double radiusFactor = 1.0;    ///< the bond's radius as a fraction of the smaller particle radius [-]
  double youngsModulus = 0.0;   ///< of the bond's material [Pa]
  double poissonRatio = 0.25;   ///< [-]; the shear modulus is E / (2 (1 + nu))
  /// Strengths [Pa]: a bond breaks where its largest normal stress exceeds the tensile strength, or its
  /// largest shear stress (with the normal stress, Tresca) exceeds the shear strength; infinity = never
  double tensileStrength = std::numeric_limits<double>::infinity();
  double shearStrength = std::numeric_limits<double>::infinity();
  /// Weibull modulus m [-] of the strengths: each bond's are the given ones (the scale) times
  /// (-ln U)^(1/m) for a uniform U drawn from the world's seed and the bond's index; 0 = all equal
  double weibullModulus = 0.0;
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
  BondParams bond;  ///< bonds only
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
  // bonds (ConnectorKind::Bond; zero or infinity for other connectors)
  std::vector<double> bondRadius;       ///< [m], [C]
  std::vector<double> youngsModulus;    ///< [Pa], [C]
  std::vector<double> poissonRatio;     ///< [-], [C]
  std::vector<double> tensileStrength;  ///< [Pa], [C]
  std::vector<double> shearStrength;    ///< [Pa], [C]

  [[nodiscard]] std::size_t size() const { return a.size(); }

  /// Adds a connector; a bond takes `bondRadius` [m] and its strengths times `strengthFactor`.
  ConnectorId add(ParticleId pa, ParticleId pb, double rest, const ConnectorParams& params, double bondRadius = 0.0,
                  double strengthFactor = 1.0);
  void reserve(std::size_t count);
};

}  // namespace volpar
