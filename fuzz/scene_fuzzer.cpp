// libFuzzer target for the scene loader (engine/scene/scene_loader.hpp): any bytes are parsed as a scene
// file. A scene that parses is also built (engine/scene/scene_build.hpp) when building it is cheap: no
// mesh shape (mesh files come from the file system, not from the input), at most kMaxBodies bodies and
// at most about kMaxParticles lattice sites or listed particles in all, estimated from the description
// before building. A scene may legitimately ask for up to 50 million particles, so larger scenes are
// only parsed. An error is a normal outcome; a crash, a sanitizer report, a failed assertion, a hang or
// running out of memory is a finding.
//
// The scene's path lies in a folder that does not exist (a unique temporary name, $TMPDIR or /tmp,
// volpar-scene-fuzz-XXXXXX, made and removed at start), so no relative mesh file resolves, not even
// through '..'.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <variant>

#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

namespace {

constexpr double kMaxBodies = 64;
constexpr double kMaxParticles = 1500;

std::string& sceneFolder() {
  static std::string folder;
  return folder;
}

/// Lattice sites along one side of `extent` [m] at `spacing` [m], generously rounded up.
double sitesAlong(double extent, double spacing) { return extent / spacing + 2.0; }

/// An upper estimate of the particles one copy of `body` creates; negative when it is not built here.
double particleEstimate(const volpar::BodyDesc& body) {
  if (const auto* list = std::get_if<volpar::ParticlesDesc>(&body.shape))
    return static_cast<double>(list->positions.size());
  volpar::Vec3 extent;
  if (const auto* b = std::get_if<volpar::BoxDesc>(&body.shape)) {
    extent = b->size;
  } else if (const auto* s = std::get_if<volpar::SphereDesc>(&body.shape)) {
    extent = volpar::Vec3::Constant(2.0 * s->radius);
  } else if (const auto* c = std::get_if<volpar::CylinderDesc>(&body.shape)) {
    extent = volpar::Vec3(2.0 * c->radius, 2.0 * c->radius, c->height);
  } else if (const auto* cap = std::get_if<volpar::CapsuleDesc>(&body.shape)) {
    extent = volpar::Vec3(2.0 * cap->radius, 2.0 * cap->radius, cap->length + 2.0 * cap->radius);
  } else {
    return -1.0;  // a mesh
  }
  const double spacing = body.fill.spacing > 0.0 ? body.fill.spacing : 2.0 * body.fill.radius;
  if (!(spacing > 0.0)) return -1.0;
  // an HCP lattice packs sqrt(2) times as many sites as a cubic one, in offset layers: twice as many
  const double perCell = body.fill.lattice == volpar::Lattice::Hcp ? 2.0 : 1.0;
  return perCell * sitesAlong(extent.x(), spacing) * sitesAlong(extent.y(), spacing) * sitesAlong(extent.z(), spacing);
}

bool cheapToBuild(const volpar::SceneDesc& desc) {
  double bodies = 0.0, particles = 0.0;
  for (const volpar::BodyDesc& b : desc.bodies) {
    const double copies = static_cast<double>(b.repeat.count[0]) * b.repeat.count[1] * b.repeat.count[2];
    const double each = particleEstimate(b);
    if (!(each >= 0.0)) return false;
    bodies += copies;
    particles += copies * each;
    if (!(bodies <= kMaxBodies && particles <= kMaxParticles)) return false;
  }
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  const char* tmp = std::getenv("TMPDIR");
  std::string pattern = std::string(tmp && *tmp ? tmp : "/tmp") + "/volpar-scene-fuzz-XXXXXX";
  if (mkdtemp(pattern.data()) == nullptr || rmdir(pattern.c_str()) != 0) std::abort();
  sceneFolder() = pattern;
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto desc = volpar::parseScene(text, sceneFolder() + "/fuzz.yaml");
  if (!desc) {
    (void)desc.error().toString();
    return 0;
  }
  (void)desc->stepCount();
  for (const volpar::BodyDesc& b : desc->bodies) (void)desc->normalsOf(b);
  if (!cheapToBuild(*desc)) return 0;
  auto built = volpar::buildScene(*desc);
  if (!built) (void)built.error().toString();
  return 0;
}
