#pragma once
// The colours of volpar render: bodies, static bodies, floor, background, overlays.

#include <array>
#include <cstddef>
#include <cstdint>

namespace volpar::render {

/// An 8-bit sRGB colour.
struct Rgb {
  std::uint8_t r = 0;
  std::uint8_t g = 0;
  std::uint8_t b = 0;
  bool operator==(const Rgb&) const = default;
};

/// The body palette: Tableau's 20 categorical colours (matplotlib's "tab20") without its two greys, the nine
/// saturated ones first and their nine light companions after, so that neighbouring body indices (a body and
/// the fragments that break off it, which take the next rows) differ in hue. Body b takes entry b mod 18.
inline constexpr std::array<Rgb, 18> kBodyPalette{{
    {0x1f, 0x77, 0xb4}, {0xff, 0x7f, 0x0e}, {0x2c, 0xa0, 0x2c}, {0xd6, 0x27, 0x28}, {0x94, 0x67, 0xbd},
    {0x8c, 0x56, 0x4b}, {0xe3, 0x77, 0xc2}, {0xbc, 0xbd, 0x22}, {0x17, 0xbe, 0xcf}, {0xae, 0xc7, 0xe8},
    {0xff, 0xbb, 0x78}, {0x98, 0xdf, 0x8a}, {0xff, 0x98, 0x96}, {0xc5, 0xb0, 0xd5}, {0xc4, 0x9c, 0x94},
    {0xf7, 0xb6, 0xd2}, {0xdb, 0xdb, 0x8d}, {0x9e, 0xda, 0xe5},
}};

inline constexpr Rgb kStaticBody{0x8c, 0x8c, 0x8c};           ///< static bodies: grey
inline constexpr Rgb kFloorLight{0xd2, 0xd2, 0xd2};           ///< the planes' checker
inline constexpr Rgb kFloorDark{0xa8, 0xa8, 0xa8};
inline constexpr Rgb kBackgroundTop{0x3a, 0x40, 0x4c};        ///< a vertical gradient, top to bottom
inline constexpr Rgb kBackgroundBottom{0x18, 0x1a, 0x20};
inline constexpr Rgb kLabelBox{0x10, 0x12, 0x16};             ///< behind the time label
inline constexpr Rgb kLabelText{0xff, 0xff, 0xff};
inline constexpr Rgb kRod{0x20, 0x20, 0x20};                  ///< connectors by kind
inline constexpr Rgb kSpring{0xc8, 0xc8, 0xc8};
inline constexpr Rgb kBond{0xff, 0xd7, 0x00};
inline constexpr Rgb kContact{0xff, 0xff, 0xff};              ///< contact points (outlined in black)
inline constexpr Rgb kNormal{0xff, 0x00, 0xff};               ///< patch normals

/// The colour of body `index`.
inline Rgb bodyColour(std::size_t index, bool isStatic) {
  return isStatic ? kStaticBody : kBodyPalette[index % kBodyPalette.size()];
}

}  // namespace volpar::render
