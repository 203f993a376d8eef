// libFuzzer target for the Wavefront OBJ reader (engine/builders/obj_reader.hpp): any bytes are parsed as
// an OBJ file, at scale 1 and at a scale taken from the input; a mesh that parses is then checked the way
// a scene's mesh shape is (makeSolid, convexFacePlanes, volume, bounds). An error is a normal outcome;
// a crash, a sanitizer report, a hang or running out of memory is a finding.

#include <cstddef>
#include <cstdint>
#include <string>

#include "volpar/engine/builders/obj_reader.hpp"

namespace {

void check(const std::string& text, double scale) {
  auto mesh = volpar::parseObj(text, "fuzz.obj", scale);
  if (!mesh) {
    (void)mesh.error().toString();
    return;
  }
  if (auto solid = mesh->makeSolid(); !solid) {
    (void)solid.error().toString();
    return;
  }
  (void)mesh->convexFacePlanes();
  (void)mesh->volume();
  (void)mesh->bounds();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  check(text, 1.0);
  // a second pass at a scale from the input's length (as a scene's `mesh: {scale}` would give one)
  check(text, 1.0 / static_cast<double>(1 + size % 7) + static_cast<double>(size % 3));
  return 0;
}
