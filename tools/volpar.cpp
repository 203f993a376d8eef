// volpar: run scenes headless, cross-check them against FCL, inspect trajectories.

#include <CLI/CLI.hpp>

#include <charconv>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <exception>
#include <new>

#include "volpar/engine/core/version.hpp"
#include "tools/commands.hpp"
#include "tools/render_command.hpp"

namespace {

/// A whole number from `lo` to `hi` written in decimal digits (no sign, exponent or fraction), or the reason not.
CLI::Validator wholeNumber(long long lo, long long hi) {
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        long long v = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, v);
        if (ec == std::errc::result_out_of_range || (ec == std::errc() && ptr == end && (v < lo || v > hi)))
          return "expected a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) + ", got " + text;
        if (ec != std::errc() || ptr != end) return "expected a whole number, got " + text;
        return {};
      },
      "INT in [" + std::to_string(lo) + " - " + std::to_string(hi) + "]");
}

/// A finite number above zero.
CLI::Validator positiveFinite() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        double v = 0.0;
        const char* end = text.data() + text.size();
        const auto [ptr, ec] = std::from_chars(text.data(), end, v);
        if (ec != std::errc() || ptr != end) return "expected a number, got " + text;
        if (!std::isfinite(v) || !(v > 0.0)) return "expected a finite number above 0, got " + text;
        return {};
      },
      "FLOAT > 0");
}

}  // namespace

int main(int argc, char** argv) {
  // a file-size limit (ulimit -f) makes a write fail like a full disk, reported, instead of killing volpar
  std::signal(SIGXFSZ, SIG_IGN);
  using namespace volpar::cli;
  CLI::App app{"volpar: volumetric particle physics engine"};
  app.set_version_flag("--version", std::string(volpar::kName) + " " + volpar::kVersion);
  app.require_subcommand(1);

  RunArgs run;
  CLI::App* runCmd = app.add_subcommand("run", "Run a scene headless and write an H5MD trajectory");
  auto* sceneArg = runCmd->add_option("scene", run.scene, "Scene file (YAML); not with --resume")->check(CLI::ExistingFile);
  auto* output = runCmd->add_option("-o,--output", run.output,
                                    "Trajectory file (default: the scene file's name with .h5, in the current folder; with --resume "
                                    "FILE: FILE's name less .partial, with -from-<step>.h5)");
  runCmd->add_flag("--no-output", run.noOutput, "Do not write a trajectory")->excludes(output);
  auto* steps = runCmd->add_option("--steps", run.steps, "Number of steps (overrides the scene)")->check(wholeNumber(1, kMaxSteps));
  runCmd->add_option("--duration", run.duration, "Simulated time [s] (overrides the scene)")
      ->check(positiveFinite())
      ->excludes(steps);
  runCmd->add_option("--every", run.every, "Write a frame every K steps (overrides the scene)")
      ->check(wholeNumber(1, 2147483647));
  runCmd->add_option("--checkpoint-every", run.checkpointEvery,
                     "Write a checkpoint (the whole state) into the trajectory every STEPS steps, at the end and when "
                     "interrupted; the file keeps the latest")
      ->check(wholeNumber(1, kMaxSteps));
  auto* resume = runCmd->add_option("--resume", run.resume,
                                    "Continue the run whose trajectory FILE holds a checkpoint, from it, to the step that run "
                                    "was to end at (or --steps / --duration more), into a new trajectory; bit for bit the "
                                    "run that was not stopped")
                     ->check(CLI::ExistingFile)
                     ->excludes(sceneArg);
  runCmd->add_option("--seed", run.seed, "Seed of what is drawn at random, bond strengths (overrides the scene's 'seed')")
      ->check(wholeNumber(0, 9007199254740992))
      ->excludes(resume);
  runCmd->add_flag("--json", run.json, "Print one JSON object with the summary on stdout");
  runCmd->add_option("--threads", run.threads,
                     "Worker threads for the step (default: this machine's hardware threads; the trajectory is the same bit for bit)")
      ->check(wholeNumber(1, 256));
  runCmd->add_option("--flush-every", run.flushSeconds,
                     "Seconds between flushes of the trajectory to disk (default 2; 0: after every frame). A run killed with "
                     "SIGKILL keeps every frame up to the last flush; Ctrl-C, SIGTERM and errors lose nothing")
      ->check(CLI::Range(0.0, 86400.0));
  const auto limits = [](CLI::App* cmd, SceneLimits& l) {
    cmd->add_option("--allow-dir", l.allowDirs, "A folder the scene's mesh files may lie in besides the scene's own (repeatable)")
        ->check(CLI::ExistingDirectory);
    cmd->add_option("--memory-limit", l.memoryLimitGiB, "Refuse a scene estimated to need more memory [GiB] (default: 80 % of this machine's)")
        ->check(positiveFinite());
  };
  limits(runCmd, run.limits);
  // testing aid, not shown in --help
  runCmd->add_option("--kill-after-frames", run.killAfterFrames)->group("")->check(wholeNumber(0, kMaxSteps));

  CheckArgs check;
  CLI::App* checkCmd =
      app.add_subcommand("check", "Run a scene and cross-check every step's collision results against FCL");
  checkCmd->add_option("scene", check.scene, "Scene file (YAML)")->required()->check(CLI::ExistingFile);
  auto* checkSteps =
      checkCmd->add_option("--steps", check.steps, "Number of steps (overrides the scene)")->check(wholeNumber(1, kMaxSteps));
  checkCmd->add_option("--duration", check.duration, "Simulated time [s] (overrides the scene)")
      ->check(positiveFinite())
      ->excludes(checkSteps);
  checkCmd->add_option("--details", check.details, "How many mismatches to describe (default 10)")
      ->check(wholeNumber(0, 1000000));
  checkCmd->add_flag("--json", check.json, "Print one JSON object with the report on stdout");
  limits(checkCmd, check.limits);

  std::string inspectPath;
  bool inspectJson = false;
  CLI::App* inspectCmd = app.add_subcommand("inspect", "Summarise a trajectory file");
  inspectCmd->add_option("file", inspectPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);
  inspectCmd->add_flag("--json", inspectJson, "Print one JSON object on stdout");

  std::string xdmfPath;
  CLI::App* xdmfCmd = app.add_subcommand("xdmf", "(Re)write the ParaView XDMF sidecar of a trajectory");
  xdmfCmd->add_option("file", xdmfPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);

  RenderArgs render;
  CLI::App* renderCmd = app.add_subcommand("render", "Draw frames of a trajectory to PNG, or an animation to MP4 or GIF (with ffmpeg)");
  renderCmd->add_option("file", render.input, "Trajectory (.h5)")->required();
  renderCmd->add_option("-o,--output", render.output,
                        "Picture (.png) or animation (.mp4, .gif) (default: the trajectory's name with .png, in the current "
                        "folder); with --frames and .png, one file a frame: OUT-0000.png, OUT-0001.png, ...");
  auto* renderFrames = renderCmd->add_option("--frames", render.frames,
                                             "Frames FIRST:LAST[:STRIDE] (indices of complete frames, LAST included, negative "
                                             "from the end; FIRST, LAST may be left out) (default for MP4/GIF: all)");
  renderCmd->add_option("--frame", render.frame, "One frame (index, negative from the end) (default for PNG: the last complete frame)")
      ->excludes(renderFrames);
  renderCmd->add_option("--view", render.view, "Camera: iso, front, side or top (default iso)");
  renderCmd->add_option("--size", render.size, "Image size WIDTHxHEIGHT in pixels (default 960x720)");
  renderCmd->add_option("--fps", render.fps, "Frames per second of an animation (default 30)")->check(positiveFinite());
  renderCmd->add_flag("--connectors", render.connectors, "Draw unbroken connectors as lines (rods black, springs grey, bonds gold), particles smaller");
  renderCmd->add_flag("--contacts", render.contacts, "Mark the contact points of each frame");
  renderCmd->add_flag("--normals", render.normals, "Draw the contact patches' normals as arrows");
  renderCmd->add_flag("--json", render.json, "Print one JSON object with the outputs, the camera and the palette on stdout");

  // every command-line error exits with status 1 (help and version with 0)
  if (argc > 1 && argv[1][0] != '-' && app.get_subcommands([&](const CLI::App* sub) { return sub->get_name() == argv[1]; }).empty()) {
    std::fprintf(stderr, "volpar: error: unknown command '%s'; expected run, check, inspect, xdmf or render\nRun with --help for more information.\n", argv[1]);
    return 1;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "volpar: error: %s\nRun with --help for more information.\n", e.what());
    return 1;
  }
  // what the commands do not catch themselves: a clear message and status 1, never an abort
  try {
    if (runCmd->parsed()) return volpar::cli::run(run);
    if (checkCmd->parsed()) return volpar::cli::check(check);
    if (inspectCmd->parsed()) return inspect(inspectPath, inspectJson);
    if (xdmfCmd->parsed()) return xdmf(xdmfPath);
    if (renderCmd->parsed()) return renderTrajectory(render);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "volpar: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "volpar: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
