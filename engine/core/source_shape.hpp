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

#include "volpar/engine/core/types.hpp"

namespace volpar {

struct SourceShape {
  enum class Kind : std::uint8_t { None, Box, Sphere, Cylinder, Capsule, Mesh };
  Kind kind = Kind::None;
  Vec3 size = Vec3::Zero();  ///< box: full side lengths [m]
  double radius = 0.0;       ///< sphere, cylinder, capsule [m]
  double length = 0.0;       ///< cylinder: total height; capsule: segment length [m]
  Vec3 centre = Vec3::Zero();  ///< where the solid's centre is in the shape frame [m] (a fitted core may be off-centre)
  /// Convex meshes: the planes n . x <= d of the solid's faces (unit n, shape frame [m]), one per distinct
  /// face plane; empty for a mesh that is not convex (which has no exact reference).
  std::vector<std::pair<Vec3, double>> facePlanes;
  /// The body's surface normals were estimated from its particles (scene `normals: estimated`, and every
  /// explicit particle list), not taken from the solid.
  bool estimatedNormals = false;

  [[nodiscard]] bool isPrimitive() const { return kind != Kind::None && kind != Kind::Mesh; }
  /// A primitive or a convex mesh: a solid whose core has an exact closest-point reference.
  [[nodiscard]] bool isConvexSolid() const { return isPrimitive() || (kind == Kind::Mesh && !facePlanes.empty()); }
};

/// The tightest solid of the same kind and axes around particle centres given in the shape frame: a box
/// spans the centres' extent along each axis, a sphere keeps its centre and reaches the farthest centre, a
/// cylinder keeps its axis, spans the centres along it and reaches the farthest from it, a capsule keeps
/// its segment and reaches the farthest centre from it, a convex mesh keeps its face normals with each
/// plane moved to the farthest centre along it. (A lattice need not sit symmetrically in its solid: an HCP
/// box's opposite faces can lie at different depths, so the core can be off-centre.) For a lattice that fills its solid exactly this is the solid shrunk by the
/// particle radius. Shapes that are not convex solids come back unchanged.
[[nodiscard]] SourceShape fittedCore(const SourceShape& shape, std::span<const Vec3> centres);

}  // namespace volpar
