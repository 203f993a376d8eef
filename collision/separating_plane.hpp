#pragma once
// The vocabulary of the local separating plane of one contact patch (docs/narrow-phase.md, after "Volumetric
// Particle Separating Planes for Collision Detection"; the method as built: docs/narrow-phase.md and
// plane_solver.hpp).
//
// The paper's cases: a patch's particles on each side (A = the body with the lower id) classified by how
// many unique particles each side contributes and whether they are collinear (the smaller side first):
//
//   case           particles (small side - large side)
//   VertexFace11   1 - 1
//   VertexFace12   1 - 2 or more collinear
//   EdgeEdge12     1 - 2 or more collinear, the single particle on an edge of its shape
//   VertexFace13   1 - 3 or more not collinear
//   EdgeEdge22     2 - 2
//   EdgeEdge23     2 or more collinear - 3 or more collinear (parallel edges: a look-ahead decides)
//   EdgeFace23     2 - 3 or more not collinear
//   EdgeFace33     3 or more collinear - 3 or more not collinear
//   FaceFace       3 or more not collinear on both sides
//   ParticlePlane  any - a plane (the plane's normal, exact)
//
// The plane itself comes from the local particles' hulls and the cores their cached face normals stand for
// (plane_solver.hpp); the paper's per-case candidates (best-fit lines and planes of the sides, cached
// normals, the centre line) remain as the fallback where the local hulls overlap. Validation: the centres
// of each side's patch particles and of their k-ring connector neighbours that face the plane lie on its
// side of it within `validationTolerance` x (r_a + r_b).

#include <array>
#include <cstdint>

#include "volpar/engine/core/types.hpp"

namespace volpar {

enum class PlaneCase : std::uint8_t {
  VertexFace11,
  VertexFace12,
  VertexFace13,
  EdgeEdge12,
  EdgeEdge22,
  EdgeEdge23,
  EdgeFace23,
  EdgeFace33,
  FaceFace,
  ParticlePlane,
};
inline constexpr std::size_t kPlaneCaseCount = 10;

/// "vertex_face_1_1", ... (the names used in statistics and the trajectory).
[[nodiscard]] const char* planeCaseName(PlaneCase c);

/// Where a chosen normal came from.
enum class NormalSource : std::uint8_t {
  FaceA,           ///< best-fit plane of A's particles
  FaceB,           ///< best-fit plane of B's particles
  LineLine,        ///< cross product of the two sides' lines
  LinePerpendicular,  ///< perpendicular from a line to the other side's single particle, or between parallel lines
  LineContactPoints,  ///< a line x the difference of the contact points
  NeighbourLine,   ///< the single particle's edge (same-normal neighbours) x the other line
  CachedA,         ///< A's cached surface normals
  CachedB,         ///< B's cached surface normals (reversed)
  CentreLine,      ///< centre-to-centre direction of the two sides
  Plane,           ///< a plane's own normal
  Separation,      ///< the direction of greatest separation of the two sides' local particle hulls
  Surface,         ///< the smooth surface normals of the sides, interpolated at the closest points
  ContactLines,    ///< each contact resolved along its own centre line: no plane validated, or a deformable body
                   ///< touching itself (layers that slide over each other, both sides' normals estimates)
  Cores,           ///< the closest points of the two bodies' whole polytope cores (polytope_cores.hpp)
};
inline constexpr std::size_t kNormalSourceCount = 14;

/// "face_a", ... (the names used in the trajectory).
[[nodiscard]] const char* normalSourceName(NormalSource s);

struct PlaneSettings {
  int validationRings = 1;           ///< k of the k-ring neighbourhood checked by validation
  double validationTolerance = 0.1;  ///< [-] x (r_a + r_b): how far a centre may lie on the wrong side
  double collinearTolerance = 0.25;  ///< [-] x mean radius: farthest a centre may be from a "line"
  bool rawNormals = false;           ///< use each contact's centre-line normal instead (for comparison)
  /// Take over a rigid group's patches from an earlier step while its contact pairs are the same and the
  /// relative pose of its bodies has turned by less than reuseAngle [rad] and moved by less than
  /// reuseShift x (r_a + r_b) since they were computed (collision/narrow_phase.hpp).
  bool reuse = true;
  double reuseAngle = 2e-2;
  double reuseShift = 0.10;
  /// Between two bodies with whole polytope cores (polytope_cores.hpp), take the plane between the cores for
  /// all their contacts instead of rebuilding each patch's local cores (false: always rebuild, for comparison)
  bool polytopeCores = true;
};

}  // namespace volpar
