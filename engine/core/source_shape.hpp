#pragma once

#include <cstdint>

#include "engine/core/types.hpp"

namespace volpar {

/// The primitive a body was filled from, in its shape frame (kept so that its contacts can be compared
/// with the exact primitive, e.g. by `volpar check`).
struct SourceShape {
  enum class Kind : std::uint8_t { None, Box, Sphere, Cylinder, Capsule, Mesh };
  Kind kind = Kind::None;
  Vec3 size = Vec3::Zero();  ///< box: full side lengths [m]
  double radius = 0.0;       ///< sphere, cylinder, capsule [m]
  double length = 0.0;       ///< cylinder: total height; capsule: segment length [m]

  [[nodiscard]] bool isPrimitive() const { return kind != Kind::None && kind != Kind::Mesh; }
};

}  // namespace volpar
