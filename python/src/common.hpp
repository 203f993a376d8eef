#pragma once
// Shared pieces of the Python bindings (docs/python.md): the error raised as volpar.Error, the world as Python
// holds it, and the checks of arguments, worded as volpar run words its own.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <array>
#include <cstdint>
#include <exception>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/core/limits.hpp"
#include "volpar/engine/core/status.hpp"
#include "volpar/engine/scene/scene_desc.hpp"
#include "volpar/engine/world.hpp"

namespace volpar::python {

namespace py = pybind11;

/// An Error thrown inside the bindings; Python sees volpar.Error, whose str() is error().toString(): what
/// `volpar run` prints after "volpar: error: " (tools/: fail()).
class PyError : public std::exception {
 public:
  explicit PyError(Error error) : error_(std::move(error)), text_(error_.toString()) {}
  [[nodiscard]] const char* what() const noexcept override { return text_.c_str(); }
  [[nodiscard]] const Error& error() const { return error_; }

 private:
  Error error_;
  std::string text_;
};

[[noreturn]] inline void raise(const Error& error) { throw PyError(error); }
/// An error located in no file.
[[noreturn]] inline void raise(std::string message) { throw PyError(Error{"", 0, 0, std::move(message)}); }

/// The value of a Result, or volpar.Error.
template <class T>
T take(Result<T>&& result) {
  if (!result) raise(result.error());
  return std::move(result.value());
}
inline void check(const Status& status) {
  if (!status) raise(status.error());
}

/// What a world built from a scene keeps of it: what `volpar run` writes into the trajectory's /parameters
/// (tools/run_command.cpp), and the scene's own defaults for a run.
struct SceneOrigin {
  std::string name;
  std::string file;  ///< the path as given to load_scene (or parse_scene's path)
  std::string text;
  std::vector<std::string> meshFiles;
  std::vector<std::string> notes;
  std::vector<std::size_t> bodySource;
  int outputEvery = 1;
  std::int64_t steps = 0;
};

/// A World as Python holds it.
struct PyWorld {
  std::unique_ptr<World> world;
  std::optional<SceneOrigin> scene;
  /// A step or run is under way with the GIL released (read and written only with the GIL held).
  bool busy = false;
  /// Zero-copy views of the particle store alive (ViewGuard); adding bodies would move the memory under them.
  std::size_t views = 0;
  /// Bodies were added since contacts were last found (World::step and refreshContacts find them).
  bool contactsStale = false;

  /// The world, when no step or run is under way in another thread.
  World& get();
  /// As get(), after finding the contacts of bodies added since the last step.
  World& current();
};

/// Marks a world busy while it is stepped with the GIL released (made and destroyed with the GIL held).
class BusyGuard {
 public:
  explicit BusyGuard(PyWorld& world) : world_(world) {
    world_.get();
    world_.busy = true;
  }
  ~BusyGuard() { world_.busy = false; }
  BusyGuard(const BusyGuard&) = delete;
  BusyGuard& operator=(const BusyGuard&) = delete;

 private:
  PyWorld& world_;
};

// ---- argument checks

/// str() of a Python object.
[[nodiscard]] std::string str(py::handle value);
/// A whole number from lo to hi (Python int or NumPy integer; bool refused); the message is volpar run's for
/// its option `name` (tools/volpar.cpp: wholeNumber): "NAME: expected a whole number from LO to HI, got X".
[[nodiscard]] std::int64_t wholeNumber(py::handle value, const std::string& name, long long lo, long long hi);
/// A finite number above 0, as volpar run checks --duration and --memory-limit (tools/volpar.cpp).
[[nodiscard]] double positiveFinite(py::handle value, const std::string& name);
/// A Python number as a double ("NAME: expected a number, got X" otherwise).
[[nodiscard]] double number(py::handle value, const std::string& name);

/// Checks worded as the scene loader's (engine/scene/scene_loader.cpp) for the same quantity, prefixed by the
/// argument's name: "radius: expected a positive particle radius [m], got -1.0".
double positive(double v, const std::string& arg, const std::string& what, const std::string& unit);
double nonNegative(double v, const std::string& arg, const std::string& what, const std::string& unit);
double inRange(double v, const std::string& arg, const std::string& what, double lo, double hi);
/// Three finite components of at most `limit` in magnitude.
Vec3 vec3(const std::array<double, 3>& v, const std::string& arg, const std::string& what, double limit,
          const std::string& unit);
/// A unit quaternion from (w, x, y, z), any non-zero length.
Quat quaternion(const std::array<double, 4>& wxyz, const std::string& arg);
/// A unit direction from any finite non-zero vector.
Vec3 direction(const std::array<double, 3>& v, const std::string& arg, const std::string& what);
/// `value` if it is one of `options`, else "ARG: unknown WHAT 'x'; expected one of: a, b".
std::string oneOf(const std::string& value, const std::string& arg, const std::string& what,
                  const std::vector<std::string>& options);
/// Python's repr of a float, for messages.
[[nodiscard]] std::string repr(double v);

// ---- NumPy arrays

/// A read-only NumPy array over the world's memory, kept valid by a ViewGuard as its base.
[[nodiscard]] py::array view(py::object owner, PyWorld& world, const void* data, const py::dtype& dtype,
                             std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides);
/// A new [n, 3] float64 array of the vectors.
[[nodiscard]] py::array_t<double> rows3(const std::vector<Vec3>& v);

// ---- the parts of the module (one file each)

void bindErrors(py::module_& m);
void bindScene(py::module_& m);
void bindBuilders(py::module_& m);
void bindWorld(py::module_& m);
void bindRun(py::module_& m);

// ---- builders (builders.cpp), used by World.add_body (world.cpp)

/// A ParticleCloud with what a body made of it is told about its solid.
struct PyCloud {
  ParticleCloud cloud;
  SourceShape source;              ///< the solid it was filled from (BodyDef::source); kind None for particle lists
  Lattice lattice = Lattice::Cubic;
  double reach = 1.5;              ///< FillSettings::reach [spacings]
  bool filled = false;             ///< made by fill_shape (has a lattice springs can be calibrated for)
};

// ---- scenes (scene.cpp), used by run (run.cpp)

/// A loaded scene: its description and the path it was given by.
struct PyScene {
  SceneDesc desc;
  std::string path;
};

/// Reads a scene file as volpar run does (its check of the scene argument, then loadScene).
[[nodiscard]] PyScene loadSceneFile(const std::filesystem::path& path, const std::vector<std::filesystem::path>& allowDirs);
/// Builds a scene's world as `volpar run` does (with --seed and --memory-limit when given: None otherwise).
[[nodiscard]] std::unique_ptr<PyWorld> buildWorld(const PyScene& scene, py::handle seed, py::handle memoryLimitGiB,
                                                  py::handle threads);
/// Threads for World::setThreads, checked as volpar run's --threads.
[[nodiscard]] int threadCount(py::handle threads);
/// Patches by case as a dict {case name: count} (volpar run --json's patches_by_case).
[[nodiscard]] py::dict patchesByCaseDict(const std::array<std::size_t, kPlaneCaseCount>& byCase);
/// The step's stages as a dict {stage: seconds} (volpar run --json's stage_seconds, without the total).
[[nodiscard]] py::dict stageSecondsDict(const StageTimes& t);

}  // namespace volpar::python
