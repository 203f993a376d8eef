#pragma once
// A small built-in bitmap font for the labels of volpar render (5 x 7 pixels a glyph).

#include <string>

#include "tools/render/canvas.hpp"

namespace volpar::render {

/// Glyph cell in font pixels: 5 x 7 and one column of space.
inline constexpr int kGlyphWidth = 5;
inline constexpr int kGlyphHeight = 7;
inline constexpr int kGlyphAdvance = 6;

// The glyphs: digits, ". - + = : /", space and the letters a e f m p r s t (what the labels use); any other
// character is drawn as a hollow box.

/// Width of `text` in pixels at `scale` (each font pixel drawn as scale x scale).
int textWidth(const std::string& text, int scale);
/// Draws `text` with its top-left corner at (x, y), over everything.
void drawText(Canvas& canvas, int x, int y, const std::string& text, int scale, Rgb colour);

}  // namespace volpar::render
