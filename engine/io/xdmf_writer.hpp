#pragma once
// XDMF sidecar for ParaView (docs/trajectory-format.md). XDMF2 flavour read by ParaView's XDMFReader:
// one temporal collection of Polyvertex grids whose geometry is a HyperSlab of
// /particles/all/position/value. Named `<trajectory>.xdmf2` so ParaView picks the right reader.

#include <cstdint>
#include <string>
#include <vector>

#include "engine/core/status.hpp"

namespace volpar {

struct XdmfFrames {
  std::string h5Path;                 ///< the trajectory
  std::size_t particles = 0;
  std::vector<double> time;           ///< [T]
  std::vector<std::int64_t> step;     ///< [T]
};

/// `<trajectory without .h5>.xdmf2`
[[nodiscard]] std::string sidecarPath(const std::string& h5Path);

/// Writes the sidecar for `frames` next to the trajectory (atomically: temp file + rename).
[[nodiscard]] Status writeXdmf(const XdmfFrames& frames);

}  // namespace volpar
