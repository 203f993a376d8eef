#pragma once

#include <cmath>
#include <limits>
#include <string>

#include "volpar/engine/core/connector_store.hpp"

namespace volpar {

/// Surface and bulk properties shared by bodies and planes.
struct Material {
  std::string name;
  double density = 1000.0;    ///< [kg/m^3]; a particle's mass is density x the volume it stands for
  double restitution = 0.5;   ///< [-] in [0, 1]
  double friction = 0.5;      ///< Coulomb coefficient [-], >= 0
  /// [-] >= 0: a rolling body meets a torque of at most this x its rolling radius x the normal force
  /// (coefficient of rolling resistance, as in DEM's constant-torque model); 0 rolls freely
  double rollingResistance = 0.0;
  /// Breaking thresholds of the connectors of bodies made of it, where the body sets none: rods break above
  /// this force [N], springs above this strain [-]; infinity = unbreakable.
  double rodStrength = std::numeric_limits<double>::infinity();
  /// Rods of bodies made of it break in compression above this force [N]; 0: ten times rodStrength (brittle
  /// solids are about ten times stronger in compression than in tension).
  double rodCompressiveStrength = 0.0;
  double strainLimit = std::numeric_limits<double>::infinity();
  // bonded bodies (connectors: bonds) and glue made of it
  double youngsModulus = 0.0;  ///< [Pa]; 0 = not given (bonds need it)
  double poissonRatio = 0.25;  ///< [-], in (-1, 0.5)
  double tensileStrength = std::numeric_limits<double>::infinity();  ///< of a bond [Pa]
  double shearStrength = std::numeric_limits<double>::infinity();    ///< of a bond [Pa]
  double weibullModulus = 0.0;  ///< [-]; 0 = every bond as strong as given
};

/// Bonds (of a body or a glue) made of `m`: they never break as rods do, take its modulus and Poisson's
/// ratio, and its strengths and Weibull modulus where they set none. They need its Young's modulus (> 0),
/// which the caller checks.
inline void takeBondDefaults(const Material& m, ConnectorParams& c) {
  c.breakLimit = c.compressionLimit = std::numeric_limits<double>::infinity();
  c.bond.youngsModulus = m.youngsModulus;
  c.bond.poissonRatio = m.poissonRatio;
  if (!std::isfinite(c.bond.tensileStrength)) c.bond.tensileStrength = m.tensileStrength;
  if (!std::isfinite(c.bond.shearStrength)) c.bond.shearStrength = m.shearStrength;
  if (!(c.bond.weibullModulus > 0.0)) c.bond.weibullModulus = m.weibullModulus;
}

}  // namespace volpar
