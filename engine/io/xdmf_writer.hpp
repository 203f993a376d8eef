#pragma once
// XDMF sidecar for ParaView (docs/trajectory-format.md). XDMF2 flavour read by ParaView's XDMFReader:
// a temporal collection "particles" of Polyvertex grids whose geometry is a HyperSlab of
// /particles/all/position/value, and a temporal collection "patches" whose grids are the rows of
// /patches of a frame (points, with normal, depth, case and validated). A frame without patches has no
// patch grid (an empty HyperSlab is not valid XDMF): at its time the reader's "patches" block is empty.
// A temporal collection "connectors" draws each frame's connectors as lines between their particles
// (/connectors/lines, a broken one as a line of zero length), with their kind; a grid "planes" draws each
// plane as a square around the particles' bounds.
// Named `<trajectory>.xdmf2` so ParaView picks the right reader.

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// The box around the particles of the frames drawn (the planes are drawn as squares around it).
struct XdmfBounds {
  std::array<double, 3> lo{0.0, 0.0, 0.0}, hi{0.0, 0.0, 0.0};
  bool empty = true;
  /// Grows the box to take in `x`'s finite points.
  void add(std::span<const Vec3> x);
};

struct XdmfFrames {
  std::string h5Path;                 ///< the trajectory
  std::size_t particles = 0;
  std::vector<double> time;           ///< [T]
  std::vector<std::int64_t> step;     ///< [T]
  /// Per frame: its first row and number of rows in /patches, [T] each. Empty for a trajectory without
  /// /patches (no "patches" collection is written then).
  std::vector<std::int64_t> patchOffset;
  std::vector<std::int64_t> patchCount;
  /// Connectors (C) and, per frame, the first of its C rows in /connectors/lines, [T]; no "connectors"
  /// collection where C is 0 or the offsets are not one per frame (a trajectory without /connectors/lines).
  std::size_t connectors = 0;
  std::vector<std::int64_t> connectorOffset;
  /// The scene's planes: normal (3) and offset, drawn as squares around the particles' bounds.
  std::vector<std::array<double, 4>> planes;
  XdmfBounds bounds;
};

/// `text` with & < > " and ' written as XML entities (for names inside attributes and elements).
[[nodiscard]] std::string xmlEscaped(const std::string& text);
/// `<trajectory without .h5>.xdmf2`
[[nodiscard]] std::string sidecarPath(const std::string& h5Path);

/// Writes the sidecar for `frames` next to the trajectory (atomically: temp file + rename).
[[nodiscard]] Status writeXdmf(const XdmfFrames& frames);

}  // namespace volpar
