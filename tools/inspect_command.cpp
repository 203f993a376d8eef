// volpar inspect and volpar xdmf: reading trajectories back.

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <thread>

#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/io/xdmf_writer.hpp"
#include "tools/commands.hpp"
#include "tools/json_writer.hpp"

namespace volpar::cli {

int fail(const Error& e) {
  std::fprintf(stderr, "volpar: error: %s\n", e.toString().c_str());
  return 1;
}


/// HDF5 itself can crash or loop forever on some damaged files (a variable-length string pointing at a heap
/// object that is not there, a heap object of size zero). So a trajectory is first read in a child process
/// under a time limit, silenced; the same reading is done here only when the child came through it.
std::optional<Error> readsSafely(const std::string& path, bool checkpoint) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  const double seconds = 20.0 + (ec ? 0.0 : static_cast<double>(size) / 20e6);
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid < 0) return std::nullopt;  // no child to spare: read directly
  if (pid == 0) {
    const int devnull = ::open("/dev/null", O_WRONLY);
    if (devnull >= 0) {
      dup2(devnull, STDOUT_FILENO);
      dup2(devnull, STDERR_FILENO);
    }
    auto reader = H5mdReader::open(path);
    if (reader) {
      auto s = (*reader)->summary();
      if (s && s->frames > 0) {
        static_cast<void>((*reader)->positions(0));
        static_cast<void>((*reader)->positions(s->frames - 1));
      }
      if (checkpoint) static_cast<void>((*reader)->checkpoint());
    }
    _exit(0);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return Error{path, 0, 0, "reading it did not finish in " + std::to_string(static_cast<int>(seconds)) +
                                   " s (the HDF5 library loops on it); the file is damaged"};
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (WIFSIGNALED(status))
    return Error{path, 0, 0, "the HDF5 library crashed reading it (signal " + std::to_string(WTERMSIG(status)) +
                                 "); the file is damaged"};
  return std::nullopt;
}

int inspect(const std::string& path, bool json) {
  if (const auto damaged = readsSafely(path)) return fail(*damaged);
  auto reader = H5mdReader::open(path);
  if (!reader) return fail(reader.error());
  auto sum = (*reader)->summary();
  if (!sum) return fail(sum.error());
  const TrajectorySummary& s = *sum;
  const double e0 = s.total.empty() ? 0.0 : s.total.front();
  const double e1 = s.total.empty() ? 0.0 : s.total.back();
  if (json) {
    JsonWriter j;
    j.begin()
        .field("file", path)
        .field("creator", s.creatorName)
        .field("version", s.creatorVersion)
        .field("scene", s.sceneName)
        .field("frames", s.frames)
        .field("torn_frames", s.tornFrames)
        .field("particles", s.particles)
        .field("bodies", s.bodies)
        .field("time_start", s.time.empty() ? 0.0 : s.time.front())
        .field("time_end", s.time.empty() ? 0.0 : s.time.back())
        .field("energy_start", e0)
        .field("energy_end", e1)
        .field("checkpoint_step", s.checkpointStep)
        .field("dt", s.dt)
        .field("bodies_alive", s.bodiesAlive)
        .field("breakages", s.breakages)
        .field("contacts", s.contacts)
        .field("patches", s.patches)
        .field("connectors", s.connectors)
        .end();
    std::cout << j.str() << std::endl;
    return 0;
  }
  std::printf("file         %s\n", path.c_str());
  std::printf("written by   %s %s\n", s.creatorName.c_str(), s.creatorVersion.c_str());
  std::printf("scene        %s\n", s.sceneName.c_str());
  std::printf("frames       %zu", s.frames);
  if (!s.time.empty())
    std::printf(" (steps %lld..%lld, t = %.6g..%.6g s)", static_cast<long long>(s.step.front()),
                static_cast<long long>(s.step.back()), s.time.front(), s.time.back());
  std::printf("\n");
  if (s.tornFrames > 0)
    std::printf("             (then %zu written after the last flush, ignored: the run was killed or its disk filled)\n", s.tornFrames);
  if (s.dt > 0.0) std::printf("dt           %.6g s\n", s.dt);
  std::printf("particles    %zu\n", s.particles);
  std::printf("bodies       %zu, %zu in the last frame (bodies that broke apart are replaced by their fragments)\n", s.bodies, s.bodiesAlive);
  std::printf("connectors   %zu, %zu broke by the last frame\n", s.connectors, s.breakages);
  if (s.contacts >= 0) std::printf("contacts     %lld in the last frame, in %lld patches\n", static_cast<long long>(s.contacts), static_cast<long long>(s.patches));
  if (!s.total.empty())
    std::printf("energy       %.9g J -> %.9g J (kinetic %.6g -> %.6g J)\n", e0, e1, s.kinetic.front(), s.kinetic.back());
  if (s.checkpointStep >= 0)
    std::printf("checkpoint   step %lld (volpar run --resume %s goes on from it)\n", static_cast<long long>(s.checkpointStep), path.c_str());
  return 0;
}

int xdmf(const std::string& path) {
  if (const auto damaged = readsSafely(path)) return fail(*damaged);
  auto reader = H5mdReader::open(path);
  if (!reader) return fail(reader.error());
  auto sum = (*reader)->summary();
  if (!sum) return fail(sum.error());
  XdmfFrames f;
  f.h5Path = path;
  f.particles = sum->particles;
  f.time = sum->time;
  f.step = sum->step;
  f.patchOffset = sum->patchOffset;
  f.patchCount = sum->patchCount;
  f.connectors = sum->connectors;
  f.connectorOffset = sum->connectorLineOffset;
  auto planes = (*reader)->planes();
  if (!planes) return fail(planes.error());
  f.planes = std::move(planes.value());
  // the particles' bounds, from the first and the last complete frame
  for (const std::size_t frame : {std::size_t{0}, sum->frames - 1}) {
    auto x = (*reader)->positions(frame);
    if (!x) return fail(x.error());
    f.bounds.add(*x);
  }
  if (auto ok = writeXdmf(f); !ok) return fail(ok.error());
  std::printf("%s\n", sidecarPath(path).c_str());
  return 0;
}

}  // namespace volpar::cli
