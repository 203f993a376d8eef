// volpar: run scenes headless, cross-check them against FCL, inspect trajectories.

#include <CLI/CLI.hpp>

#include "engine/core/version.hpp"
#include "tools/commands.hpp"

int main(int argc, char** argv) {
  using namespace volpar::cli;
  CLI::App app{"volpar: volumetric particle physics engine"};
  app.set_version_flag("--version", std::string(volpar::kName) + " " + volpar::kVersion);
  app.require_subcommand(1);

  RunArgs run;
  CLI::App* runCmd = app.add_subcommand("run", "Run a scene headless and write an H5MD trajectory");
  runCmd->add_option("scene", run.scene, "Scene file (YAML)")->required()->check(CLI::ExistingFile);
  auto* output =
      runCmd->add_option("-o,--output", run.output, "Trajectory file (default: <scene name>.h5 in the current folder)");
  runCmd->add_flag("--no-output", run.noOutput, "Do not write a trajectory")->excludes(output);
  auto* steps = runCmd->add_option("--steps", run.steps, "Number of steps (overrides the scene)")->check(CLI::PositiveNumber);
  runCmd->add_option("--duration", run.duration, "Simulated time [s] (overrides the scene)")
      ->check(CLI::PositiveNumber)
      ->excludes(steps);
  runCmd->add_option("--every", run.every, "Write a frame every K steps (overrides the scene)")->check(CLI::PositiveNumber);
  runCmd->add_flag("--json", run.json, "Print one JSON object with the summary on stdout");
  runCmd->add_option("--threads", run.threads, "Worker threads for the step (default 1; the results are the same)")
      ->check(CLI::Range(1, 256));
  // testing aid, not shown in --help
  runCmd->add_option("--kill-after-frames", run.killAfterFrames)->group("");

  CheckArgs check;
  CLI::App* checkCmd =
      app.add_subcommand("check", "Run a scene and cross-check every step's collision results against FCL");
  checkCmd->add_option("scene", check.scene, "Scene file (YAML)")->required()->check(CLI::ExistingFile);
  auto* checkSteps =
      checkCmd->add_option("--steps", check.steps, "Number of steps (overrides the scene)")->check(CLI::PositiveNumber);
  checkCmd->add_option("--duration", check.duration, "Simulated time [s] (overrides the scene)")
      ->check(CLI::PositiveNumber)
      ->excludes(checkSteps);
  checkCmd->add_option("--details", check.details, "How many mismatches to describe (default 10)")
      ->check(CLI::NonNegativeNumber);
  checkCmd->add_flag("--json", check.json, "Print one JSON object with the report on stdout");

  std::string inspectPath;
  bool inspectJson = false;
  CLI::App* inspectCmd = app.add_subcommand("inspect", "Summarise a trajectory file");
  inspectCmd->add_option("file", inspectPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);
  inspectCmd->add_flag("--json", inspectJson, "Print one JSON object on stdout");

  std::string xdmfPath;
  CLI::App* xdmfCmd = app.add_subcommand("xdmf", "(Re)write the ParaView XDMF sidecar of a trajectory");
  xdmfCmd->add_option("file", xdmfPath, "Trajectory (.h5)")->required()->check(CLI::ExistingFile);

  CLI11_PARSE(app, argc, argv);
  if (runCmd->parsed()) return volpar::cli::run(run);
  if (checkCmd->parsed()) return volpar::cli::check(check);
  if (inspectCmd->parsed()) return inspect(inspectPath, inspectJson);
  if (xdmfCmd->parsed()) return xdmf(xdmfPath);
  return 0;
}
