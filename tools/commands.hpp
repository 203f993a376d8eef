#pragma once
// The volpar subcommands; main() in volpar.cpp parses the command line with CLI11.

#include <algorithm>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/run_loop.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

namespace volpar::cli {

/// What `run` and `check` allow a scene: folders besides its own that its meshes may lie in, and the memory
/// it may be estimated to need.
struct SceneLimits {
  std::vector<std::string> allowDirs;
  double memoryLimitGiB = 0.0;  ///< 0: 80 % of the machine's memory (defaultMemoryLimit)

  [[nodiscard]] LoadOptions load() const { return LoadOptions{allowDirs}; }
  [[nodiscard]] BuildOptions build() const {
    BuildOptions b;
    if (memoryLimitGiB > 0.0) b.memoryLimit = static_cast<std::uint64_t>(std::min(memoryLimitGiB * 1073741824.0, 1.8e19));
    return b;
  }
};

struct RunArgs {
  std::string scene;
  std::string output;
  bool noOutput = false;
  std::int64_t steps = 0;    ///< 0: the scene's
  double duration = 0.0;     ///< 0: the scene's
  int every = 0;             ///< 0: the scene's
  bool json = false;
  int threads = 0;           ///< 0: defaultThreads()
  double flushSeconds = 2.0; ///< seconds between commits of the trajectory (0: after every frame)
  std::int64_t seed = -1;    ///< -1: the scene's
  std::int64_t killAfterFrames = 0;
  std::int64_t checkpointEvery = 0;  ///< 0: no checkpoints
  std::string resume;                ///< a trajectory whose checkpoint the run continues from
  SceneLimits limits;
};

struct CheckArgs {
  std::string scene;
  std::int64_t steps = 0;
  double duration = 0.0;
  bool json = false;
  int details = 10;
  SceneLimits limits;
};

int run(const RunArgs& args);
int check(const CheckArgs& args);
int inspect(const std::string& path, bool json);
int xdmf(const std::string& path);

/// Reads a trajectory (and with `checkpoint` its checkpoint) in a child process under a time limit first: the
/// HDF5 library can crash or loop on damaged files. An error where the child did not come through.
std::optional<Error> readsSafely(const std::string& path, bool checkpoint = false);
/// Prints "volpar: error: ..." to stderr and returns exit status 1.
int fail(const Error& e);
/// The most steps a run may have (--steps, or --duration / dt), and the steps of a run (engine/run_loop.hpp).
using ::volpar::kMaxSteps;
using ::volpar::stepsFor;

}  // namespace volpar::cli
