// World: building from code, stepping (without the GIL), and the state as NumPy arrays.

#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <type_traits>

#include "python/src/common.hpp"
#include "volpar/engine/builders/elastic_calibration.hpp"
#include "volpar/engine/core/material.hpp"
#include "volpar/engine/run_loop.hpp"

namespace volpar::python {

// The particle store's arrays are handed to NumPy without copying: a std::vector<Vec3> must then be exactly
// [P, 3] float64 (Eigen's fixed-size 3-vectors of double are three doubles, no padding, 8-byte aligned), and a
// std::vector<BodyId> [P] uint32.
static_assert(sizeof(Vec3) == 3 * sizeof(double), "Vec3 must be three doubles with no padding");
static_assert(alignof(Vec3) == alignof(double), "Vec3 must be aligned as a double");
static_assert(std::is_standard_layout_v<BodyId> && sizeof(BodyId) == sizeof(std::uint32_t),
              "BodyId must be a plain 32-bit index");

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

/// While alive, a zero-copy view of a world's particle store exists: it keeps the world alive (its base is
/// this guard, which holds the world) and stops bodies being added (which would move the memory).
class ViewGuard {
 public:
  ViewGuard(py::object owner, PyWorld& world) : owner_(std::move(owner)), world_(world) { ++world_.views; }
  ~ViewGuard() { --world_.views; }
  ViewGuard(const ViewGuard&) = delete;
  ViewGuard& operator=(const ViewGuard&) = delete;
  [[nodiscard]] const py::object& owner() const { return owner_; }

 private:
  py::object owner_;
  PyWorld& world_;
};

const char* kindName(BodyKind k) {
  return k == BodyKind::Rigid ? "rigid" : k == BodyKind::Deformable ? "deformable" : "static";
}

py::array_t<double> vectors(const World& w, const std::function<Vec3(std::size_t)>& get) {
  const BodyStore& b = w.bodies();
  py::array_t<double> a({static_cast<py::ssize_t>(b.size()), py::ssize_t{3}});
  auto out = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < b.size(); ++i) {
    const Vec3 v = b.info[i].alive ? get(i) : Vec3::Constant(kNan);
    for (int k = 0; k < 3; ++k) out(static_cast<py::ssize_t>(i), k) = v[k];
  }
  return a;
}

template <class T>
py::array_t<T> column(std::size_t n, const std::function<T(std::size_t)>& get) {
  py::array_t<T> a(static_cast<py::ssize_t>(n));
  auto out = a.template mutable_unchecked<1>();
  for (std::size_t i = 0; i < n; ++i) out(static_cast<py::ssize_t>(i)) = get(i);
  return a;
}

py::array_t<double> rows(std::size_t n, const std::function<Vec3(std::size_t)>& get) {
  py::array_t<double> a({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  auto out = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 v = get(i);
    for (int k = 0; k < 3; ++k) out(static_cast<py::ssize_t>(i), k) = v[k];
  }
  return a;
}

std::unique_ptr<PyWorld> makeWorld(double dt, const std::array<double, 3>& gravity, py::object solverIterations,
                                   py::object substeps, py::object seed, py::object threads) {
  // the scene loader's checks of the same keys
  WorldSettings s;
  s.dt = positive(dt, "dt", "time step dt", "s");
  if (dt > 1.0) raise("dt: expected a time step dt of at most 1 s, got " + repr(dt));
  s.gravity = vec3(gravity, "gravity", "gravity", kMaxSpeed, "m/s^2");
  s.solverIterations = static_cast<int>(wholeNumber(solverIterations, "solver_iterations", 1, 1000));
  s.substeps = static_cast<int>(wholeNumber(substeps, "substeps", 1, 1000));
  s.seed = static_cast<std::uint64_t>(wholeNumber(seed, "--seed", 0, 9007199254740992));
  s.threads = threadCount(threads);
  auto w = std::make_unique<PyWorld>();
  w->world = std::make_unique<World>(s);
  return w;
}

MaterialId materialId(const World& world, const py::object& material) {
  const auto& mats = world.materials();
  if (mats.empty()) raise("material: the world has no materials; add one with add_material(volpar.Material(...)) first");
  if (py::isinstance<py::str>(material)) {
    const auto name = material.cast<std::string>();
    for (std::size_t i = 0; i < mats.size(); ++i)
      if (mats[i].name == name) return MaterialId(i);
    std::string list;
    for (const Material& m : mats) list += (list.empty() ? "" : ", ") + m.name;
    raise("material: unknown material '" + name + "'; expected one of: " + list);
  }
  const std::int64_t i = wholeNumber(material, "material", 0, std::numeric_limits<std::int32_t>::max());
  if (static_cast<std::size_t>(i) >= mats.size())
    raise("material: unknown material " + std::to_string(i) + "; expected 0 to " + std::to_string(static_cast<long long>(mats.size()) - 1) +
          " (add_material returns the index)");
  return MaterialId(static_cast<std::size_t>(i));
}

/// A body's or a glue's bonds take their modulus, and the strengths they leave unset, from the material
/// (takeBondDefaults, as the scene builder does).
void bondsFromMaterial(const Material& mat, const std::string& who, ConnectorParams& c) {
  takeBondDefaults(mat, c);
  if (!(mat.youngsModulus > 0.0))
    raise(who + ": bonds need their material's Young's modulus; expected youngs_modulus [Pa] in material '" + mat.name + "'");
}

std::size_t addBody(PyWorld& self, const PyCloud& cloudIn, const py::object& material, const py::object& nameArg,
                    const std::string& kindArg, const std::array<double, 3>& position,
                    const std::array<double, 4>& orientation, const std::array<double, 3>& velocity,
                    const std::array<double, 3>& angularVelocity, const py::object& connectors, const py::object& mass,
                    const py::object& particleMass, const std::string& massProperties) {
  World& world = self.get();
  if (self.views > 0)
    raise("add_body: " + std::to_string(self.views) +
          " views of this world's particle arrays are alive, and adding a body moves those arrays; delete the views "
          "(or take copies with numpy.array(view)) first");
  BodyDef def;
  def.name = nameArg.is_none() ? "body" + std::to_string(world.bodies().size()) : nameArg.cast<std::string>();
  const std::string kind = oneOf(kindArg, "kind", "body kind", {"rigid", "deformable", "static"});
  def.kind = kind == "rigid" ? BodyKind::Rigid : kind == "deformable" ? BodyKind::Deformable : BodyKind::Static;
  def.material = materialId(world, material);
  const Material& mat = world.materials()[def.material.index()];
  def.position = vec3(position, "position", "position", kMaxLength, "m");
  def.orientation = quaternion(orientation, "orientation");
  def.linearVelocity = vec3(velocity, "velocity", "velocity", kMaxSpeed, "m/s");
  def.angularVelocity = vec3(angularVelocity, "angular_velocity", "angular velocity", kMaxSpeed, "rad/s");
  if (def.kind == BodyKind::Static && (def.linearVelocity.norm() > 0.0 || def.angularVelocity.norm() > 0.0))
    raise("a static body cannot have a velocity");
  if (!mass.is_none() && !particleMass.is_none()) raise("expected at most one of 'mass' or 'particle_mass'");
  if (!mass.is_none()) def.totalMass = positive(number(mass, "mass"), "mass", "body mass", "kg");
  if (!particleMass.is_none())
    def.particleMass = positive(number(particleMass, "particle_mass"), "particle_mass", "particle mass", "kg");
  def.massModel = oneOf(massProperties, "mass_properties", "mass_properties", {"solid", "particles"}) == "particles"
                      ? MassModel::Particles
                      : MassModel::Solid;
  def.source = cloudIn.source;
  if (!cloudIn.cloud.pinned.empty() && def.kind != BodyKind::Deformable)
    raise("only deformable bodies can have pinned particles");

  ParticleCloud calibrated;  // (a copy only where springs are calibrated)
  const ParticleCloud* cloud = &cloudIn.cloud;
  def.connectors = connectors.is_none() ? ConnectorParams{} : connectors.cast<ConnectorParams>();
  ConnectorParams& c = def.connectors;
  const std::string who = "body '" + def.name + "'";
  if (c.kind == ConnectorKind::Spring && def.kind != BodyKind::Deformable)
    raise("springs need kind='deformable'; rigid and static bodies are joined by rods");
  if (c.kind == ConnectorKind::Bond && def.kind == BodyKind::Deformable)
    raise("bonds join the particles of rigid bodies; a deformable body takes springs or rods");
  if (def.kind == BodyKind::Static && (std::isfinite(c.breakLimit) || std::isfinite(c.compressionLimit) ||
                                       std::isfinite(c.bond.tensileStrength) || std::isfinite(c.bond.shearStrength)))
    raise("static bodies never break; give the connectors a strength on a rigid or deformable body");
  // as the scene builder (engine/scene/scene_build.cpp: buildScene) makes a body of its description
  if (c.kind == ConnectorKind::Spring && !(c.stiffness > 0.0)) {
    if (!cloudIn.filled)
      raise(who + ": springs of an explicit particle list need a 'stiffness' [N/m] (there is no lattice to calibrate them for)");
    if (!(mat.youngsModulus > 0.0))
      raise(who + ": springs need a 'stiffness' [N/m], or their material's 'youngs_modulus' [Pa] (material '" + mat.name + "')");
    const double spacing = cloudIn.cloud.spacing;
    const SpringCalibration springs = calibrateSprings(cloudIn.lattice, spacing, cloudIn.reach, mat.youngsModulus, mat.poissonRatio);
    if (!(springs.nearest > 0.0) || !std::isfinite(springs.nearest))
      raise(who + ": its lattice and reach cannot be calibrated for a Young's modulus (give the springs a 'stiffness')");
    calibrated = cloudIn.cloud;
    calibrated.connectorStiffness = calibratedStiffness(calibrated, springs, cloudIn.lattice, spacing, cloudIn.reach);
    cloud = &calibrated;
  }
  if (def.kind != BodyKind::Static) {
    // the material's thresholds where the connectors set none; rods that break in tension crush at ten times that
    // unless a compressive strength is given
    const bool rods = c.kind == ConnectorKind::Rod;
    if (!std::isfinite(c.breakLimit)) c.breakLimit = rods ? mat.rodStrength : mat.strainLimit;
    if (rods && !std::isfinite(c.compressionLimit))
      c.compressionLimit = mat.rodCompressiveStrength > 0.0 ? mat.rodCompressiveStrength : 10.0 * c.breakLimit;
  }
  if (c.kind == ConnectorKind::Bond) bondsFromMaterial(mat, who, c);

  Result<BodyId> id = Error{};
  {
    py::gil_scoped_release release;
    id = world.addBody(def, *cloud);
  }
  self.contactsStale = true;
  return take(std::move(id)).index();
}

std::size_t glue(PyWorld& self, const std::vector<std::int64_t>& bodies, const std::string& name, const py::object& material,
                 double reach, double radius, const std::optional<std::vector<std::array<std::int64_t, 2>>>& pairs) {
  World& world = self.get();
  if (self.views > 0)
    raise("glue: views of this world's particle arrays are alive; delete them (or take copies) first");
  const Material& mat = world.materials()[materialId(world, material).index()];
  GlueDef def;
  def.name = name;
  if (!(reach > 1.0 && reach <= 4.0))
    raise("reach: expected reach in (1, 4] times the two particles' radii summed (touching particles sit at 1), got " + repr(reach));
  def.reach = reach;
  if (!(radius > 0.0 && radius <= 1.0))
    raise("radius: expected a bond radius in (0, 1] (a fraction of the smaller particle radius), got " + repr(radius));
  def.bonds.kind = ConnectorKind::Bond;
  def.bonds.bond.radiusFactor = radius;
  bondsFromMaterial(mat, "glue '" + name + "'", def.bonds);
  std::vector<BodyId> ids;
  for (const std::int64_t b : bodies) {
    if (b < 0 || static_cast<std::size_t>(b) >= world.bodies().size())
      raise("bodies: unknown body " + std::to_string(b) + "; expected 0 to " +
            std::to_string(static_cast<long long>(world.bodies().size()) - 1));
    ids.emplace_back(static_cast<std::size_t>(b));
  }
  if (pairs) {
    for (const auto& [a, b] : *pairs) {
      std::array<std::uint32_t, 2> slot{0xffffffffu, 0xffffffffu};
      for (std::size_t k = 0; k < bodies.size(); ++k) {
        if (bodies[k] == a && slot[0] == 0xffffffffu) slot[0] = static_cast<std::uint32_t>(k);
        if (bodies[k] == b && slot[1] == 0xffffffffu) slot[1] = static_cast<std::uint32_t>(k);
      }
      if (slot[0] == 0xffffffffu || slot[1] == 0xffffffffu)
        raise("pairs: the pair (" + std::to_string(a) + ", " + std::to_string(b) + ") names a body that is not in `bodies`");
      def.pairs.push_back(slot);
    }
  }
  Result<BodyId> id = Error{};
  {
    py::gil_scoped_release release;
    id = world.glue(ids, def);
  }
  self.contactsStale = true;
  return take(std::move(id)).index();
}

void step(PyWorld& self, py::handle n) {
  const std::int64_t count = wholeNumber(n, "n", 0, kMaxSteps);
  World& world = self.get();
  const BusyGuard busy(self);
  std::optional<Error> failure;
  bool interrupted = false;
  {
    py::gil_scoped_release release;
    using Clock = std::chrono::steady_clock;
    auto last = Clock::now();
    for (std::int64_t i = 0; i < count; ++i) {
      if (hasFlag(world.step(), StepStatus::NonFinite)) {
        // (the run loop's words, engine/run_loop.cpp)
        failure = Error{"", 0, 0,
                        "the simulation became non-finite (NaN or infinity) at step " + std::to_string(world.stepIndex()) +
                            " (t = " + std::to_string(world.time()) + " s); stopped"};
        break;
      }
      // Ctrl-C: a KeyboardInterrupt after the current step
      if (const auto now = Clock::now(); now - last > std::chrono::milliseconds(100)) {
        last = now;
        const py::gil_scoped_acquire acquire;
        if (PyErr_CheckSignals() != 0) {
          interrupted = true;
          break;
        }
      }
    }
  }
  self.contactsStale = false;
  if (interrupted) throw py::error_already_set();
  if (failure) raise(*failure);
}

py::dict contacts(PyWorld& self, bool speculative) {
  const World& world = self.current();
  const auto& all = world.contacts().contacts;
  std::vector<std::size_t> rowsOf;
  for (std::size_t i = 0; i < all.size(); ++i)
    if (speculative || all[i].touching()) rowsOf.push_back(i);
  const std::size_t n = rowsOf.size();
  py::dict d;
  d["particle_a"] = column<std::int32_t>(n, [&](std::size_t i) { return static_cast<std::int32_t>(all[rowsOf[i]].a.value); });
  d["particle_b"] = column<std::int32_t>(n, [&](std::size_t i) {
    const ParticleContact& c = all[rowsOf[i]];
    return c.b.valid() ? static_cast<std::int32_t>(c.b.value) : std::int32_t{-1};
  });
  d["plane"] = column<std::int32_t>(n, [&](std::size_t i) {
    const ParticleContact& c = all[rowsOf[i]];
    return c.plane.valid() ? static_cast<std::int32_t>(c.plane.value) : std::int32_t{-1};
  });
  d["point"] = rows(n, [&](std::size_t i) { return all[rowsOf[i]].point; });
  d["normal"] = rows(n, [&](std::size_t i) { return all[rowsOf[i]].normal; });
  d["depth"] = column<double>(n, [&](std::size_t i) { return all[rowsOf[i]].depth; });
  return d;
}

py::dict patches(PyWorld& self) {
  const World& world = self.current();
  const auto& ps = world.patches().patches;
  const std::size_t n = ps.size();
  py::dict d;
  d["body_a"] = column<std::int32_t>(n, [&](std::size_t i) { return static_cast<std::int32_t>(ps[i].a.value); });
  d["body_b"] = column<std::int32_t>(n, [&](std::size_t i) {
    return ps[i].b.valid() ? static_cast<std::int32_t>(ps[i].b.value) : std::int32_t{-1};
  });
  d["plane"] = column<std::int32_t>(n, [&](std::size_t i) {
    return ps[i].plane.valid() ? static_cast<std::int32_t>(ps[i].plane.value) : std::int32_t{-1};
  });
  d["case"] = column<std::int32_t>(n, [&](std::size_t i) { return static_cast<std::int32_t>(ps[i].planeCase); });
  py::list caseNames, sourceNames;
  for (const ContactPatch& p : ps) {
    caseNames.append(planeCaseName(p.planeCase));
    sourceNames.append(normalSourceName(p.source));
  }
  d["case_name"] = caseNames;
  d["source"] = column<std::int32_t>(n, [&](std::size_t i) { return static_cast<std::int32_t>(ps[i].source); });
  d["source_name"] = sourceNames;
  d["point"] = rows(n, [&](std::size_t i) { return ps[i].point; });
  d["normal"] = rows(n, [&](std::size_t i) { return ps[i].normal; });
  d["depth"] = column<double>(n, [&](std::size_t i) { return ps[i].depth; });
  d["validated"] = column<bool>(n, [&](std::size_t i) { return ps[i].validated; });
  d["look_ahead"] = column<bool>(n, [&](std::size_t i) { return ps[i].lookAhead; });
  d["contacts"] = column<std::int32_t>(n, [&](std::size_t i) { return static_cast<std::int32_t>(ps[i].count); });
  return d;
}

py::dict stats(PyWorld& self) {
  const World& world = self.current();
  const StepStats& s = world.stats();
  py::dict d;
  d["step"] = s.step;
  d["contacts"] = s.contacts;
  d["max_penetration"] = s.maxPenetration;
  d["body_pairs"] = s.bodyPairs;
  d["plane_pairs"] = s.planePairs;
  d["patches"] = s.patches;
  d["patches_by_case"] = patchesByCaseDict(s.patchesByCase);
  d["unvalidated_patches"] = s.unvalidatedPatches;
  d["look_aheads"] = s.lookAheads;
  d["candidates"] = s.candidates;
  d["patches_reused"] = s.patchesReused;
  d["contact_points"] = s.contactPoints;
  d["connectors_broken"] = s.connectorsBroken;
  d["bodies_created"] = s.bodiesCreated;
  d["normals_recomputed"] = s.normalsRecomputed;
  py::dict t = stageSecondsDict(s.time);
  t["total"] = s.time.total;
  d["stage_seconds"] = t;
  return d;
}

PyWorld& of(const py::object& self) { return self.cast<PyWorld&>(); }

}  // namespace

World& PyWorld::get() {
  if (busy) raise("the world is being stepped in another thread; wait for step() or run() to return");
  return *world;
}

World& PyWorld::current() {
  World& w = get();
  if (contactsStale) {
    w.refreshContacts();
    contactsStale = false;
  }
  return w;
}

py::array view(py::object owner, PyWorld& world, const void* data, const py::dtype& dtype, std::vector<py::ssize_t> shape,
               std::vector<py::ssize_t> strides) {
  py::object base;
  if (shape[0] > 0) base = py::cast(new ViewGuard(std::move(owner), world), py::return_value_policy::take_ownership);
  py::array a = shape[0] > 0 ? py::array(dtype, std::move(shape), std::move(strides), data, base)
                             : py::array(dtype, std::move(shape), std::move(strides));
  a.attr("setflags")(py::arg("write") = false);
  return a;
}

py::array_t<double> rows3(const std::vector<Vec3>& v) {
  return rows(v.size(), [&](std::size_t i) { return v[i]; });
}

void bindWorld(py::module_& m) {
  py::class_<ViewGuard>(m, "_ViewGuard", R"doc(
The base of a zero-copy view of a World's particle arrays (array.base): it keeps the world alive while the
view is, and while any such view is alive the world refuses add_body() and glue(), which would move the
arrays' memory. Not made directly.
)doc")
      .def_property_readonly("world", &ViewGuard::owner, "The World whose memory the view shows.");

  std::vector<std::string> caseNames, sourceNames;
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) caseNames.emplace_back(planeCaseName(static_cast<PlaneCase>(k)));
  for (std::size_t k = 0; k < kNormalSourceCount; ++k) sourceNames.emplace_back(normalSourceName(static_cast<NormalSource>(k)));
  m.attr("CASE_NAMES") = py::tuple(py::cast(caseNames));
  m.attr("SOURCE_NAMES") = py::tuple(py::cast(sourceNames));

  py::class_<PyWorld>(m, "World", R"doc(
A simulated world: materials, planes, bodies of particles, and their state.

Made by Scene.build() (or build_scene()) from a scene, or empty by World(...) and filled from code with
add_material(), add_plane(), add_body() (clouds from fill_shape() or particle_list()) and glue(). Stepped by
step(); written to a trajectory by volpar.run().

Arrays: the particle arrays (positions, velocities, radii, masses, particle_bodies, particle_flags) are
read-only views of the engine's own memory without copying: they change as the world steps, and keep the world
alive. Everything else (bodies, contacts, patches, ...) is a new array each time: a copy of the moment.
Units are SI: m, m/s, kg, rad/s, J.
)doc")
      .def(py::init(&makeWorld), py::kw_only(), py::arg("dt") = 1.0 / 240.0,
           py::arg("gravity") = std::array<double, 3>{0.0, 0.0, -9.81}, py::arg("solver_iterations") = 10,
           py::arg("substeps") = 4, py::arg("seed") = 0, py::arg("threads") = 1, R"doc(
An empty world.

Keyword arguments:
    dt (float): time step [s], above 0 and at most 1.
    gravity (3 floats): [m/s^2].
    solver_iterations (int): contact solver iterations per step, 1 to 1000.
    substeps (int): XPBD substeps per step for deformable bodies, 1 to 1000.
    seed (int): seeds what is drawn at random (bond strengths with a Weibull modulus), 0 to 2**53.
    threads (int): worker threads for the steps, 1 to 256; the results do not depend on it.
)doc")
      // ---- building
      .def(
          "add_material",
          [](PyWorld& self, const Material& material) { return self.get().addMaterial(material).index(); },
          py::arg("material"), "Adds a Material; returns its index (for add_plane and add_body, which also take its name).")
      .def(
          "add_plane",
          [](PyWorld& self, const std::array<double, 3>& normal, double offset, const py::object& material) {
            World& w = self.get();
            Plane p;
            p.normal = direction(normal, "normal", "plane normal");
            p.offset = offset;
            if (!(std::abs(offset) <= kMaxLength))
              raise("offset: expected plane offset of at most 1e+06 m in magnitude, got " + repr(offset));
            p.material = materialId(w, material);
            w.addPlane(p);
            self.contactsStale = true;
            return w.planes().size() - 1;
          },
          py::arg("normal") = std::array<double, 3>{0.0, 0.0, 1.0}, py::arg("offset") = 0.0, py::kw_only(),
          py::arg("material") = 0, R"doc(
Adds a static half-space: the points x with normal . x <= offset are solid. normal: any non-zero direction
(normalised); offset [m]; material: index or name. Returns the plane's index.
)doc")
      .def("add_body", &addBody, py::arg("cloud"), py::kw_only(), py::arg("material") = 0, py::arg("name") = py::none(),
           py::arg("kind") = "rigid", py::arg("position") = std::array<double, 3>{0.0, 0.0, 0.0},
           py::arg("orientation") = std::array<double, 4>{1.0, 0.0, 0.0, 0.0},
           py::arg("velocity") = std::array<double, 3>{0.0, 0.0, 0.0},
           py::arg("angular_velocity") = std::array<double, 3>{0.0, 0.0, 0.0}, py::arg("connectors") = py::none(),
           py::arg("mass") = py::none(), py::arg("particle_mass") = py::none(), py::arg("mass_properties") = "solid",
           R"doc(
Makes a body of a ParticleCloud, as a scene's body entry is made (World::addBody); returns its index.

Keyword arguments:
    material (int | str): its material, by index or name (default: the first added).
    name (str | None): None: 'body<index>'.
    kind (str): 'rigid', 'deformable' or 'static'.
    position (3 floats): where the cloud's shape-frame origin goes [m].
    orientation (4 floats): rotation of the shape frame, quaternion (w, x, y, z), any non-zero length.
    velocity (3 floats): of the centre of mass [m/s]; angular_velocity (3 floats) [rad/s], world frame.
    connectors (Connectors | None): None: Connectors.rods(). Deformable bodies need springs or rods; what the
        connectors leave unset comes from the material, as in a scene.
    mass (float | None): total mass [kg], spread evenly; particle_mass: per particle [kg]; neither: the
        material's density x each particle's volume.
    mass_properties (str): 'solid' (a rigid body filled from a solid takes its exact inertia) or 'particles'.

Unlike a scene, bodies may overlap at the start. Raises volpar.Error for bad arguments, and while views of the
particle arrays are alive (adding particles moves those arrays: delete the views first).
)doc")
      .def("glue", &glue, py::arg("bodies"), py::kw_only(), py::arg("name") = "glued", py::arg("material") = 0,
           py::arg("reach") = 1.5, py::arg("radius") = 1.0, py::arg("pairs") = py::none(), R"doc(
Glues rigid bodies joined by bonds into one rigid body (a scene's `glue`; World::glue): touching particles of
different bodies are joined by bonds of the material's Young's modulus and strengths. Returns the new body's
index; the glued bodies are retired.

Arguments:
    bodies (list of int): the bodies.
    name (str): the glued body's name.
    material (int | str): the glue's material (needs youngs_modulus).
    reach (float): particles closer than reach x (r_a + r_b) are bonded, in (1, 4].
    radius (float): bond radius as a fraction of the smaller particle radius, in (0, 1].
    pairs (list of (int, int) | None): only these pairs of bodies are glued to each other.
)doc")
      .def(
          "refresh_contacts", [](PyWorld& self) { self.current().refreshContacts(); },
          "Finds the contacts of the current state again (done by step(), and before contacts() and patches() after bodies were added).")
      // ---- stepping
      .def("step", &step, py::arg("n") = 1, R"doc(
Advances the world by n steps of dt (n from 0 to 10**12), without the GIL: other Python threads run
meanwhile (they cannot use this world until it returns, and should not read its views). Ctrl-C stops it after
the current step with KeyboardInterrupt. Raises volpar.Error when the state becomes non-finite (with the
message `volpar run` prints).
)doc")
      .def(
          "set_threads",
          [](PyWorld& self, py::handle threads, bool shareAll) { self.get().setThreads(threadCount(threads), shareAll); },
          py::arg("threads"), py::arg("share_all") = false, R"doc(
Worker threads for later steps, 1 to 256 (as `volpar run --threads`; 1 = the calling thread only). The results
are the same bit for bit with any number. share_all: also share work too small to be worth waking the workers.
)doc")
      .def_property_readonly("threads", [](PyWorld& self) { return self.get().settings().threads; }, "Worker threads.")
      // ---- settings, time, energy
      .def_property_readonly("dt", [](PyWorld& self) { return self.get().settings().dt; }, "Time step [s].")
      .def_property_readonly(
          "gravity", [](PyWorld& self) { const Vec3 g = self.get().settings().gravity; return py::make_tuple(g.x(), g.y(), g.z()); },
          "Gravity (x, y, z) [m/s^2].")
      .def_property_readonly("seed", [](PyWorld& self) { return self.get().settings().seed; }, "The seed of what is drawn at random.")
      .def_property_readonly("time", [](PyWorld& self) { return self.get().time(); }, "Simulated time [s]: step_index * dt.")
      .def_property_readonly("step_index", [](PyWorld& self) { return self.get().stepIndex(); },
                             "Steps taken so far (0 for a new world).")
      .def(
          "energy",
          [](PyWorld& self) {
            const EnergyReport e = self.get().energy();
            py::dict d;
            d["kinetic"] = e.kinetic;
            d["potential"] = e.potential;
            d["total"] = e.total();
            return d;
          },
          "Energies of the world [J]: a dict with 'kinetic', 'potential' (gravitational relative to the origin, plus "
          "elastic) and 'total'.")
      .def(
          "linear_momentum",
          [](PyWorld& self) { const Vec3 p = self.get().linearMomentum(); return py::make_tuple(p.x(), p.y(), p.z()); },
          "Total linear momentum (x, y, z) [kg m/s].")
      .def(
          "angular_momentum",
          [](PyWorld& self) { const Vec3 p = self.get().angularMomentum(); return py::make_tuple(p.x(), p.y(), p.z()); },
          "Total angular momentum about the origin (x, y, z) [kg m^2/s].")
      .def("stats", &stats, R"doc(
Counters and timings of the last step (a dict): 'step', 'contacts' (touching pairs), 'max_penetration' [m],
'body_pairs', 'plane_pairs', 'patches', 'patches_by_case' (dict by case name), 'unvalidated_patches',
'look_aheads', 'candidates', 'patches_reused', 'contact_points', 'connectors_broken', 'bodies_created',
'normals_recomputed', 'stage_seconds' (dict of wall seconds by stage).
)doc")
      // ---- particles: views
      .def_property_readonly("particle_count", [](PyWorld& self) { return self.get().particles().size(); },
                             "Number of particles P.")
      .def_property_readonly(
          "positions",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.position.data(), py::dtype::of<double>(), {static_cast<py::ssize_t>(p.size()), 3},
                        {static_cast<py::ssize_t>(sizeof(Vec3)), static_cast<py::ssize_t>(sizeof(double))});
          },
          "Particle centres, world frame [m]: float64 array [P, 3], a read-only view (no copy) that follows the world as "
          "it steps.")
      .def_property_readonly(
          "velocities",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.velocity.data(), py::dtype::of<double>(), {static_cast<py::ssize_t>(p.size()), 3},
                        {static_cast<py::ssize_t>(sizeof(Vec3)), static_cast<py::ssize_t>(sizeof(double))});
          },
          "Particle velocities, world frame [m/s]: float64 array [P, 3], a read-only view (no copy).")
      .def_property_readonly(
          "radii",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.radius.data(), py::dtype::of<double>(), {static_cast<py::ssize_t>(p.size())},
                        {static_cast<py::ssize_t>(sizeof(double))});
          },
          "Particle radii [m]: float64 array [P], a read-only view (no copy).")
      .def_property_readonly(
          "masses",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.mass.data(), py::dtype::of<double>(), {static_cast<py::ssize_t>(p.size())},
                        {static_cast<py::ssize_t>(sizeof(double))});
          },
          "Particle masses [kg]: float64 array [P], a read-only view (no copy).")
      .def_property_readonly(
          "particle_bodies",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.body.data(), py::dtype::of<std::uint32_t>(), {static_cast<py::ssize_t>(p.size())},
                        {static_cast<py::ssize_t>(sizeof(BodyId))});
          },
          "Index of each particle's body: uint32 array [P], a read-only view (no copy); it changes where a body breaks "
          "apart.")
      .def_property_readonly(
          "particle_flags",
          [](const py::object& self) {
            PyWorld& w = of(self);
            const ParticleStore& p = w.get().particles();
            return view(self, w, p.flags.data(), py::dtype::of<std::uint8_t>(), {static_cast<py::ssize_t>(p.size())},
                        {py::ssize_t{1}});
          },
          "Surface flags of each particle (1 surface, 2 edge, 4 corner, 8 sheet, 16 line): uint8 array [P], a "
          "read-only view (no copy).")
      // ---- bodies: copies
      .def_property_readonly("body_count", [](PyWorld& self) { return self.get().bodies().size(); },
                             "Number of bodies B ever created (retired ones included).")
      .def_property_readonly(
          "body_names",
          [](PyWorld& self) {
            std::vector<std::string> names;
            for (const BodyInfo& i : self.get().bodies().info) names.push_back(i.name);
            return names;
          },
          "Body names (list of str).")
      .def_property_readonly(
          "body_kinds",
          [](PyWorld& self) {
            std::vector<std::string> kinds;
            for (const BodyInfo& i : self.get().bodies().info) kinds.emplace_back(kindName(i.kind));
            return kinds;
          },
          "Body kinds: 'rigid', 'deformable' or 'static' (list of str).")
      .def_property_readonly(
          "body_alive",
          [](PyWorld& self) {
            const BodyStore& b = self.get().bodies();
            return column<bool>(b.size(), [&](std::size_t i) { return b.info[i].alive; });
          },
          "Whether each body exists now (False once it broke apart or was glued): bool array [B] (a copy).")
      .def_property_readonly(
          "body_masses",
          [](PyWorld& self) {
            const BodyStore& b = self.get().bodies();
            return column<double>(b.size(), [&](std::size_t i) { return b.info[i].mass; });
          },
          "Body masses [kg]: float64 array [B] (a copy).")
      .def_property_readonly(
          "body_positions",
          [](PyWorld& self) {
            const World& w = self.get();
            return vectors(w, [&](std::size_t i) { return w.bodies().state[i].position; });
          },
          "Centres of mass, world frame [m]: float64 array [B, 3] (a copy; NaN for bodies that no longer exist).")
      .def_property_readonly(
          "body_orientations",
          [](PyWorld& self) {
            const BodyStore& b = self.get().bodies();
            py::array_t<double> a({static_cast<py::ssize_t>(b.size()), py::ssize_t{4}});
            auto out = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < b.size(); ++i) {
              const Quat q = b.shapeOrientation(BodyId(i));
              const bool alive = b.info[i].alive;
              const auto r = static_cast<py::ssize_t>(i);
              out(r, 0) = alive ? q.w() : kNan;
              out(r, 1) = alive ? q.x() : kNan;
              out(r, 2) = alive ? q.y() : kNan;
              out(r, 3) = alive ? q.z() : kNan;
            }
            return a;
          },
          "Orientations of the bodies' shape frames as unit quaternions (w, x, y, z), scalar first: float64 array "
          "[B, 4] (a copy; identity for deformable bodies, NaN for bodies that no longer exist). The same as the "
          "trajectory's /particles/bodies/orientation.")
      .def_property_readonly(
          "body_velocities",
          [](PyWorld& self) {
            const World& w = self.get();
            return vectors(w, [&](std::size_t i) { return w.bodies().state[i].linearVelocity; });
          },
          "Velocities of the centres of mass, world frame [m/s]: float64 array [B, 3] (a copy; NaN for bodies that no "
          "longer exist).")
      .def_property_readonly(
          "body_angular_velocities",
          [](PyWorld& self) {
            const World& w = self.get();
            return vectors(w, [&](std::size_t i) { return w.bodies().state[i].angularVelocity; });
          },
          "Angular velocities, world frame [rad/s]: float64 array [B, 3] (a copy; NaN for bodies that no longer exist).")
      .def(
          "body_particles",
          [](PyWorld& self, py::handle body) {
            const BodyStore& b = self.get().bodies();
            if (b.size() == 0) raise("body: the world has no bodies");
            const auto i = static_cast<std::size_t>(wholeNumber(body, "body", 0, static_cast<long long>(b.size()) - 1));
            const auto& ps = b.info[i].particles;
            return column<std::uint32_t>(ps.size(), [&](std::size_t k) { return ps[k].value; });
          },
          py::arg("body"), "The particles of a body, ascending: uint32 array (a copy; empty once it no longer exists).")
      // ---- materials and planes
      .def_property_readonly("materials", [](PyWorld& self) { return self.get().materials(); },
                             "The materials (list of Material copies), by index.")
      .def_property_readonly(
          "planes",
          [](PyWorld& self) {
            const auto& planes = self.get().planes();
            py::array_t<double> a({static_cast<py::ssize_t>(planes.size()), py::ssize_t{4}});
            auto out = a.mutable_unchecked<2>();
            for (std::size_t i = 0; i < planes.size(); ++i) {
              const auto r = static_cast<py::ssize_t>(i);
              for (int k = 0; k < 3; ++k) out(r, k) = planes[i].normal[k];
              out(r, 3) = planes[i].offset;
            }
            return a;
          },
          "The planes: float64 array [n, 4], unit normal (3) and offset [m] of each (a copy).")
      // ---- contacts
      .def("contacts", &contacts, py::kw_only(), py::arg("speculative") = false, R"doc(
The particle contacts of the current state (a dict of new arrays, N rows; the trajectory's /contacts):
    'particle_a' int32 [N]: particle (of the body with the lower index, or the one touching a plane)
    'particle_b' int32 [N]: the other particle, -1 for a particle-plane contact
    'plane' int32 [N]: plane index, -1 for a particle pair
    'point' float64 [N, 3]: midpoint of the overlap on the centre line [m]
    'normal' float64 [N, 3]: unit centre-line direction from particle_a towards particle_b (into the plane)
    'depth' float64 [N]: overlap along the centre line [m]; negative: the gap of a speculative contact
speculative: also the pairs within reach but not yet touching (depth <= 0), which the solver considers.
)doc")
      .def("patches", &patches, R"doc(
The contact patches of the current state, one separating plane each (a dict of new arrays, N rows; the
trajectory's /patches; docs/narrow-phase.md):
    'body_a', 'body_b' int32 [N]: the bodies (body_b -1 for a body-plane patch, body_a for a deformable body
        touching itself); 'plane' int32 [N]: plane index or -1
    'case' int32 [N]: the plane case, an index into volpar.CASE_NAMES; 'case_name': list of those names
    'source' int32 [N]: where the normal came from, an index into volpar.SOURCE_NAMES; 'source_name': names
    'point' float64 [N, 3]: the deepest contact point [m]; 'normal' float64 [N, 3]: unit, from body_a towards
        body_b; 'depth' float64 [N]: the largest overlap along the normal [m]
    'validated' bool [N]: the normal passed validation; 'look_ahead' bool [N]: a look-ahead decided it
    'contacts' int32 [N]: the particle contacts in the patch, speculative ones included
)doc")
      // ---- where it came from
      .def_property_readonly(
          "scene_name", [](PyWorld& self) { return self.scene ? py::object(py::str(self.scene->name)) : py::object(py::none()); },
          "The name of the scene it was built from (None for a world built from code).")
      .def_property_readonly(
          "scene_file", [](PyWorld& self) { return self.scene ? py::object(py::str(self.scene->file)) : py::object(py::none()); },
          "The path of the scene it was built from, as given (None for a world built from code).")
      .def_property_readonly(
          "notes", [](PyWorld& self) { return self.scene ? self.scene->notes : std::vector<std::string>{}; },
          "What `volpar run` prints as notes about the build (bodies whose particles fall short of their solid).")
      .def(
          "__repr__",
          [](PyWorld& self) {
            if (self.busy) return std::string("<volpar.World (stepping)>");
            const World& w = *self.world;
            return "<volpar.World: " + std::to_string(w.bodies().size()) + " bodies, " +
                   std::to_string(w.particles().size()) + " particles, step " + std::to_string(w.stepIndex()) +
                   ", t = " + repr(w.time()) + " s>";
          },
          "Bodies, particles, step and time of the world.");
}

}  // namespace volpar::python
