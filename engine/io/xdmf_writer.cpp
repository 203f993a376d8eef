#include "volpar/engine/io/xdmf_writer.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <ostream>

namespace volpar {

namespace {

/// Rows `first` .. `first` + `count` - 1 of an HDF5 dataset [rows] or [rows, width] as a HyperSlab item.
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
  x << " NumberType=\"" << type << "\" Precision=\"" << precision << "\" Format=\"HDF\">" << h5 << ":/patches/"
    << dataset << "</DataItem>\n    </DataItem>\n";
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
    rowSlab(x, h5, "point", "Float", 8, rows, first, n, 3);
    x << "   </Geometry>\n"
      << "   <Attribute Name=\"normal\" AttributeType=\"Vector\" Center=\"Node\">\n";
    rowSlab(x, h5, "normal", "Float", 8, rows, first, n, 3);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"depth\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "depth", "Float", 8, rows, first, n, 1);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"case\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "case", "Int", 4, rows, first, n, 1);
    x << "   </Attribute>\n"
      << "   <Attribute Name=\"validated\" AttributeType=\"Scalar\" Center=\"Node\">\n";
    rowSlab(x, h5, "validated", "Char", 1, rows, first, n, 1);
    x << "   </Attribute>\n  </Grid>\n";
  }
  x << " </Grid>\n";
}

}  // namespace

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
