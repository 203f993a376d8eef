// volpar: run scenes headless, inspect trajectories.

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "engine/core/version.hpp"
#include "engine/io/h5md_reader.hpp"
#include "engine/io/xdmf_writer.hpp"
#include "engine/run_loop.hpp"
#include "engine/scene/scene_build.hpp"
#include "engine/scene/scene_loader.hpp"
#include "tools/json_writer.hpp"

namespace {

std::atomic<bool> gStop{false};

extern "C" void onSignal(int) { gStop.store(true); }

int fail(const volpar::Error& e) {
  std::fprintf(stderr, "volpar: error: %s\n", e.toString().c_str());
  return 1;
}

void progressBar(std::int64_t done, std::int64_t total) {
  const int width = 40;
  const double f = total > 0 ? static_cast<double>(done) / static_cast<double>(total) : 1.0;
  const int filled = static_cast<int>(f * width);
  std::fprintf(stderr, "\r[%s%s] %5.1f%% step %lld/%lld", std::string(static_cast<std::size_t>(filled), '#').c_str(),
               std::string(static_cast<std::size_t>(width - filled), ' ').c_str(), 100.0 * f,
               static_cast<long long>(done), static_cast<long long>(total));
  if (done >= total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

struct RunArgs {
  std::string scene;
  std::string output;
  bool noOutput = false;
  std::int64_t steps = 0;
  double duration = 0.0;
  int every = 0;
  bool json = false;
  std::int64_t killAfterFrames = 0;
};

int runCommand(const RunArgs& args) {
  auto desc = volpar::loadScene(args.scene);
  if (!desc) return fail(desc.error());
  auto built = volpar::buildScene(*desc);
  if (!built) return fail(built.error());
  volpar::World& world = built->world;

  volpar::RunOptions options;
  options.steps = desc->stepCount();
  if (args.steps > 0) options.steps = args.steps;
  if (args.duration > 0.0) options.steps = std::max<std::int64_t>(1, std::llround(args.duration / desc->dt));
  options.every = args.every > 0 ? args.every : desc->outputEvery;
  if (!args.noOutput)
    options.output = args.output.empty() ? std::filesystem::path(args.scene).stem().string() + ".h5" : args.output;
  if (isatty(STDERR_FILENO)) options.progress = progressBar;
  options.stop = &gStop;
  options.killAfterFrames = args.killAfterFrames;
  // Ctrl-C, kill, a scheduler's time limit or a closed terminal: finish the step and close the file
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, onSignal);

  volpar::TrajectoryMeta meta;
  meta.sceneName = desc->name;
  meta.sceneFile = args.scene;
  meta.sceneText = desc->text;
  meta.extraFiles = built->meshFiles;
  meta.outputEvery = options.every;
  meta.stepsRequested = options.steps;

  auto summary = volpar::runWorld(world, meta, options);
  if (!summary) return fail(summary.error());
  const volpar::RunSummary& s = *summary;
  const double drift = s.energyEnd.total() - s.energyStart.total();
  if (args.json) {
    volpar::JsonWriter j;
    j.begin()
        .field("scene", desc->name)
        .field("steps", s.steps)
        .field("frames", s.frames)
        .field("bodies", s.bodies)
        .field("particles", s.particles)
        .field("wall_seconds", s.wallSeconds)
        .field("step_seconds", s.stepSeconds)
        .field("steps_per_second", s.stepsPerSecond)
        .field("simulated_seconds", world.time())
        .field("energy_start", s.energyStart.total())
        .field("energy_end", s.energyEnd.total())
        .field("energy_drift", drift)
        .field("interrupted", s.interrupted)
        .field("output", s.output);
    j.begin("stage_seconds")
        .field("integrate_velocities", s.stageTimes.integrateVelocities)
        .field("integrate_positions", s.stageTimes.integratePositions)
        .end();
    j.end();
    std::cout << j.str() << std::endl;
  } else {
    std::printf("scene        %s (%s)\n", desc->name.c_str(), args.scene.c_str());
    std::printf("bodies       %zu, particles %zu\n", s.bodies, s.particles);
    std::printf("steps        %lld (t = %.6g s)%s\n", static_cast<long long>(s.steps), world.time(),
                s.interrupted ? ", interrupted" : "");
    std::printf("speed        %.1f steps/s (%.3f s stepping, %.3f s wall)\n", s.stepsPerSecond, s.stepSeconds,
                s.wallSeconds);
    std::printf("stages       integrate velocities %.3f s, integrate positions %.3f s\n",
                s.stageTimes.integrateVelocities, s.stageTimes.integratePositions);
    std::printf("energy       %.9g J -> %.9g J (drift %.3g J)\n", s.energyStart.total(), s.energyEnd.total(), drift);
    if (!s.output.empty())
      std::printf("trajectory   %s (%zu frames), sidecar %s\n", s.output.c_str(), s.frames,
                  volpar::sidecarPath(s.output).c_str());
  }
  return s.interrupted ? 130 : 0;
}

int inspectCommand(const std::string& path, bool json) {
  auto reader = volpar::H5mdReader::open(path);
  if (!reader) return fail(reader.error());
  auto sum = (*reader)->summary();
  if (!sum) return fail(sum.error());
  const volpar::TrajectorySummary& s = *sum;
  const double e0 = s.total.empty() ? 0.0 : s.total.front();
  const double e1 = s.total.empty() ? 0.0 : s.total.back();
  if (json) {
    volpar::JsonWriter j;
    j.begin()
        .field("file", path)
        .field("creator", s.creatorName)
        .field("version", s.creatorVersion)
        .field("scene", s.sceneName)
        .field("frames", s.frames)
        .field("particles", s.particles)
        .field("bodies", s.bodies)
        .field("time_start", s.time.empty() ? 0.0 : s.time.front())
        .field("time_end", s.time.empty() ? 0.0 : s.time.back())
        .field("energy_start", e0)
        .field("energy_end", e1)
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
  std::printf("\nparticles    %zu\nbodies       %zu\n", s.particles, s.bodies);
  if (!s.total.empty())
    std::printf("energy       %.9g J -> %.9g J (kinetic %.6g -> %.6g J)\n", e0, e1, s.kinetic.front(), s.kinetic.back());
  return 0;
}

int xdmfCommand(const std::string& path) {
  auto reader = volpar::H5mdReader::open(path);
  if (!reader) return fail(reader.error());
  auto sum = (*reader)->summary();
  if (!sum) return fail(sum.error());
  volpar::XdmfFrames f;
  f.h5Path = path;
  f.particles = sum->particles;
  f.time = sum->time;
  f.step = sum->step;
  if (auto ok = volpar::writeXdmf(f); !ok) return fail(ok.error());
  std::printf("%s\n", volpar::sidecarPath(path).c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"volpar: volumetric particle physics engine"};
  app.set_version_flag("--version", std::string(volpar::kName) + " " + volpar::kVersion);
  app.require_subcommand(1);

  RunArgs run;
  CLI::App* runCmd = app.add_subcommand("run", "Run a scene headless and write an H5MD trajectory");
  runCmd->add_option("scene", run.scene, "Scene file (YAML)")->required()->check(CLI::ExistingFile);
  runCmd->add_option("-o,--output", run.output, "Trajectory file (default: <scene name>.h5 in the current folder)");
  auto* noOut = runCmd->add_flag("--no-output", run.noOutput, "Do not write a trajectory");
  auto* steps = runCmd->add_option("--steps", run.steps, "Number of steps (overrides the scene)")->check(CLI::PositiveNumber);
  auto* duration = runCmd->add_option("--duration", run.duration, "Simulated time [s] (overrides the scene)")
                       ->check(CLI::PositiveNumber);
  steps->excludes(duration);
  runCmd->add_option("--every", run.every, "Write a frame every K steps (overrides the scene)")->check(CLI::PositiveNumber);
  runCmd->add_flag("--json", run.json, "Print one JSON object with the summary on stdout");
  noOut->excludes(runCmd->get_option("--output"));
  // testing aid, not shown in --help
  runCmd->add_option("--kill-after-frames", run.killAfterFrames)->group("");

  std::string inspectPath;
  bool inspectJson = false;
  CLI::App* inspectCmd = app.add_subcommand("inspect", "Summarise a trajectory file");
  inspectCmd->add_option("file", inspectPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);
  inspectCmd->add_flag("--json", inspectJson, "Print one JSON object on stdout");

  std::string xdmfPath;
  CLI::App* xdmfCmd = app.add_subcommand("xdmf", "(Re)write the ParaView XDMF sidecar of a trajectory");
  xdmfCmd->add_option("file", xdmfPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);

  CLI11_PARSE(app, argc, argv);
  if (runCmd->parsed()) return runCommand(run);
  if (inspectCmd->parsed()) return inspectCommand(inspectPath, inspectJson);
  if (xdmfCmd->parsed()) return xdmfCommand(xdmfPath);
  return 0;
}
