#pragma once
// The Runner steps a World, writes a trajectory frame every K steps (and the final state), and makes the
// summary. The world never writes files itself.

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/io/h5md_writer.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

/// The most steps a run may have.
inline constexpr long long kMaxSteps = 1'000'000'000'000LL;

/// Steps to run: `steps` where it is set (> 0), else `duration` / dt where that is (> 0), else the scene's; an
/// error when `duration` needs more than kMaxSteps steps of `dt` (the message names --duration, as the
/// command line's option).
[[nodiscard]] Result<std::int64_t> stepsFor(std::int64_t scene, double dt, std::int64_t steps, double duration);

/// An error when the trajectory `output` would be written over one of a run's inputs (`input`, unless empty:
/// the scene file or the trajectory resumed, which `inputName` names in the message; a mesh file the scene
/// reads, of `inputs`; through any link) or over a folder.
[[nodiscard]] std::optional<Error> refuseOverwrite(const std::string& output, const std::string& input,
                                                   const std::vector<std::string>& inputs,
                                                   const std::string& inputName = "the scene file");

/// Worker threads a run takes when not told: the machine's hardware threads (1 where it cannot tell), at
/// most 256. The trajectory is the same bit for bit whatever the count.
[[nodiscard]] int defaultThreads();

/// Where a run writes its trajectory until it ends well (`out.partial.h5` for `out.h5`); an interrupted or
/// failed run leaves its complete frames there.
[[nodiscard]] std::string partialPath(const std::string& output);

struct RunOptions {
  std::string output;          ///< trajectory path; empty = no file
  std::int64_t steps = 0;      ///< steps to take
  int every = 1;               ///< write a frame every `every` steps
  /// Called with (0, steps total) before the first step, now and then with (steps done, steps total) and
  /// once after the last; may be empty.
  std::function<void(std::int64_t, std::int64_t)> progress;
  /// When set and it becomes true, the run stops after the current step and closes the file cleanly.
  const std::atomic<bool>* stop = nullptr;
  /// Processes stepping one world together: called before every step with whether this one would stop;
  /// returns whether all stop (every process gets the same answer, so all stop at the same step). May be empty.
  std::function<bool(bool)> stopTogether;
  /// Processes writing `output` together (H5mdWriter::create), each running this with the same world and
  /// options; process 0 alone renames the file and writes its sidecar. May be null: this process alone.
  const FileProcesses* fileProcesses = nullptr;
  /// When > 0: a checkpoint (the whole state, H5mdWriter::writeCheckpoint) after every step whose index is a
  /// multiple of it, after the last step and when interrupted; the file keeps the latest.
  std::int64_t checkpointEvery = 0;
  /// Seconds between commits of the trajectory (H5mdWriter::commit: the frames written are flushed and then
  /// counted complete); 0: after every frame. A run killed with SIGKILL loses at most the frames of the last
  /// interval; an interrupted, failed or finished run commits every frame it wrote.
  double commitSeconds = 0.0;
  /// Testing aid: when > 0, the process kills itself (SIGKILL, no cleanup) right after writing this many
  /// frames, to show that a killed run leaves a readable file.
  std::int64_t killAfterFrames = 0;
};

struct RunSummary {
  std::int64_t steps = 0;        ///< steps taken
  std::size_t frames = 0;        ///< frames written
  std::size_t bodies = 0;
  std::size_t particles = 0;
  std::size_t connectors = 0;    ///< connectors (rods, springs, bonds) at the start, broken or not
  double wallSeconds = 0.0;      ///< the whole loop, output included [s]
  double stepSeconds = 0.0;      ///< inside World::step only [s]
  double stepsPerSecond = 0.0;   ///< steps / stepSeconds
  EnergyReport energyStart;
  EnergyReport energyEnd;
  StageTimes stageTimes;         ///< summed over the run [s]
  StageTimes exchangeTimes;      ///< of them, in exchanges among processes (StepStats::exchangeTime) [s]
  double maxPenetration = 0.0;   ///< deepest particle overlap seen after any step [m]
  // narrow-phase statistics summed over the steps
  std::size_t patches = 0;
  std::array<std::size_t, kPlaneCaseCount> patchesByCase{};
  std::size_t candidates = 0;
  std::size_t lookAheads = 0;
  std::size_t unvalidatedPatches = 0;
  std::size_t patchesReused = 0;
  std::size_t connectorsBroken = 0;  ///< rods and springs that broke
  std::size_t bodiesCreated = 0;     ///< fragments of bodies that broke apart
  std::size_t normalsRecomputed = 0; ///< cached surface normals recomputed after breaks and strain
  std::array<std::size_t, 4> breaksByMode{};  ///< connectors broken by BreakMode (tension, compression, shear, strain)
  double breakageEnergy = 0.0;       ///< elastic energy the broken bonds held [J]
  FragmentHistogram fragments;       ///< at the end
  bool interrupted = false;
  std::string output;  ///< the trajectory written: the output's name, or its partial name when interrupted
  std::uint64_t outputBytes = 0;  ///< bytes this process wrote into the trajectory's datasets
};

[[nodiscard]] Result<RunSummary> runWorld(World& world, const TrajectoryMeta& meta, const RunOptions& options);

}  // namespace volpar
