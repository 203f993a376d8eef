// volpar run: a scene headless to an H5MD trajectory.

#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <optional>

#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/io/xdmf_writer.hpp"
#include "volpar/engine/run_loop.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "tools/commands.hpp"
#include "tools/json_writer.hpp"
#if VOLPAR_HAS_MPI
#include <fcntl.h>

#include "volpar/distributed/mpi_session.hpp"
#include "volpar/distributed/mpi_file_processes.hpp"
#include "volpar/distributed/mpi_process_group.hpp"
#endif

namespace volpar::cli {

namespace {

std::atomic<bool> gStop{false};

extern "C" void onSignal(int) { gStop.store(true); }

/// h:mm:ss, or m:ss under an hour
std::string clockText(double seconds) {
  const auto s = static_cast<long long>(std::max(0.0, std::min(seconds, 3.6e8)) + 0.5);
  char buf[32];
  if (s >= 3600) std::snprintf(buf, sizeof buf, "%lld:%02lld:%02lld", s / 3600, s / 60 % 60, s % 60);
  else std::snprintf(buf, sizeof buf, "%lld:%02lld", s / 60, s % 60);
  return buf;
}

/// The progress bar on a terminal: share done, steps, rate, time elapsed and the time left at that rate.
void progressBar(std::int64_t done, std::int64_t total) {
  using Clock = std::chrono::steady_clock;
  static const Clock::time_point start = Clock::now();  // (the runner's first call, at 0 steps done)
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  const double rate = elapsed > 0.0 ? static_cast<double>(done) / elapsed : 0.0;
  const int width = 30;
  const double f = total > 0 ? static_cast<double>(done) / static_cast<double>(total) : 1.0;
  const int filled = static_cast<int>(f * width);
  const std::string left = rate > 0.0 ? clockText(static_cast<double>(total - done) / rate) : "?";
  std::fprintf(stderr, "\r[%s%s] %5.1f%%  step %lld/%lld  %.0f steps/s  %s elapsed  %s left ",
               std::string(static_cast<std::size_t>(filled), '#').c_str(), std::string(static_cast<std::size_t>(width - filled), ' ').c_str(),
               100.0 * f, static_cast<long long>(done), static_cast<long long>(total), rate, clockText(elapsed).c_str(), left.c_str());
  if (done >= total) std::fprintf(stderr, "\n");
  std::fflush(stderr);
}

/// The default name of a resumed run's trajectory: `pile.partial.h5` at step 1200 -> `pile-from-1200.h5`
/// (and a resumed run's own `pile-from-1200.h5` at step 1800 -> `pile-from-1800.h5`).
std::string resumedName(const std::string& resumed, std::int64_t step) {
  std::string stem = std::filesystem::path(resumed).stem().string();
  constexpr std::string_view kPartial = ".partial";
  if (stem.size() > kPartial.size() && stem.ends_with(kPartial)) stem.resize(stem.size() - kPartial.size());
  if (const std::size_t from = stem.rfind("-from-"); from != std::string::npos && from > 0 &&
                                                    stem.find_first_not_of("0123456789", from + 6) == std::string::npos &&
                                                    from + 6 < stem.size())
    stem.resize(from);
  return stem + "-from-" + std::to_string(step) + ".h5";
}

#if !VOLPAR_HAS_MPI
/// How many processes an MPI launcher started this one among (Open MPI's mpirun, or a PMI launcher such as
/// MPICH's or Slurm's); 1 when none did.
int launchedProcesses() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"})
    if (const char* value = std::getenv(name)) return std::max(1, std::atoi(value));
  return 1;
}
#endif

/// The most memory this process has held resident [bytes] (getrusage: kibibytes on Linux).
std::size_t maxResidentBytes() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0 || usage.ru_maxrss < 0) return 0;
  return static_cast<std::size_t>(usage.ru_maxrss) * 1024;
}

/// Each stage's seconds, as the object `name` of the report.
void stageFields(JsonWriter& j, const std::string& name, const StageTimes& t) {
  j.begin(name)
      .field("integrate_velocities", t.integrateVelocities)
      .field("integrate_positions", t.integratePositions)
      .field("broadphase", t.broadphase)
      .field("particle_contacts", t.particleContacts)
      .field("narrow_phase", t.narrowPhase)
      .field("solver", t.solver)
      .field("breakage", t.breakage)
      .end();
}

}  // namespace

int run(const RunArgs& args) {
#if VOLPAR_HAS_MPI
  // under mpirun: every process builds and steps the whole world and they share the narrow phase and the
  // contact solver's iterations, and they write the trajectory together; process 0 reports (docs/distributed.md).
  // The others' output goes nowhere: they read the same inputs and so meet the same errors, which process 0
  // reports; a failure to write the file, which may be one process's alone, each reports (through `ownErrors`).
  const MpiSession mpi;
  int ownErrors = -1;
  if (mpi.rank() != 0) {
    ownErrors = ::dup(STDERR_FILENO);
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) ::dup2(null, STDOUT_FILENO), ::dup2(null, STDERR_FILENO), ::close(null);
  }
#else
  // (without MPI, processes started together would each run the whole scene and write the same file)
  if (const int processes = launchedProcesses(); processes > 1)
    return fail(Error{"", 0, 0,
                      "this volpar was built without MPI, but an MPI launcher started it as one of " + std::to_string(processes) +
                          " processes, each of which would run the whole scene and write the same file; expected one "
                          "process, or a volpar built with -DVOLPAR_MPI=ON (the dev preset; docs/distributed.md)"});
#endif
  if (args.scene.empty() && args.resume.empty()) return fail(Error{"", 0, 0, "expected a scene file, or --resume FILE"});
  // a resumed run: the scene as it was run, from the trajectory, and the state of its checkpoint
  std::optional<Checkpoint> checkpoint;
  if (!args.resume.empty()) {
    if (const auto damaged = readsSafely(args.resume, true)) return fail(*damaged);
    auto reader = H5mdReader::open(args.resume);
    if (!reader) return fail(reader.error());
    auto cp = reader.value()->checkpoint();
    if (!cp) return fail(cp.error());
    checkpoint = std::move(cp.value());
  }
  auto desc = checkpoint ? parseScene(checkpoint->sceneText, checkpoint->sceneFile, args.limits.load())
                         : loadScene(args.scene, args.limits.load());
  if (!desc) return fail(desc.error());
  if (checkpoint) desc->seed = static_cast<std::uint64_t>(checkpoint->seed);
  else if (args.seed >= 0) desc->seed = static_cast<std::uint64_t>(args.seed);
  auto built = buildScene(*desc, args.limits.build());
  if (!built) return fail(built.error());
  World& world = built->world;
#if VOLPAR_HAS_MPI
  // (by default the machine's hardware threads, divided among the processes on it)
  world.setThreads(args.threads > 0 ? args.threads : std::max(1, defaultThreads() / mpi.localSize()));
  std::optional<MpiProcessGroup> processes;
  std::optional<MpiFileProcesses> fileProcesses;
  if (mpi.size() > 1) {
    processes.emplace(MPI_COMM_WORLD);
    world.setProcesses(&*processes);
    fileProcesses.emplace(MPI_COMM_WORLD);
  }
#else
  world.setThreads(args.threads > 0 ? args.threads : defaultThreads());
#endif
  if (checkpoint) {
    if (auto restored = world.restoreState(checkpoint->state); !restored) {
      Error e = restored.error();
      e.file = args.resume;
      e.message = "cannot resume from the checkpoint of step " + std::to_string(checkpoint->step) + ": " + e.message;
      return fail(e);
    }
  }

  RunOptions options;
  if (checkpoint && args.steps == 0 && args.duration == 0.0) {
    options.steps = checkpoint->endStep - checkpoint->step;
    if (options.steps == 0)
      return fail(Error{args.resume, 0, 0, "the run reached its end (step " + std::to_string(checkpoint->endStep) +
                                               ") at this checkpoint; give --steps or --duration to go on from it"});
  } else {
    const auto steps = stepsFor(desc->stepCount(), desc->dt, args.steps, args.duration);
    if (!steps) return fail(steps.error());
    options.steps = steps.value();
  }
  options.every = args.every > 0 ? args.every : checkpoint ? checkpoint->outputEvery : desc->outputEvery;
  options.checkpointEvery = args.checkpointEvery;
  const std::string input = checkpoint ? args.resume : args.scene;
  if (!args.noOutput) {
    options.output = !args.output.empty() ? args.output
                     : checkpoint         ? resumedName(args.resume, checkpoint->step)
                                          : std::filesystem::path(args.scene).stem().string() + ".h5";
    for (const std::string& out : {options.output, partialPath(options.output)})
      if (const auto refused = refuseOverwrite(out, input, built->meshFiles, checkpoint ? "the trajectory resumed" : "the scene file"))
        return fail(*refused);
  }
#if VOLPAR_HAS_MPI
  if (mpi.size() > 1) {
    options.stopTogether = [&mpi](bool mine) { return mpi.any(mine); };
    options.fileProcesses = &*fileProcesses;
  }
#endif
  if (isatty(STDERR_FILENO)) options.progress = progressBar;
  options.stop = &gStop;
  options.killAfterFrames = args.killAfterFrames;
  options.commitSeconds = args.killAfterFrames > 0 ? 0.0 : args.flushSeconds;
  // Ctrl-C, kill, a scheduler's time limit or a closed terminal: finish the step and close the file
  for (const int sig : {SIGINT, SIGTERM, SIGHUP}) std::signal(sig, onSignal);

  TrajectoryMeta meta;
  meta.sceneName = desc->name;
  meta.sceneFile = checkpoint ? checkpoint->sceneFile : args.scene;
  meta.sceneText = desc->text;
  meta.extraFiles = built->meshFiles;
  meta.outputEvery = options.every;
  meta.stepsRequested = options.steps;

  auto summary = runWorld(world, meta, options);
  if (!summary) {
    const int status = fail(summary.error());
#if VOLPAR_HAS_MPI
    // (a failure of one process alone, writing, leaves the others waiting for it: it says why, and ends them all)
    if (ownErrors >= 0 && !summary.error().file.empty()) {
      const std::string line = "volpar: process " + std::to_string(mpi.rank()) + ": " + summary.error().toString() + "\n";
      static_cast<void>(::write(ownErrors, line.data(), line.size()));
    }
    if (mpi.size() > 1) mpi.abort(status);
#endif
    return status;
  }
  const RunSummary& s = *summary;
#if VOLPAR_HAS_MPI
  // what each process wrote into the trajectory (process 0 reports them)
  std::vector<std::size_t> outputBytes(static_cast<std::size_t>(mpi.size()), static_cast<std::size_t>(s.outputBytes));
  if (mpi.size() > 1) {
    const auto mine = static_cast<unsigned long long>(s.outputBytes);
    std::vector<unsigned long long> all(outputBytes.size());
    MPI_Gather(&mine, 1, MPI_UNSIGNED_LONG_LONG, all.data(), 1, MPI_UNSIGNED_LONG_LONG, 0, MPI_COMM_WORLD);
    for (std::size_t r = 0; r < all.size(); ++r) outputBytes[r] = static_cast<std::size_t>(all[r]);
  }
  // each process's time stepping and, of it, in exchanges (the waits for the others included)
  std::vector<double> stepSecondsByProcess(static_cast<std::size_t>(mpi.size()), s.stepSeconds);
  std::vector<double> exchangeSecondsByProcess(static_cast<std::size_t>(mpi.size()), s.exchangeTimes.total);
  if (mpi.size() > 1) {
    const double mine[2] = {s.stepSeconds, s.exchangeTimes.total};
    std::vector<double> all(2 * stepSecondsByProcess.size());
    MPI_Gather(mine, 2, MPI_DOUBLE, all.data(), 2, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    for (std::size_t r = 0; r < stepSecondsByProcess.size(); ++r) {
      stepSecondsByProcess[r] = all[2 * r];
      exchangeSecondsByProcess[r] = all[2 * r + 1];
    }
  }
#endif
  const double change = s.energyEnd.total() - s.energyStart.total();
  const StageTimes& t = s.stageTimes;
  if (args.json) {
    JsonWriter j;
    j.begin()
        .field("scene", desc->name)
        .field("steps", s.steps)
        .field("frames", s.frames)
        .field("bodies", s.bodies)
        .field("particles", s.particles)
        .field("connectors", s.connectors)
        .field("wall_seconds", s.wallSeconds)
        .field("step_seconds", s.stepSeconds)
        .field("steps_per_second", s.stepsPerSecond)
        .field("threads", world.settings().threads)
        .field("max_resident_bytes", maxResidentBytes())
#if VOLPAR_HAS_MPI
        .field("processes", mpi.size())
        .field("exchanges", processes ? processes->calls() : std::size_t{0})
        .field("exchange_bytes", processes ? processes->bytesReceived() : std::size_t{0})
        .field("output_bytes_by_process", std::span<const std::size_t>(outputBytes))
        .field("step_seconds_by_process", std::span<const double>(stepSecondsByProcess))
        .field("exchange_seconds_by_process", std::span<const double>(exchangeSecondsByProcess))
#endif
        .field("simulated_seconds", world.time())
        .field("energy_start", s.energyStart.total())
        .field("energy_end", s.energyEnd.total())
        .field("energy_change", change)
        .field("contacts", world.stats().contacts)
        .field("solver_rows_by_level", std::span<const std::size_t>(world.stats().solverRowsByLevel))
        .field("connectors_broken", s.connectorsBroken)
        .field("bodies_created", s.bodiesCreated)
        .field("normals_recomputed", s.normalsRecomputed)
        .field("breaks_in_tension", s.breaksByMode[0])
        .field("breaks_in_compression", s.breaksByMode[1])
        .field("breaks_in_shear", s.breaksByMode[2])
        .field("breaks_by_strain", s.breaksByMode[3])
        .field("breakage_energy", s.breakageEnergy)
        .field("fragments", s.fragments.count)
        .field("single_particle_fragments", s.fragments.singles)
        .field("largest_fragment", s.fragments.largest)
        .field("max_penetration", s.maxPenetration)
        .field("interrupted", s.interrupted)
        .field("output", s.output);
    j.field("patches", s.patches)
        .field("unvalidated_patches", s.unvalidatedPatches)
        .field("look_aheads", s.lookAheads)
        .field("patches_reused", s.patchesReused)
        .field("candidates", s.candidates);
    j.begin("patches_by_case");
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) j.field(planeCaseName(static_cast<PlaneCase>(k)), s.patchesByCase[k]);
    j.end();
    stageFields(j, "stage_seconds", t);
#if VOLPAR_HAS_MPI
    // of each stage's seconds, those in exchanges among the processes (process 0's)
    stageFields(j, "exchange_seconds_by_stage", s.exchangeTimes);
#endif
    j.end();
    std::cout << j.str() << std::endl;
  } else {
    std::printf("scene        %s (%s)\n", desc->name.c_str(), input.c_str());
    if (checkpoint) std::printf("resumed      from the checkpoint of step %lld\n", static_cast<long long>(checkpoint->step));
    std::printf("bodies       %zu, particles %zu\n", s.bodies, s.particles);
    for (const std::string& note : built->notes) std::printf("note         %s\n", note.c_str());
    std::printf("steps        %lld (t = %.6g s)%s\n", static_cast<long long>(s.steps), world.time(),
                s.interrupted ? ", interrupted" : "");
    std::printf("speed        %.1f steps/s (%.3f s stepping, %.3f s wall)\n", s.stepsPerSecond, s.stepSeconds,
                s.wallSeconds);
#if VOLPAR_HAS_MPI
    if (mpi.size() > 1)
      std::printf("processes    %d sharing the contact solver, %.3g MB of its exchanges received by process 0\n", mpi.size(),
                  static_cast<double>(processes->bytesReceived()) / 1e6);
#endif
    std::printf("stages       integrate velocities %.3f s, solver %.3f s, integrate positions %.3f s, broadphase %.3f s, "
                "particle contacts %.3f s, narrow phase %.3f s\n",
                t.integrateVelocities, t.solver, t.integratePositions, t.broadphase, t.particleContacts, t.narrowPhase);
    std::printf("contacts     %zu at the end, deepest overlap during the run %.3g m\n", world.stats().contacts,
                s.maxPenetration);
    if (s.connectorsBroken > 0 || s.normalsRecomputed > 0) {
      std::printf("breakage     %zu connectors broke (tension %zu, compression %zu, shear %zu, strain %zu), %zu fragments "
                  "made, %zu normals recomputed (%.3f s)\n",
                  s.connectorsBroken, s.breaksByMode[0], s.breaksByMode[1], s.breaksByMode[2], s.breaksByMode[3],
                  s.bodiesCreated, s.normalsRecomputed, t.breakage);
      if (s.fragments.count > 0)
        std::printf("fragments    %zu at the end (%zu of one particle, %.3g %% of their particles), the largest %zu "
                    "particles; the broken bonds held %.4g J\n",
                    s.fragments.count, s.fragments.singles,
                    s.fragments.particles ? 100.0 * static_cast<double>(s.fragments.singles) / static_cast<double>(s.fragments.particles) : 0.0,
                    s.fragments.largest, s.breakageEnergy);
    }
    std::printf("planes       %zu patches over the run, %zu unvalidated (%.3g %%), %zu look-aheads, %zu candidates, "
                "%zu taken over from the step before\n",
                s.patches, s.unvalidatedPatches, s.patches ? 100.0 * static_cast<double>(s.unvalidatedPatches) / static_cast<double>(s.patches) : 0.0,
                s.lookAheads, s.candidates, s.patchesReused);
    if (s.patches > 0) {
      std::printf("cases       ");
      for (std::size_t k = 0; k < kPlaneCaseCount; ++k)
        if (s.patchesByCase[k] > 0) std::printf(" %s %zu", planeCaseName(static_cast<PlaneCase>(k)), s.patchesByCase[k]);
      std::printf("\n");
    }
    // (contacts, damping and breaking bonds take energy out; a change is not an integration error)
    std::printf("energy       %.9g J -> %.9g J (change %.3g J)\n", s.energyStart.total(), s.energyEnd.total(), change);
    if (!s.output.empty())
      std::printf("trajectory   %s (%zu frames), sidecar %s\n", s.output.c_str(), s.frames, sidecarPath(s.output).c_str());
  }
  if (s.interrupted && !s.output.empty())
    std::fprintf(stderr, "volpar: interrupted; the %zu complete frames are kept in %s\n", s.frames, s.output.c_str());
  return s.interrupted ? 130 : 0;
}

}  // namespace volpar::cli
