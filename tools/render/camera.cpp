#include "tools/render/camera.hpp"

#include <algorithm>
#include <cmath>

namespace volpar::render {

bool parseView(const std::string& text, View& out) {
  if (text == "iso") out = View::Iso;
  else if (text == "front") out = View::Front;
  else if (text == "side") out = View::Side;
  else if (text == "top") out = View::Top;
  else return false;
  return true;
}

const char* viewName(View v) {
  switch (v) {
    case View::Iso: return "iso";
    case View::Front: return "front";
    case View::Side: return "side";
    case View::Top: return "top";
  }
  return "iso";
}

Camera Camera::framing(View view, const Bounds& bounds, int width, int height, double margin) {
  Camera c;
  c.width = width;
  c.height = height;
  // the direction from the target towards the eye, with z up: front looks along +y (x to the right), side
  // along -x (y to the right), top down -z (x right, y up), iso from the front, right and above
  Vec3 back = Vec3(1.0, -1.0, 1.0).normalized();
  switch (view) {
    case View::Iso: back = Vec3(1.0, -1.0, 1.0).normalized(); break;
    case View::Front: back = Vec3(0.0, -1.0, 0.0); break;
    case View::Side: back = Vec3(1.0, 0.0, 0.0); break;
    case View::Top: back = Vec3(0.0, 0.0, 1.0); break;
  }
  c.forward = -back;
  if (view == View::Top) {
    c.right = Vec3::UnitX();
  } else {
    c.right = c.forward.cross(Vec3::UnitZ()).normalized();
  }
  c.up = c.right.cross(c.forward);
  c.target = bounds.centre();
  const double diag = std::max(bounds.diagonal(), 1e-9);
  c.eye = c.target + back * diag;
  // the eight corners' extent on the screen axes (symmetric about the centre, as the box is)
  double halfX = 0.0;
  double halfY = 0.0;
  for (int k = 0; k < 8; ++k) {
    const Vec3 corner((k & 1) ? bounds.hi.x() : bounds.lo.x(), (k & 2) ? bounds.hi.y() : bounds.lo.y(),
                      (k & 4) ? bounds.hi.z() : bounds.lo.z());
    const Vec3 q = corner - c.target;
    halfX = std::max(halfX, std::abs(q.dot(c.right)));
    halfY = std::max(halfY, std::abs(q.dot(c.up)));
  }
  const double usableX = 0.5 * width * (1.0 - 2.0 * margin);
  const double usableY = 0.5 * height * (1.0 - 2.0 * margin);
  c.scale = std::min(usableX / std::max(halfX, 1e-12), usableY / std::max(halfY, 1e-12));
  return c;
}

ScreenPoint Camera::project(const Vec3& p) const {
  const Vec3 q = p - target;
  return {0.5 * width + scale * q.dot(right), 0.5 * height - scale * q.dot(up), q.dot(forward)};
}

Vec3 Camera::unproject(double x, double y) const {
  return target + right * ((x - 0.5 * width) / scale) - up * ((y - 0.5 * height) / scale);
}

}  // namespace volpar::render
