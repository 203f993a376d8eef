// Scenes: load_scene, parse_scene, Scene and build_scene, as `volpar run` loads and builds them.

#include <CLI/Error.hpp>
#include <CLI/Validators.hpp>

#include <cmath>
#include <filesystem>

#include "python/src/common.hpp"
#include "volpar/engine/run_loop.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

namespace volpar::python {

namespace {

/// The folders of allow_dirs, refused as volpar run refuses an --allow-dir that is no folder (CLI11's
/// ExistingDirectory check, the same message).
LoadOptions loadOptions(const std::vector<std::filesystem::path>& allowDirs) {
  LoadOptions options;
  for (const std::filesystem::path& dir : allowDirs) {
    std::string d = dir.string();
    if (const std::string bad = CLI::ExistingDirectory(d); !bad.empty()) raise("--allow-dir: " + bad);
    options.allowedDirs.push_back(d);
  }
  return options;
}

}  // namespace

PyScene loadSceneFile(const std::filesystem::path& path, const std::vector<std::filesystem::path>& allowDirs) {
  std::string file = path.string();
  const LoadOptions options = loadOptions(allowDirs);
  // volpar run checks its scene argument with CLI11's ExistingFile before reading it: the same check, the same
  // message ("scene: File does not exist: PATH")
  if (const std::string bad = CLI::ExistingFile(file); !bad.empty()) raise("scene: " + bad);
  Result<SceneDesc> desc = Error{};
  {
    py::gil_scoped_release release;
    desc = loadScene(file, options);
  }
  return PyScene{take(std::move(desc)), file};
}

namespace {

PyScene parse(const std::string& text, const std::string& path, const std::vector<std::filesystem::path>& allowDirs) {
  const LoadOptions options = loadOptions(allowDirs);
  Result<SceneDesc> desc = Error{};
  {
    py::gil_scoped_release release;
    desc = parseScene(text, path, options);
  }
  return PyScene{take(std::move(desc)), path};
}

py::tuple tuple3(const Vec3& v) { return py::make_tuple(v.x(), v.y(), v.z()); }

}  // namespace

int threadCount(py::handle threads) {
  if (threads.is_none()) return defaultThreads();
  return static_cast<int>(wholeNumber(threads, "--threads", 1, 256));
}

std::unique_ptr<PyWorld> buildWorld(const PyScene& scene, py::handle seed, py::handle memoryLimitGiB, py::handle threads) {
  SceneDesc desc = scene.desc;
  if (!seed.is_none()) desc.seed = static_cast<std::uint64_t>(wholeNumber(seed, "--seed", 0, 9007199254740992));
  BuildOptions options;
  if (!memoryLimitGiB.is_none())  // (as tools/commands.hpp's SceneLimits::build)
    options.memoryLimit =
        static_cast<std::uint64_t>(std::min(positiveFinite(memoryLimitGiB, "--memory-limit") * 1073741824.0, 1.8e19));
  const int threadsWanted = threadCount(threads);
  Result<BuiltScene> built = Error{};
  {
    py::gil_scoped_release release;
    built = buildScene(desc, options);
  }
  BuiltScene b = take(std::move(built));
  auto out = std::make_unique<PyWorld>();
  out->world = std::make_unique<World>(std::move(b.world));
  out->world->setThreads(threadsWanted);
  SceneOrigin origin;
  origin.name = desc.name;
  origin.file = scene.path;
  origin.text = desc.text;
  origin.meshFiles = std::move(b.meshFiles);
  origin.notes = std::move(b.notes);
  origin.bodySource = std::move(b.bodySource);
  origin.outputEvery = desc.outputEvery;
  origin.steps = desc.stepCount();
  out->scene = std::move(origin);
  return out;
}

void bindScene(py::module_& m) {
  py::class_<PyScene>(m, "Scene", R"doc(
A scene read from a YAML file or text (docs/scene-format.md), checked but not yet built.

Made by load_scene() or parse_scene(); build() turns it into a World, as `volpar run` does. The
attributes are read-only and give the scene's own values (its defaults where it leaves a key out).
)doc")
      .def_property_readonly("name", [](const PyScene& s) { return s.desc.name; }, "The scene's name (str; '' if it has none).")
      .def_property_readonly("path", [](const PyScene& s) { return s.path; },
                             "The path it was loaded from, as given (parse_scene: its `path` argument).")
      .def_property_readonly("text", [](const PyScene& s) { return s.desc.text; }, "The scene's full YAML text.")
      .def_property_readonly("dt", [](const PyScene& s) { return s.desc.dt; }, "Time step [s].")
      .def_property_readonly("steps", [](const PyScene& s) { return s.desc.stepCount(); },
                             "Steps the scene asks for: its `steps`, or round(duration / dt) (int).")
      .def_property_readonly("duration", [](const PyScene& s) { return static_cast<double>(s.desc.stepCount()) * s.desc.dt; },
                             "Simulated time of those steps [s]: steps * dt.")
      .def_property_readonly("gravity", [](const PyScene& s) { return tuple3(s.desc.gravity); },
                             "Gravity (x, y, z) [m/s^2].")
      .def_property_readonly("output_every", [](const PyScene& s) { return s.desc.outputEvery; },
                             "Its `output: every`: a trajectory frame every this many steps.")
      .def_property_readonly("seed", [](const PyScene& s) { return s.desc.seed; },
                             "Its `seed` for what is drawn at random (bond strengths); build(seed=...) overrides it.")
      .def_property_readonly("solver_iterations", [](const PyScene& s) { return s.desc.solverIterations; },
                             "Contact solver iterations per step.")
      .def_property_readonly("substeps", [](const PyScene& s) { return s.desc.substeps; },
                             "XPBD substeps per step of deformable bodies.")
      .def_property_readonly("allow_initial_overlap", [](const PyScene& s) { return s.desc.allowInitialOverlap; },
                             "Whether bodies may overlap at the start.")
      .def_property_readonly(
          "materials",
          [](const PyScene& s) {
            std::vector<std::string> names;
            for (const auto& [name, mat] : s.desc.materials) names.push_back(name);
            return names;
          },
          "Names of its materials (list of str, 'default' included), in name order.")
      .def_property_readonly(
          "body_names",
          [](const PyScene& s) {
            std::vector<std::string> names;
            for (const BodyDesc& b : s.desc.bodies) names.push_back(b.name);
            return names;
          },
          "Names of its body entries (list of str), before repeats are expanded.")
      .def_property_readonly("plane_count", [](const PyScene& s) { return s.desc.planes.size(); }, "Number of planes.")
      .def(
          "estimate",
          [](const PyScene& s) {
            const SceneEstimate e = take(estimateScene(s.desc));
            py::dict d;
            d["particles"] = e.particles;
            d["connectors"] = e.connectors;
            d["bodies"] = e.bodies;
            d["bytes"] = e.bytes;
            return d;
          },
          R"doc(
What the scene will need, estimated from its description alone (meshes are read for their volume), as
`volpar run` estimates it before building: a dict with 'particles', 'connectors' (rods, springs, bonds),
'bodies' and 'bytes' (memory of the world while it runs), all floats.
)doc")
      .def(
          "build",
          [](const PyScene& s, py::object seed, py::object memoryLimitGiB, py::object threads) {
            return buildWorld(s, seed, memoryLimitGiB, threads);
          },
          py::kw_only(), py::arg("seed") = py::none(), py::arg("memory_limit_gib") = py::none(),
          py::arg("threads") = py::none(),
          R"doc(
Builds the scene's world, as `volpar run` does, and returns it (a World).

Keyword arguments (each as the `volpar run` option of the same name; None: the option left out):
    seed (int | None): overrides the scene's `seed` (--seed), 0 to 2**53.
    memory_limit_gib (float | None): refuse a scene estimated to need more memory [GiB] (--memory-limit);
        None: 80 % of this machine's memory.
    threads (int | None): worker threads for the steps, 1 to 256 (--threads; None: the machine's hardware threads). The results do not
        depend on it.

Raises volpar.Error where the scene cannot be built (bodies overlapping at the start, a mesh that is not a
closed solid, more memory than allowed, ...), with the message `volpar run` prints.
)doc");

  m.def("load_scene", &loadSceneFile, py::arg("path"), py::kw_only(), py::arg("allow_dirs") = std::vector<std::filesystem::path>{},
        R"doc(
Reads and checks a scene file (YAML, docs/scene-format.md) and returns a Scene.

Arguments:
    path (str | os.PathLike): the scene file. Mesh files it names are found relative to its folder.
    allow_dirs (list of paths): folders besides the scene's own that its mesh files may lie in
        (`volpar run --allow-dir`).

Raises volpar.Error with exactly the message `volpar run` prints for the same file (after 'volpar: error: '):
'scene: File does not exist: PATH' for a missing file, 'PATH:LINE:COLUMN: what was expected' for a syntax
error, an unknown key or a value out of range.
)doc");
  m.def("parse_scene", &parse, py::arg("text"), py::arg("path") = "<string>", py::kw_only(),
        py::arg("allow_dirs") = std::vector<std::filesystem::path>{},
        R"doc(
Reads and checks scene text (YAML, docs/scene-format.md) and returns a Scene.

Arguments:
    text (str): the scene.
    path (str): the name used in messages ('<string>:3:5: ...') and the file the scene is taken to be: mesh
        files it names are found relative to its folder (the current folder for '<string>').
    allow_dirs (list of paths): further folders mesh files may lie in (`volpar run --allow-dir`).

Raises volpar.Error ('PATH:LINE:COLUMN: what was expected') for bad text.
)doc");
  m.def(
      "build_scene",
      [](const PyScene& s, py::object seed, py::object memoryLimitGiB, py::object threads) {
        return buildWorld(s, seed, memoryLimitGiB, threads);
      },
      py::arg("scene"), py::kw_only(), py::arg("seed") = py::none(), py::arg("memory_limit_gib") = py::none(),
      py::arg("threads") = py::none(), "Builds a Scene's world: the same as scene.build(...) (see there).");
}

}  // namespace volpar::python
