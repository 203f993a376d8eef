#pragma once
// The solid a body was filled from, kept so that its contacts can be compared with exact geometry
// (`volpar check`, the accuracy tests).
//
// A body filled from a solid is a *rounded* solid: its particle centres fill a core (the solid shrunk by the
// particle radius) and the spheres dilate that core by the radius again. The exact reference for a contact
// normal between two such bodies is therefore the direction of the closest points between their cores
// (fittedCore() gives a body's core from its actual particle centres).

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "engine/core/types.hpp"

namespace volpar {

struct SourceShape {
  enum class Kind : std::uint8_t { None, Box, Sphere, Cylinder, Capsule, Mesh };
  Kind kind = Kind::None;
  Vec3 size = Vec3::Zero();  ///< box: full side lengths [m]
  double radius = 0.0;       ///< sphere, cylinder, capsule [m]
  double length = 0.0;       ///< cylinder: total height; capsule: segment length [m]
  /// Convex meshes: the planes n . x <= d of the solid's faces (unit n, shape frame [m]), one per distinct
  /// face plane; empty for a mesh that is not convex (which has no exact reference).
  std::vector<std::pair<Vec3, double>> facePlanes;

  [[nodiscard]] bool isPrimitive() const { return kind != Kind::None && kind != Kind::Mesh; }
  /// A primitive or a convex mesh: a solid whose core has an exact closest-point reference.
  [[nodiscard]] bool isConvexSolid() const { return isPrimitive() || (kind == Kind::Mesh && !facePlanes.empty()); }
};

/// The tightest solid of the same kind around particle centres given in the shape frame: a box's half
/// sides are the largest |coordinates|, a sphere's radius the farthest centre, a cylinder's radius and half
/// height the farthest centre from its axis and from its middle plane, a capsule keeps its segment and
/// takes the farthest centre from it, a convex mesh keeps its face normals with each plane moved to the
/// farthest centre along it. For a lattice that fills its solid exactly this is the solid shrunk by the
/// particle radius. Shapes that are not convex solids come back unchanged.
[[nodiscard]] SourceShape fittedCore(const SourceShape& shape, std::span<const Vec3> centres);

}  // namespace volpar
