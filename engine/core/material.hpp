#pragma once

#include <string>

namespace volpar {

/// Surface and bulk properties shared by bodies and planes.
struct Material {
  std::string name;
  double density = 1000.0;    ///< [kg/m^3]; a particle's mass is density x the volume it stands for
  double restitution = 0.5;   ///< [-] in [0, 1]
  double friction = 0.5;      ///< Coulomb coefficient [-], >= 0
};

}  // namespace volpar
