// volpar.run: a world (or a scene) stepped and written to a trajectory by the run loop, as `volpar run` does.

#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "python/src/common.hpp"
#include "volpar/engine/run_loop.hpp"

namespace volpar::python {

py::dict patchesByCaseDict(const std::array<std::size_t, kPlaneCaseCount>& byCase) {
  py::dict d;
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) d[planeCaseName(static_cast<PlaneCase>(k))] = byCase[k];
  return d;
}

py::dict stageSecondsDict(const StageTimes& t) {
  py::dict d;
  d["integrate_velocities"] = t.integrateVelocities;
  d["integrate_positions"] = t.integratePositions;
  d["broadphase"] = t.broadphase;
  d["particle_contacts"] = t.particleContacts;
  d["narrow_phase"] = t.narrowPhase;
  d["solver"] = t.solver;
  d["breakage"] = t.breakage;
  return d;
}

namespace {

/// The summary, with the keys and in the order of `volpar run --json` (tools/run_command.cpp).
py::dict summaryDict(const World& world, const std::string& sceneName, const RunSummary& s) {
  const StageTimes& t = s.stageTimes;
  py::dict d;
  d["scene"] = sceneName;
  d["steps"] = s.steps;
  d["frames"] = s.frames;
  d["bodies"] = s.bodies;
  d["particles"] = s.particles;
  d["wall_seconds"] = s.wallSeconds;
  d["step_seconds"] = s.stepSeconds;
  d["steps_per_second"] = s.stepsPerSecond;
  d["threads"] = world.settings().threads;
  d["simulated_seconds"] = world.time();
  d["energy_start"] = s.energyStart.total();
  d["energy_end"] = s.energyEnd.total();
  d["energy_change"] = s.energyEnd.total() - s.energyStart.total();
  d["contacts"] = world.stats().contacts;
  d["connectors_broken"] = s.connectorsBroken;
  d["bodies_created"] = s.bodiesCreated;
  d["normals_recomputed"] = s.normalsRecomputed;
  d["breaks_in_tension"] = s.breaksByMode[0];
  d["breaks_in_compression"] = s.breaksByMode[1];
  d["breaks_in_shear"] = s.breaksByMode[2];
  d["breaks_by_strain"] = s.breaksByMode[3];
  d["breakage_energy"] = s.breakageEnergy;
  d["fragments"] = s.fragments.count;
  d["single_particle_fragments"] = s.fragments.singles;
  d["largest_fragment"] = s.fragments.largest;
  d["max_penetration"] = s.maxPenetration;
  d["interrupted"] = s.interrupted;
  d["output"] = s.output;
  d["patches"] = s.patches;
  d["unvalidated_patches"] = s.unvalidatedPatches;
  d["look_aheads"] = s.lookAheads;
  d["patches_reused"] = s.patchesReused;
  d["candidates"] = s.candidates;
  d["patches_by_case"] = patchesByCaseDict(s.patchesByCase);
  d["stage_seconds"] = stageSecondsDict(t);
  return d;
}

py::dict runWorldFromPython(PyWorld& self, const py::object& output, const py::object& stepsArg,
                            const py::object& durationArg, const py::object& everyArg, const py::object& threads,
                            const py::object& checkpointEvery) {
  World& world = self.get();
  // the steps and the frames, checked and worded as volpar run's options
  if (!stepsArg.is_none() && !durationArg.is_none()) raise("--steps excludes --duration");
  const std::int64_t steps = stepsArg.is_none() ? 0 : wholeNumber(stepsArg, "--steps", 1, kMaxSteps);
  const double duration = durationArg.is_none() ? 0.0 : positiveFinite(durationArg, "--duration");
  if (steps == 0 && duration == 0.0 && !self.scene)
    raise("steps: expected steps or duration for a world built from code (a scene's world takes the scene's)");
  const std::int64_t count = take(stepsFor(self.scene ? self.scene->steps : 0, world.settings().dt, steps, duration));
  const int every = everyArg.is_none() ? (self.scene ? self.scene->outputEvery : 1)
                                       : static_cast<int>(wholeNumber(everyArg, "--every", 1, 2147483647));
  const int threadsWanted = threads.is_none() ? world.settings().threads : threadCount(threads);

  RunOptions options;
  options.steps = count;
  options.every = every;
  if (!checkpointEvery.is_none()) options.checkpointEvery = wholeNumber(checkpointEvery, "--checkpoint-every", 1, kMaxSteps);
  const std::string sceneFile = self.scene ? self.scene->file : std::string();
  const std::vector<std::string> meshFiles = self.scene ? self.scene->meshFiles : std::vector<std::string>{};
  if (!output.is_none()) {
    options.output = py::cast<std::filesystem::path>(output).string();
    if (options.output.empty()) raise("output: expected a file name for the trajectory, got ''");
    for (const std::string& out : {options.output, partialPath(options.output)})
      if (const auto refused = refuseOverwrite(out, sceneFile, meshFiles)) raise(*refused);
  }
  // the trajectory's /parameters, as volpar run fills them
  TrajectoryMeta meta;
  if (self.scene) {
    meta.sceneName = self.scene->name;
    meta.sceneFile = self.scene->file;
    meta.sceneText = self.scene->text;
    meta.extraFiles = self.scene->meshFiles;
  }
  meta.outputEvery = options.every;
  meta.stepsRequested = options.steps;

  world.setThreads(threadsWanted);
  self.current();  // the contacts of bodies added since the last step, for the first frame
  // Ctrl-C: the run stops after the current step, closes the file under its partial name, and KeyboardInterrupt
  // is raised (the progress callback looks for signals about every 100 ms, with the GIL)
  std::atomic<bool> stop{false};
  PyObject *errType = nullptr, *errValue = nullptr, *errTrace = nullptr;
  options.stop = &stop;
  options.progress = [&](std::int64_t, std::int64_t) {
    if (stop.load()) return;
    const py::gil_scoped_acquire acquire;
    if (PyErr_CheckSignals() != 0) {
      PyErr_Fetch(&errType, &errValue, &errTrace);
      stop.store(true);
    }
  };
  Result<RunSummary> summary = Error{};
  {
    const BusyGuard busy(self);
    py::gil_scoped_release release;
    summary = runWorld(world, meta, options);
  }
  if (errType) {
    PyErr_Restore(errType, errValue, errTrace);
    throw py::error_already_set();
  }
  const RunSummary s = take(std::move(summary));
  return summaryDict(world, self.scene ? self.scene->name : std::string(), s);
}

}  // namespace

void bindRun(py::module_& m) {
  m.def(
      "run",
      [](const py::object& what, const py::object& output, const py::object& steps, const py::object& duration,
         const py::object& every, const py::object& threads, const py::object& checkpointEvery, const py::object& seed,
         const py::object& memoryLimitGiB) {
        // a path or a Scene is loaded and built as volpar run does; a World is run as it is
        if (py::isinstance<PyWorld>(what)) {
          if (!seed.is_none() || !memoryLimitGiB.is_none())
            raise("seed and memory_limit_gib apply when a scene is built; this World is built already");
          return runWorldFromPython(what.cast<PyWorld&>(), output, steps, duration, every, threads, checkpointEvery);
        }
        py::object scene = what;
        if (!py::isinstance<PyScene>(what)) {
          if (!(py::isinstance<py::str>(what) || py::hasattr(what, "__fspath__")))
            throw py::type_error("run(): expected a World, a Scene or a scene file's path, got " + str(py::repr(what)));
          scene = py::cast(loadSceneFile(py::cast<std::filesystem::path>(what), {}));
        }
        const std::unique_ptr<PyWorld> world = buildWorld(scene.cast<const PyScene&>(), seed, memoryLimitGiB, threads);
        return runWorldFromPython(*world, output, steps, duration, every, py::none(), checkpointEvery);
      },
      py::arg("world_or_scene"), py::arg("output") = py::none(), py::kw_only(), py::arg("steps") = py::none(),
      py::arg("duration") = py::none(), py::arg("every") = py::none(), py::arg("threads") = py::none(),
      py::arg("checkpoint_every") = py::none(), py::arg("seed") = py::none(), py::arg("memory_limit_gib") = py::none(),
      R"doc(
Runs a world and writes its trajectory: what `volpar run` does, with the same run loop (engine/run_loop.hpp)
and the same trajectory parameters, so that a scene run here writes the same file as `volpar run SCENE -o
OUTPUT` with the same options.

Arguments:
    world_or_scene: a World (run from its current state, which the run advances), a Scene (built first, as
        volpar run builds it), or the path of a scene file (loaded and built).
    output (str | os.PathLike | None): the trajectory (H5MD, docs/trajectory-format.md) and its sidecar
        OUTPUT.xdmf2; None: no file (volpar run --no-output). The file grows as OUTPUT.partial.h5 and is
        renamed when the run ends well. An output that is the scene file, a mesh it reads or a folder is
        refused.
Keyword arguments (each as the volpar run option of the same name):
    steps (int): steps to take (--steps), 1 to 10**12; duration (float): or simulated seconds (--duration).
        Neither: the scene's (a world built from code needs one).
    every (int): write a frame every this many steps (--every), besides step 0 and the last; None: the
        scene's `output: every` (1 for a world built from code).
    threads (int): worker threads (--threads), 1 to 256; None: for a Scene or path the machine's hardware threads,
        for a World its own setting.
    checkpoint_every (int): write a checkpoint (the whole state) into the trajectory every this many steps, at
        the end and when interrupted (--checkpoint-every; `volpar run --resume FILE` continues from it).
    seed (int), memory_limit_gib (float): --seed and --memory-limit, for a Scene or path only.

Returns a dict with the keys of `volpar run --json` ('steps', 'frames', 'bodies', 'particles',
'wall_seconds', 'step_seconds', 'steps_per_second', 'threads', 'energy_start', 'energy_end', 'energy_change', 'output', ...,
'patches_by_case', 'stage_seconds'). The run releases the GIL. Raises volpar.Error with volpar run's message
for bad input or a failed run (the frames written stay in OUTPUT.partial.h5); Ctrl-C stops the run after
the current step, closes the file (it keeps its partial name) and raises KeyboardInterrupt.
)doc");
}

}  // namespace volpar::python
