#pragma once
// A curved surface of particles as one rounded core: the points at a distance from a point (a sphere), a
// line (a cylinder's side) or a segment (a capsule: a cylinder's side closed by half-spheres about the
// segment's ends). The surface's normal at a particle is the direction from the nearest point of the core,
// fitted to every particle of the surface at once: a lattice outlines a curve with flat runs of steps, and
// a fit over a few neighbours follows a run, where the whole surface's fit follows the curve.

#include <limits>
#include <span>

#include "volpar/engine/core/types.hpp"

namespace volpar {

struct RoundedCore {
  enum class Kind : std::uint8_t { None, Point, Line, Segment };
  Kind kind = Kind::None;
  Vec3 centre = Vec3::Zero();  ///< the point; a point of the line (or segment's line)
  Vec3 axis = Vec3::Zero();    ///< the line's unit direction
  double lo = -std::numeric_limits<double>::infinity();  ///< the segment's ends along `axis` from `centre`
  double hi = std::numeric_limits<double>::infinity();
  double radius = 0.0;         ///< the surface's distance from the core
  double rms = 0.0;            ///< root mean square of the particles' distances from the fitted surface (of
                               ///< those it takes: a flat end the faces left out is no part of a cylinder)

  /// How far x lies outside the surface (negative inside).
  [[nodiscard]] double distance(const Vec3& x) const;
  /// The outward normal at x: from the core's nearest point to x.
  [[nodiscard]] Vec3 normalAt(const Vec3& x) const;
};

/// The rounded core that fits `points` best (their estimated outward `normals`, one each, pick the
/// cylinder's axis and which particles are its side), or Kind::None where none lies within `tolerance`
/// (root mean square) of them, or of at least half of them: a cylinder's side and those of its ends that are
/// half-spheres.
[[nodiscard]] RoundedCore fitRoundedCore(std::span<const Vec3> points, std::span<const Vec3> normals, double tolerance);

}  // namespace volpar
