#include "volpar/engine/io/xdmf_writer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>

namespace volpar {

namespace {

/// Rows `first` .. `first` + `count` - 1 of the HDF5 dataset `dataset` [rows] or [rows, width] as a HyperSlab item.
void rowSlab(std::ostream& x, const std::string& h5, const char* dataset, const char* type, int precision,
             std::int64_t rows, std::int64_t first, std::int64_t count, int width) {
  if (width > 1) {
    x << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << count << " " << width << "\">\n"
      << "     <DataItem Dimensions=\"3 2\" Format=\"XML\" NumberType=\"Int\">" << first << " 0  1 1  " << count
      << " " << width << "</DataItem>\n"
      << "     <DataItem Dimensions=\"" << rows << " " << width << "\"";
  } else {
    x << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << count << "\">\n"
      << "     <DataItem Dimensions=\"3 1\" Format=\"XML\" NumberType=\"Int\">" << first << " 1 " << count
      << "</DataItem>\n"
      << "     <DataItem Dimensions=\"" << rows << "\"";
  }
  x << " NumberType=\"" << type << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << h5 << ":" << dataset
    << "</DataItem>\n    </DataItem>\n";
}

/// The "patches" temporal collection: one Polyvertex grid per frame that has patches.
void writePatchGrids(std::ostream& x, const XdmfFrames& f, const std::string& h5) {
  const std::size_t t = f.time.size();
  std::int64_t rows = 0;
  for (std::size_t i = 0; i < t; ++i) rows = std::max(rows, f.patchOffset[i] + f.patchCount[i]);
  x << " <Grid Name=\"patches\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t i = 0; i < t; ++i) {
    const std::int64_t first = f.patchOffset[i], n = f.patchCount[i];
    if (n <= 0) continue;
    x << "  <Grid Name=\"patches_step_" << f.step[i] << "\" GridType=\"Uniform\">\n"
      << "   <Time Value=\"" << f.time[i] << "\"/>\n"
      << "   <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << n << "\" NodesPerElement=\"1\"/>\n"
      << "   <Geometry GeometryType=\"XYZ\">\n";
    rowSlab(x, h5, "/patches/point", "Float", 8, rows, first, n, 3);
    x << "   </Geometry>\n"
      << "   <Attribute Name=\"normal\" AttributeType=\"Vector\" Center=\"Node\">\n";
    rowSlab(x, h5, "/patches/normal", "Float", 8, rows, first, n, 3);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"depth\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "/patches/depth", "Float", 8, rows, first, n, 1);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"case\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "/patches/case", "Int", 4, rows, first, n, 1);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"validated\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "/patches/validated", "Char", 1, rows, first, n, 1);
    x << "   </Attribute>\n  </Grid>\n";
  }
  x << " </Grid>\n";
}

/// Frame i's particle positions as a HyperSlab of /particles/all/position/value.
void positionSlab(std::ostream& x, const std::string& h5, std::size_t i, std::size_t t, std::size_t p) {
  x << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << p << " 3\">\n"
    << "     <DataItem Dimensions=\"3 3\" Format=\"XML\" NumberType=\"Int\">" << i << " 0 0  1 1 1  1 " << p
    << " 3</DataItem>\n"
    << "     <DataItem Dimensions=\"" << t << " " << p << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
    << h5 << ":/particles/all/position/value</DataItem>\n"
    << "    </DataItem>\n";
}

/// The "connectors" temporal collection: each frame's connectors as lines, /connectors/lines rows
/// offset .. offset + C - 1 (a broken connector is a line of zero length, from one of its particles to
/// itself: ParaView's XDMF reader fails on line topologies whose size changes from one time to the next).
void writeConnectorGrids(std::ostream& x, const XdmfFrames& f, const std::string& h5) {
  const std::size_t t = f.time.size();
  const auto n = static_cast<std::int64_t>(f.connectors);
  if (n == 0 || f.connectorOffset.size() != t) return;
  std::int64_t rows = 0;
  for (const std::int64_t first : f.connectorOffset) rows = std::max(rows, first + n);
  x << " <Grid Name=\"connectors\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
  for (std::size_t i = 0; i < t; ++i) {
    x << "  <Grid Name=\"connectors_step_" << f.step[i] << "\" GridType=\"Uniform\">\n"
      << "   <Time Value=\"" << f.time[i] << "\"/>\n"
      << "   <Topology TopologyType=\"Polyline\" NumberOfElements=\"" << n << "\" NodesPerElement=\"2\">\n";
    rowSlab(x, h5, "/connectors/lines", "Int", 4, rows, f.connectorOffset[i], n, 2);
    x << "   </Topology>\n   <Geometry GeometryType=\"XYZ\">\n";
    positionSlab(x, h5, i, t, f.particles);
    x << "   </Geometry>\n"
      << "   <Attribute Name=\"kind\" AttributeType=\"Scalar\" Center=\"Cell\">\n"
      << "    <DataItem Dimensions=\"" << n << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">" << h5
      << ":/connectors/kind</DataItem>\n"
      << "   </Attribute>\n  </Grid>\n";
  }
  x << " </Grid>\n";
}

/// The "planes" grid: each plane as a square centred where the middle of the particles' bounds projects onto
/// it, as wide as the bounds' diagonal and at least 1 m.
void writePlaneGrid(std::ostream& x, const XdmfFrames& f) {
  const std::size_t n = f.planes.size();
  if (n == 0) return;
  double centre[3], diagonal2 = 0.0;
  for (std::size_t k = 0; k < 3; ++k) {
    centre[k] = 0.5 * (f.bounds.lo[k] + f.bounds.hi[k]);
    diagonal2 += (f.bounds.hi[k] - f.bounds.lo[k]) * (f.bounds.hi[k] - f.bounds.lo[k]);
  }
  const double half = std::max(0.5, std::sqrt(diagonal2));
  x << " <Grid Name=\"planes\" GridType=\"Uniform\">\n"
    << "  <Topology TopologyType=\"Quadrilateral\" NumberOfElements=\"" << n << "\">\n"
    << "   <DataItem Dimensions=\"" << n << " 4\" Format=\"XML\" NumberType=\"Int\">";
  for (std::size_t i = 0; i < n; ++i) x << ' ' << 4 * i << ' ' << 4 * i + 1 << ' ' << 4 * i + 2 << ' ' << 4 * i + 3;
  x << "</DataItem>\n  </Topology>\n  <Geometry GeometryType=\"XYZ\">\n"
    << "   <DataItem Dimensions=\"" << 4 * n << " 3\" Format=\"XML\" NumberType=\"Float\" Precision=\"8\">\n";
  for (const auto& pl : f.planes) {
    double nrm[3] = {pl[0], pl[1], pl[2]};
    const double len = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (double& v : nrm) v = len > 0.0 ? v / len : 0.0;
    const double offset = len > 0.0 ? pl[3] / len : 0.0;
    // the centre projected onto the plane, and two directions along it
    const double h = nrm[0] * centre[0] + nrm[1] * centre[1] + nrm[2] * centre[2] - offset;
    const double o[3] = {centre[0] - h * nrm[0], centre[1] - h * nrm[1], centre[2] - h * nrm[2]};
    const int axis = std::fabs(nrm[0]) < 0.6 ? 0 : 1;  // the world axis least along the normal, roughly
    double u[3] = {0.0, 0.0, 0.0};
    u[axis] = 1.0;
    const double along = u[0] * nrm[0] + u[1] * nrm[1] + u[2] * nrm[2];
    for (int k = 0; k < 3; ++k) u[k] -= along * nrm[k];
    const double ul = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    for (double& v : u) v /= ul;
    const double w[3] = {nrm[1] * u[2] - nrm[2] * u[1], nrm[2] * u[0] - nrm[0] * u[2], nrm[0] * u[1] - nrm[1] * u[0]};
    for (const auto& [su, sw] : {std::pair{-1.0, -1.0}, std::pair{1.0, -1.0}, std::pair{1.0, 1.0}, std::pair{-1.0, 1.0}})
      x << "    " << o[0] + half * (su * u[0] + sw * w[0]) << ' ' << o[1] + half * (su * u[1] + sw * w[1]) << ' '
        << o[2] + half * (su * u[2] + sw * w[2]) << '\n';
  }
  x << "   </DataItem>\n  </Geometry>\n"
    << "  <Attribute Name=\"plane\" AttributeType=\"Scalar\" Center=\"Cell\">\n"
    << "   <DataItem Dimensions=\"" << n << "\" Format=\"XML\" NumberType=\"Int\">";
  for (std::size_t i = 0; i < n; ++i) x << ' ' << i;
  x << "</DataItem>\n  </Attribute>\n </Grid>\n";
}

}  // namespace

void XdmfBounds::add(std::span<const Vec3> x) {
  for (const Vec3& p : x) {
    if (!p.allFinite()) continue;
    for (std::size_t k = 0; k < 3; ++k) {
      const double v = p[static_cast<Eigen::Index>(k)];
      lo[k] = empty ? v : std::min(lo[k], v);
      hi[k] = empty ? v : std::max(hi[k], v);
    }
    empty = false;
  }
}

std::string xmlEscaped(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&apos;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string sidecarPath(const std::string& h5Path) {
  std::filesystem::path p(h5Path);
  if (p.extension() == ".h5" || p.extension() == ".hdf5" || p.extension() == ".h5md") p.replace_extension();
  return p.string() + ".xdmf2";
}

Status writeXdmf(const XdmfFrames& f) {
  const std::string out = sidecarPath(f.h5Path);
  const std::string tmp = out + ".tmp";
  // the HDF5 path inside the sidecar is relative to the sidecar
  const std::string h5 = xmlEscaped(std::filesystem::path(f.h5Path).filename().string());
  const std::size_t t = f.time.size();
  const std::size_t p = f.particles;
  {
    std::ofstream x(tmp, std::ios::binary | std::ios::trunc);
    if (!x) return Error{tmp, 0, 0, "cannot write the XDMF sidecar"};
    x.precision(17);
    x << "<?xml version=\"1.0\" ?>\n<Xdmf Version=\"2.0\">\n<Domain>\n"
      << " <Grid Name=\"particles\" GridType=\"Collection\" CollectionType=\"Temporal\">\n";
    for (std::size_t i = 0; i < t; ++i) {
      x << "  <Grid Name=\"step_" << f.step[i] << "\" GridType=\"Uniform\">\n"
        << "   <Time Value=\"" << f.time[i] << "\"/>\n"
        << "   <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"" << p << "\" NodesPerElement=\"1\"/>\n"
        << "   <Geometry GeometryType=\"XYZ\">\n"
        << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << p << " 3\">\n"
        << "     <DataItem Dimensions=\"3 3\" Format=\"XML\" NumberType=\"Int\">" << i << " 0 0  1 1 1  1 " << p
        << " 3</DataItem>\n"
        << "     <DataItem Dimensions=\"" << t << " " << p << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
        << h5 << ":/particles/all/position/value</DataItem>\n"
        << "    </DataItem>\n   </Geometry>\n"
        << "   <Attribute Name=\"velocity\" AttributeType=\"Vector\" Center=\"Node\">\n"
        << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << p << " 3\">\n"
        << "     <DataItem Dimensions=\"3 3\" Format=\"XML\" NumberType=\"Int\">" << i << " 0 0  1 1 1  1 " << p
        << " 3</DataItem>\n"
        << "     <DataItem Dimensions=\"" << t << " " << p << " 3\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">"
        << h5 << ":/particles/all/velocity/value</DataItem>\n"
        << "    </DataItem>\n   </Attribute>\n"
        << "   <Attribute Name=\"body\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << "    <DataItem ItemType=\"HyperSlab\" Dimensions=\"" << p << "\">\n"
        << "     <DataItem Dimensions=\"3 2\" Format=\"XML\" NumberType=\"Int\">" << i << " 0  1 1  1 " << p
        << "</DataItem>\n"
        << "     <DataItem Dimensions=\"" << t << " " << p << "\" NumberType=\"Int\" Precision=\"4\" Format=\"HDF\">"
        << h5 << ":/particles/all/body/value</DataItem>\n"
        << "    </DataItem>\n   </Attribute>\n"
        << "   <Attribute Name=\"radius\" AttributeType=\"Scalar\" Center=\"Node\">\n"
        << "    <DataItem Dimensions=\"" << p << "\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">" << h5
        << ":/particles/all/radius</DataItem>\n"
        << "   </Attribute>\n  </Grid>\n";
    }
    x << " </Grid>\n";
    if (f.patchOffset.size() == t && f.patchCount.size() == t) writePatchGrids(x, f, h5);
    writeConnectorGrids(x, f, h5);
    writePlaneGrid(x, f);
    x << "</Domain>\n</Xdmf>\n";
    x.close();  // (the last of the text reaches the disk here: a full disk shows now, not later)
    if (!x) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      return Error{tmp, 0, 0, "failed writing the XDMF sidecar (disk full?); the previous sidecar, if any, is kept"};
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) return Error{out, 0, 0, "cannot replace the XDMF sidecar: " + ec.message()};
  return okStatus();
}

}  // namespace volpar
