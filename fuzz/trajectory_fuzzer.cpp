// libFuzzer target for the trajectory reader (engine/io/h5md_reader.hpp). The HDF5 library reads files,
// so each input is written to one temporary file per process ($TMPDIR or /tmp,
// volpar-trajectory-fuzz-<pid>.h5, removed at exit; a crash leaves it) and opened with
// H5mdReader::open; when that succeeds, summary() and the particle positions, body positions and body
// orientations of the first, the second and the last frame (and of one past the last) are read; then the
// checkpoint, and where it reads, the world of its scene is built (within 64 MiB) and the checkpoint restored
// into it (World::restoreState checks every array against the world). An error
// is a normal outcome; a crash, a sanitizer report, a hang, running out of memory or an HDF5 object left
// open after the reader is gone is a finding.
//
// Memory that the HDF5 library itself allocates and loses on a malformed file is not a finding:
// LeakSanitizer leaves out leaks allocated inside libhdf5 (__lsan_default_suppressions below), as HDF5
// 1.10 loses some on error paths; the check for objects left open still holds the reader to close what
// it opens.
//
// Inputs that would hang the Debian 12 HDF5 library (1.10.8) in a way already known are skipped, so
// that fuzzing goes on past them: a global heap collection ("GCOL") with a free-space object of size 0
// loops forever in H5HG__cache_heap_deserialize (the object's length is the step to the next one). The
// trajectory reader reaches it through any variable-length string (docs/hardening.md).

#include <hdf5.h>
#include <sanitizer/lsan_interface.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

namespace {

std::string& scratchPath() {
  static std::string path;
  return path;
}

void removeScratch() {
  if (!scratchPath().empty()) std::remove(scratchPath().c_str());
}

std::uint64_t little(const std::uint8_t* p, int bytes) {
  std::uint64_t v = 0;
  for (int k = bytes - 1; k >= 0; --k) v = (v << 8) | p[k];
  return v;
}

/// Whether HDF5 1.10.8 would loop forever decoding one of the input's global heap collections: the
/// objects of a collection are walked as H5HG__cache_heap_deserialize walks them (16-byte collection
/// header, then per object a 2-byte index, 2-byte reference count, 4 reserved bytes and an 8-byte
/// size, the lengths of a volpar file), and an object of index 0 (free space) with size 0 never advances.
bool knownHdf5Hang(const std::uint8_t* data, std::size_t size) {
  constexpr std::size_t kHeader = 16, kObjectHeader = 16;
  for (std::size_t at = 0; at + kHeader <= size; ++at) {
    if (data[at] != 'G' || data[at + 1] != 'C' || data[at + 2] != 'O' || data[at + 3] != 'L') continue;
    const std::uint64_t collection = little(data + at + 8, 8);
    const std::size_t end = at + static_cast<std::size_t>(std::min<std::uint64_t>(collection, size - at));
    std::size_t p = at + kHeader;
    while (p + kObjectHeader <= end) {
      const std::uint64_t index = little(data + p, 2);
      const std::uint64_t length = little(data + p + 8, 8);
      const std::uint64_t need = index > 0 ? kObjectHeader + ((length + 7) & ~std::uint64_t{7}) : length;
      if (need == 0) return true;
      if (need > end - p) break;
      p += static_cast<std::size_t>(need);
    }
  }
  return false;
}

void readFrame(const volpar::H5mdReader& reader, std::size_t frame) {
  if (auto p = reader.positions(frame); !p) (void)p.error().toString();
  if (auto b = reader.bodyPositions(frame); !b) (void)b.error().toString();
  if (auto q = reader.bodyOrientations(frame); !q) (void)q.error().toString();
}

void readTrajectory(const std::string& path) {
  auto reader = volpar::H5mdReader::open(path);
  if (!reader) {
    (void)reader.error().toString();
    return;
  }
  auto summary = (*reader)->summary();
  std::size_t frames = 2;
  if (summary) {
    frames = summary->frames;
  } else {
    (void)summary.error().toString();
  }
  std::vector<std::size_t> wanted{0, 1};
  if (frames > 0) wanted.push_back(frames - 1);
  wanted.push_back(frames);  // one past the last: must be refused, not read
  for (const std::size_t f : wanted) readFrame(**reader, f);
  auto checkpoint = (*reader)->checkpoint();
  if (!checkpoint) {
    (void)checkpoint.error().toString();
    return;
  }
  auto desc = volpar::parseScene(checkpoint->sceneText, scratchPath());
  if (!desc) return;
  volpar::BuildOptions build;
  build.memoryLimit = std::uint64_t{64} << 20;
  auto built = volpar::buildScene(*desc, build);
  if (!built) return;
  if (auto restored = built->world.restoreState(checkpoint->state); restored) static_cast<void>(built->world.step());
}

}  // namespace

extern "C" const char* __lsan_default_suppressions() { return "leak:libhdf5\n"; }

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);  // no HDF5 error stacks on stderr
  const char* tmp = std::getenv("TMPDIR");
  const std::string folder = tmp && *tmp ? tmp : "/tmp";
  scratchPath() = folder + "/volpar-trajectory-fuzz-" + std::to_string(getpid()) + ".h5";
  std::atexit(removeScratch);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (knownHdf5Hang(data, size)) return -1;  // (-1: not added to the corpus)
  {
    std::ofstream out(scratchPath(), std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) {
      std::fprintf(stderr, "trajectory_fuzzer: cannot write %s\n", scratchPath().c_str());
      std::abort();
    }
  }
  readTrajectory(scratchPath());
  H5garbage_collect();  // (HDF5's free lists would otherwise only grow)
  // the reader closes everything it opened: an HDF5 object still open is a leak (and would keep the
  // file open for the next input)
  const ssize_t open = H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_ALL);
  if (open != 0) {
    std::fprintf(stderr, "trajectory_fuzzer: %zd HDF5 objects left open after the reader was destroyed\n", open);
    std::abort();
  }
  return 0;
}
