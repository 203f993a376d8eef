#include "engine/io/xdmf_writer.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

namespace volpar {

std::string sidecarPath(const std::string& h5Path) {
  std::filesystem::path p(h5Path);
  if (p.extension() == ".h5" || p.extension() == ".hdf5" || p.extension() == ".h5md") p.replace_extension();
  return p.string() + ".xdmf2";
}

Status writeXdmf(const XdmfFrames& f) {
  const std::string out = sidecarPath(f.h5Path);
  const std::string tmp = out + ".tmp";
  // the HDF5 path inside the sidecar is relative to the sidecar
  const std::string h5 = std::filesystem::path(f.h5Path).filename().string();
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
    x << " </Grid>\n</Domain>\n</Xdmf>\n";
    if (!x) return Error{tmp, 0, 0, "failed writing the XDMF sidecar"};
  }
  std::error_code ec;
  std::filesystem::rename(tmp, out, ec);
  if (ec) return Error{out, 0, 0, "cannot replace the XDMF sidecar: " + ec.message()};
  return okStatus();
}

}  // namespace volpar
