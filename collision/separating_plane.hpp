#pragma once
// The local separating plane of one contact patch (DESIGN section 4, after "Volumetric Particle
// Separating Planes for Collision Detection").
//
// A patch's particles on each side (A = the body with the lower id) are classified by how many unique
// particles each side contributes and whether they are collinear; the smaller side is named first:
//
//   case           particles (small side - large side)        candidate normals (besides the common ones)
//   VertexFace11   1 - 1 (one contact; a look-ahead first)     those of the look-ahead's configuration
//   VertexFace12   1 - 2 or more collinear                     perpendicular from the line to the particle;
//                                                              line x (difference of the contact points)
//   EdgeEdge12     1 - 2 or more collinear, the single         the line of its same-normal neighbours x the
//                  particle lies on an edge of its shape       other line; and the VertexFace12 ones
//   VertexFace13   1 - 3 or more not collinear                 face normal of the large side
//   EdgeEdge22     2 - 2                                       (xA1 - xA0) x (xB1 - xB0); if parallel, the
//                                                              perpendicular between the two lines
//   EdgeEdge23     2 or more collinear - 3 or more collinear   line A x line B (likewise)
//   EdgeFace23     2 - 3 or more not collinear                 face normal of the large side; line x line
//   EdgeFace33     3 or more collinear - 3 or more not coll.   face normal of the non-collinear side
//   FaceFace       3 or more not collinear on both sides       face normals of both sides
//   ParticlePlane  any - a plane                               the plane's normal (exact)
//
// Face normals and lines are the best-fit plane and line of the side's particle centres (for three
// particles the plane is exactly the paper's (x1 - x0) x (x2 - x0)); a side is collinear when every centre
// lies within `collinearTolerance` x radius of its best-fit line. Always offered as well: the mean cached
// surface normal of each side's particles (section 5) and, last, the centre-to-centre direction of the two
// sides. Every candidate is oriented from A to B.
//
// Validation: the plane through the deepest contact point with the candidate normal must have the centres
// of A's patch particles and of their k-ring connector neighbours on its negative side and B's on its
// positive side, within `validationTolerance` x (r_a + r_b). A neighbour counts when it is interior or its
// cached surface normal faces the plane (n . candidate > 0.05 on A, < -0.05 on B): around a concave corner
// (a peg against the wall of a slot) the ring wraps onto the floor of the slot, whose particles lie beyond
// the wall's plane without being in the way. Among the accepted candidates the one with the largest minimum
// margin wins; a patch with none keeps the best and is counted as unvalidated.

#include <array>
#include <cstdint>

#include "engine/core/types.hpp"

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
};
inline constexpr std::size_t kNormalSourceCount = 13;

/// "face_a", ... (the names used in the trajectory).
[[nodiscard]] const char* normalSourceName(NormalSource s);

struct PlaneSettings {
  int validationRings = 1;           ///< k of the k-ring neighbourhood checked by validation
  double validationTolerance = 0.1;  ///< [-] x (r_a + r_b): how far a centre may lie on the wrong side
  double collinearTolerance = 0.25;  ///< [-] x mean radius: farthest a centre may be from a "line"
  int lookAheadSteps = 4;            ///< look-ahead iterations for single-contact patches
  double lookAheadStep = 0.25;       ///< [-] x radius: relative approach per look-ahead iteration
  bool rawNormals = false;           ///< use each contact's centre-line normal instead (for comparison)
  /// Take over a rigid group's patches from an earlier step while its contact pairs are the same and the
  /// relative pose of its bodies has turned by less than reuseAngle [rad] and moved by less than
  /// reuseShift x (r_a + r_b) since they were computed (collision/narrow_phase.hpp).
  bool reuse = true;
  double reuseAngle = 1e-2;
  double reuseShift = 0.05;
};

}  // namespace volpar
