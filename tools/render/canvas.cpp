#include "tools/render/canvas.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace volpar::render {

namespace {

constexpr double kFar = std::numeric_limits<double>::infinity();

std::uint8_t channel(double v) { return static_cast<std::uint8_t>(std::clamp(std::floor(v + 0.5), 0.0, 255.0)); }

/// `base` lit from `light` at a surface of unit normal `n` (camera frame, z towards the viewer).
Rgb shade(Rgb base, const Vec3& n, const Lighting& light) {
  const double lambert = std::max(0.0, n.dot(light.light));
  const double diffuse = light.ambient + (1.0 - light.ambient) * lambert;
  const Vec3 half = (light.light + Vec3::UnitZ()).normalized();
  const double s = light.specular * std::pow(std::max(0.0, n.dot(half)), light.shininess);
  const auto mix = [&](std::uint8_t c) { return channel((1.0 - s) * diffuse * c + s * 255.0); };
  return {mix(base.r), mix(base.g), mix(base.b)};
}

/// Clips [lo, hi] to [0, n - 1]; false when nothing is left.
bool clipRange(double lo, double hi, int n, int& first, int& last) {
  if (!(hi >= 0.0) || !(lo < static_cast<double>(n))) return false;
  first = static_cast<int>(std::max(0.0, std::floor(lo)));
  last = static_cast<int>(std::min(static_cast<double>(n - 1), std::floor(hi)));
  return first <= last;
}

}  // namespace

Canvas::Canvas(int width, int height)
    : width_(width),
      height_(height),
      rgb_(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3, 0),
      depth_(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), kFar) {}

Rgb Canvas::at(int x, int y) const {
  const std::size_t i = 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x));
  return {rgb_[i], rgb_[i + 1], rgb_[i + 2]};
}

void Canvas::put(int x, int y, Rgb c) {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
  const std::size_t i = 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x));
  rgb_[i] = c.r;
  rgb_[i + 1] = c.g;
  rgb_[i + 2] = c.b;
}

void Canvas::plot(int x, int y, double depth, Rgb c, bool depthTest) {
  if (x < 0 || y < 0 || x >= width_ || y >= height_) return;
  const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x);
  if (depthTest) {
    if (!(depth < depth_[i])) return;
    depth_[i] = depth;
  }
  put(x, y, c);
}

void Canvas::clear(Rgb top, Rgb bottom) {
  std::fill(depth_.begin(), depth_.end(), kFar);
  for (int y = 0; y < height_; ++y) {
    const double t = height_ > 1 ? static_cast<double>(y) / (height_ - 1) : 0.0;
    const auto lerp = [t](std::uint8_t a, std::uint8_t b) { return channel((1.0 - t) * a + t * b); };
    const Rgb c{lerp(top.r, bottom.r), lerp(top.g, bottom.g), lerp(top.b, bottom.b)};
    for (int x = 0; x < width_; ++x) put(x, y, c);
  }
}

void Canvas::sphere(const Camera& cam, const Vec3& centre, double radius, Rgb colour, const Lighting& light) {
  const ScreenPoint s = cam.project(centre);
  // a sphere under a pixel across still covers the pixel its centre is in
  const double rp = std::max(radius * cam.scale, 0.75);
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  if (!clipRange(s.x - rp, s.x + rp, width_, x0, x1) || !clipRange(s.y - rp, s.y + rp, height_, y0, y1)) return;
  for (int y = y0; y <= y1; ++y) {
    const double dy = (y + 0.5 - s.y) / rp;
    for (int x = x0; x <= x1; ++x) {
      const double dx = (x + 0.5 - s.x) / rp;
      const double d2 = dx * dx + dy * dy;
      if (d2 > 1.0) continue;
      // the visible half: the surface point under the pixel, its normal (x right, y up, z to the viewer)
      const double nz = std::sqrt(1.0 - d2);
      const std::size_t i = static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x);
      const double depth = s.depth - radius * nz;
      if (!(depth < depth_[i])) continue;
      depth_[i] = depth;
      put(x, y, shade(colour, Vec3(dx, -dy, nz), light));
    }
  }
}

void Canvas::floor(const Camera& cam, const Vec3& centre, const Vec3& normal, double half, double cell, Rgb light, Rgb dark,
                   const Lighting& lighting) {
  // seen from below or edge-on: not drawn (it would hide what stands on it)
  const double facing = -normal.dot(cam.forward);
  if (!(facing > 1e-6)) return;
  // two directions in the plane: the world axis least along the normal, made perpendicular to it
  const Vec3 n = normal.normalized();
  int least = 0;
  for (int k = 1; k < 3; ++k)
    if (std::abs(n(k)) < std::abs(n(least))) least = k;
  const Vec3 axis = Vec3::Unit(least);
  const Vec3 t1 = n.cross(axis).normalized();
  const Vec3 t2 = n.cross(t1);
  // the square's extent on the screen
  double xlo = kFar, xhi = -kFar, ylo = kFar, yhi = -kFar;
  for (int k = 0; k < 4; ++k) {
    const Vec3 corner = centre + t1 * ((k & 1) ? half : -half) + t2 * ((k & 2) ? half : -half);
    const ScreenPoint s = cam.project(corner);
    xlo = std::min(xlo, s.x);
    xhi = std::max(xhi, s.x);
    ylo = std::min(ylo, s.y);
    yhi = std::max(yhi, s.y);
  }
  int x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  if (!clipRange(xlo, xhi, width_, x0, x1) || !clipRange(ylo, yhi, height_, y0, y1)) return;
  const Vec3 nCam(n.dot(cam.right), n.dot(cam.up), -n.dot(cam.forward));
  const Rgb lit[2] = {shade(light, nCam, lighting), shade(dark, nCam, lighting)};
  const double offset = n.dot(centre);
  const double denom = n.dot(cam.forward);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      // the viewing ray through the pixel's centre meets the plane at depth t
      const Vec3 o = cam.unproject(x + 0.5, y + 0.5);
      const double t = (offset - n.dot(o)) / denom;
      const Vec3 p = o + cam.forward * t;
      const Vec3 q = p - centre;
      if (std::abs(q.dot(t1)) > half || std::abs(q.dot(t2)) > half) continue;
      const double u = std::clamp(std::floor(p.dot(t1) / cell), -1e15, 1e15);
      const double v = std::clamp(std::floor(p.dot(t2) / cell), -1e15, 1e15);
      const auto parity = (static_cast<long long>(u) + static_cast<long long>(v)) & 1;
      plot(x, y, t, lit[parity], true);
    }
  }
}

void Canvas::line(const Camera& cam, const Vec3& a, const Vec3& b, int thickness, Rgb colour, bool depthTest) {
  const ScreenPoint pa = cam.project(a);
  const ScreenPoint pb = cam.project(b);
  const double dx = pb.x - pa.x;
  const double dy = pb.y - pa.y;
  // one sample per pixel along the longer axis (at most a few image sizes: longer lines leave the image)
  const double along = std::max(std::abs(dx), std::abs(dy));
  const int limit = 4 * (width_ + height_);
  const int steps = static_cast<int>(std::min(std::ceil(along), static_cast<double>(limit)));
  const int lo = -(thickness - 1) / 2;
  const int hi = thickness / 2;
  for (int k = 0; k <= steps; ++k) {
    const double t = steps > 0 ? static_cast<double>(k) / steps : 0.0;
    const double x = pa.x + t * dx;
    const double y = pa.y + t * dy;
    const double depth = pa.depth + t * (pb.depth - pa.depth);
    if (!(x > -thickness && y > -thickness && x < width_ + thickness && y < height_ + thickness)) continue;
    const int cx = static_cast<int>(std::floor(x));
    const int cy = static_cast<int>(std::floor(y));
    for (int oy = lo; oy <= hi; ++oy)
      for (int ox = lo; ox <= hi; ++ox) plot(cx + ox, cy + oy, depth, colour, depthTest);
  }
}

void Canvas::marker(double x, double y, int size, Rgb fill, Rgb outline) {
  if (!(x > -size && y > -size && x < width_ + size && y < height_ + size)) return;
  const int x0 = static_cast<int>(std::floor(x)) - size / 2;
  const int y0 = static_cast<int>(std::floor(y)) - size / 2;
  rect(x0 - 1, y0 - 1, size + 2, size + 2, outline);
  rect(x0, y0, size, size, fill);
}

void Canvas::rect(int x, int y, int w, int h, Rgb colour) {
  for (int j = std::max(y, 0); j < std::min(y + h, height_); ++j)
    for (int i = std::max(x, 0); i < std::min(x + w, width_); ++i) put(i, j, colour);
}

}  // namespace volpar::render
