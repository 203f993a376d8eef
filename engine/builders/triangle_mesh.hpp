#pragma once
// Closed triangle meshes for filling with particles: validation, inside test and distances.

#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

struct TriangleMesh {
  std::vector<Vec3> vertices;                           ///< [V] [m]
  std::vector<std::array<std::uint32_t, 3>> triangles;  ///< [T], counter-clockwise seen from outside
  std::vector<int> triangleLine;                        ///< source line of each triangle, [T] (0 if unknown)
  std::vector<int> vertexNumber;                        ///< 1-based number of each vertex in its source file, [V]
  std::string source;                                   ///< file name, for messages

  /// Checks that the mesh bounds a solid: no degenerate triangles, every edge shared by exactly two
  /// triangles that traverse it in opposite directions (closed, manifold, consistently oriented), and a
  /// non-zero enclosed volume. Turns an inside-out mesh the right way round.
  [[nodiscard]] Status makeSolid();

  /// Generalised winding number > 1/2 (robust for closed meshes). O(T).
  [[nodiscard]] bool contains(const Vec3& p) const;
  /// Unsigned distance to the surface [m]. O(T).
  [[nodiscard]] double distance(const Vec3& p) const;
  /// Unit normals of the distinct face planes within `band` [m] of the nearest one, nearest first.
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const;
  /// The distinct face planes n . x <= d (unit outward n) when the solid is convex (every vertex on the
  /// inner side of every face plane, within 1e-9 of the mesh's size); empty otherwise.
  [[nodiscard]] std::vector<std::pair<Vec3, double>> convexFacePlanes() const;
  [[nodiscard]] Eigen::AlignedBox3d bounds() const;
  /// Enclosed volume [m^3] (positive once makeSolid() succeeded).
  [[nodiscard]] double volume() const;
};

/// Closest point to p on triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5).
[[nodiscard]] Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

}  // namespace volpar
