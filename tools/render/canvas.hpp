#pragma once
// The sphere rasteriser of volpar render: an RGB image with a depth buffer, drawn into pixel by pixel.

#include <cstdint>
#include <vector>

#include "tools/render/camera.hpp"
#include "tools/render/palette.hpp"

namespace volpar::render {

/// Lighting, in the camera's frame (x right, y up, z towards the viewer): Lambert with an ambient term, and a
/// Blinn-Phong highlight blended towards white (which keeps the hue of the base colour).
struct Lighting {
  Vec3 light = Vec3(-0.4, 0.6, 0.7).normalized();  ///< unit: towards the light
  double ambient = 0.3;                             ///< the share of the colour lit from every side
  double specular = 0.35;                           ///< the most the highlight blends towards white
  double shininess = 32.0;                          ///< Blinn-Phong exponent
};

/// An image of `width` x `height` RGB pixels (rows from the top) with a depth per pixel [m along the view].
/// Everything is drawn with plain double arithmetic in a fixed order: the same calls give the same pixels.
class Canvas {
 public:
  Canvas(int width, int height);

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  /// [height x width x 3] bytes, row by row from the top.
  [[nodiscard]] const std::vector<std::uint8_t>& pixels() const { return rgb_; }
  [[nodiscard]] Rgb at(int x, int y) const;

  /// Fills the image with a vertical gradient and clears the depth buffer.
  void clear(Rgb top, Rgb bottom);
  /// A shaded sphere of world radius `radius` [m] centred on `centre`, depth-tested per pixel.
  void sphere(const Camera& cam, const Vec3& centre, double radius, Rgb colour, const Lighting& light);
  /// The square of half-size `half` [m] centred on `centre` in the plane through it with unit normal `normal`,
  /// a checker of cells `cell` [m] wide aligned with the world origin, depth-tested; drawn only where the
  /// camera sees its upper side (the side the normal points to).
  void floor(const Camera& cam, const Vec3& centre, const Vec3& normal, double half, double cell, Rgb light, Rgb dark,
             const Lighting& lighting);
  /// A line `thickness` pixels wide from a to b; depth-tested when `depthTest`, else drawn over everything.
  void line(const Camera& cam, const Vec3& a, const Vec3& b, int thickness, Rgb colour, bool depthTest);
  /// A filled square of `size` pixels centred on screen point (x, y) with a one-pixel outline, over everything.
  void marker(double x, double y, int size, Rgb fill, Rgb outline);
  /// A filled rectangle in pixels, over everything (clipped to the image).
  void rect(int x, int y, int w, int h, Rgb colour);
  /// One pixel, over everything (ignored outside the image).
  void put(int x, int y, Rgb colour);

 private:
  void plot(int x, int y, double depth, Rgb colour, bool depthTest);

  int width_;
  int height_;
  std::vector<std::uint8_t> rgb_;
  std::vector<double> depth_;
};

}  // namespace volpar::render
