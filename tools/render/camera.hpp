#pragma once
// The camera of volpar render: orthographic, framed once on the bounds of everything rendered.

#include <array>
#include <string>

#include "volpar/engine/core/types.hpp"

namespace volpar::render {

/// Where the camera looks from. World z is up in every view.
enum class View { Iso, Front, Side, Top };

/// Parses "iso", "front", "side" or "top".
bool parseView(const std::string& text, View& out);
const char* viewName(View v);

/// An axis-aligned box [m], world frame.
struct Bounds {
  Vec3 lo = Vec3::Constant(1e300);
  Vec3 hi = Vec3::Constant(-1e300);
  void add(const Vec3& p, double r) {
    lo = lo.cwiseMin(p - Vec3::Constant(r));
    hi = hi.cwiseMax(p + Vec3::Constant(r));
  }
  [[nodiscard]] bool empty() const { return !(lo.x() <= hi.x()); }
  [[nodiscard]] Vec3 centre() const { return 0.5 * (lo + hi); }
  [[nodiscard]] double diagonal() const { return (hi - lo).norm(); }
};

/// A point on the screen: column and row in pixels (row 0 at the top; pixel (i, j) covers [i, i+1) x [j, j+1)),
/// and its depth [m] along the view direction (larger is farther).
struct ScreenPoint {
  double x = 0.0;
  double y = 0.0;
  double depth = 0.0;
};

/// Orthographic projection: a point p lands at
///   x = width / 2 + scale * (p - target) . right,   y = height / 2 - scale * (p - target) . up,
///   depth = (p - target) . forward,
/// with forward = -(eye - target) / |eye - target| and right, up, forward an orthonormal right-handed frame
/// (right x up = -forward). Orthographic because sizes then do not depend on depth: the framing from the bounds
/// is exact and stays so over an animation, every sphere is a circle of radius r * scale, and the projection is
/// one linear map that a test (or a reader) can apply to any point.
class Camera {
 public:
  /// A camera looking along `view` at the centre of `bounds`, with the scale that fits the box's eight corners
  /// in a `width` x `height` image with a margin of `margin` (a fraction of each side).
  static Camera framing(View view, const Bounds& bounds, int width, int height, double margin = 0.06);

  [[nodiscard]] ScreenPoint project(const Vec3& p) const;
  /// The world point on the camera's plane through `target` seen at screen position (x, y).
  [[nodiscard]] Vec3 unproject(double x, double y) const;

  Vec3 eye;       ///< [m] world frame, at the distance of the bounds' diagonal from target
  Vec3 target;    ///< [m] the centre of the framed bounds
  Vec3 forward;   ///< unit: the view direction
  Vec3 right;     ///< unit: screen x
  Vec3 up;        ///< unit: screen -y (rows grow downwards)
  double scale = 1.0;  ///< [pixels/m]
  int width = 0;
  int height = 0;
};

}  // namespace volpar::render
