// Builders: shapes, fill_shape, particle_list, ParticleCloud, Material and Connectors, as
// engine/builders/ and the scene builder use them.

#include <cmath>
#include <limits>
#include <sstream>

#include "python/src/common.hpp"
#include "volpar/engine/builders/obj_reader.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/core/material.hpp"
#include "volpar/engine/scene/scene_build.hpp"

namespace volpar::python {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

std::string format(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

/// A solid shape and the SourceShape a body filled from it records (as the scene builder's sourceOf).
struct PyShape {
  virtual ~PyShape() = default;
  std::shared_ptr<const SolidShape> solid;
  SourceShape source;
  std::string repr;
};
struct PyBox : PyShape {};
struct PySphere : PyShape {};
struct PyCylinder : PyShape {};
struct PyCapsule : PyShape {};
struct PyMesh : PyShape {};

std::shared_ptr<PyBox> makeBox(const std::array<double, 3>& size) {
  const Vec3 s = vec3(size, "size", "box size", kMaxLength, "m");
  for (int k = 0; k < 3; ++k)
    if (!(s[k] > 0.0)) raise("size: expected positive components for box size [m], got " + repr(s[k]));
  auto b = std::make_shared<PyBox>();
  b->solid = std::make_shared<BoxShape>(s);
  b->source.kind = SourceShape::Kind::Box;
  b->source.size = s;
  b->repr = "volpar.Box(size=(" + repr(s.x()) + ", " + repr(s.y()) + ", " + repr(s.z()) + "))";
  return b;
}

std::shared_ptr<PySphere> makeSphere(double radius) {
  positive(radius, "radius", "sphere radius", "m");
  auto b = std::make_shared<PySphere>();
  b->solid = std::make_shared<SphereShape>(radius);
  b->source.kind = SourceShape::Kind::Sphere;
  b->source.radius = radius;
  b->repr = "volpar.Sphere(radius=" + repr(radius) + ")";
  return b;
}

std::shared_ptr<PyCylinder> makeCylinder(double radius, double height) {
  positive(radius, "radius", "cylinder radius", "m");
  positive(height, "height", "cylinder height", "m");
  auto b = std::make_shared<PyCylinder>();
  b->solid = std::make_shared<CylinderShape>(radius, height);
  b->source.kind = SourceShape::Kind::Cylinder;
  b->source.radius = radius;
  b->source.length = height;
  b->repr = "volpar.Cylinder(radius=" + repr(radius) + ", height=" + repr(height) + ")";
  return b;
}

std::shared_ptr<PyCapsule> makeCapsule(double radius, double length) {
  positive(radius, "radius", "capsule radius", "m");
  nonNegative(length, "length", "capsule segment length", "m");
  auto b = std::make_shared<PyCapsule>();
  b->solid = std::make_shared<CapsuleShape>(radius, length);
  b->source.kind = SourceShape::Kind::Capsule;
  b->source.radius = radius;
  b->source.length = length;
  b->repr = "volpar.Capsule(radius=" + repr(radius) + ", length=" + repr(length) + ")";
  return b;
}

std::shared_ptr<PyMesh> makeMesh(const std::filesystem::path& path, double scale) {
  positive(scale, "scale", "mesh scale", "-");
  const std::string file = path.string();
  Result<TriangleMesh> mesh = Error{};
  {
    py::gil_scoped_release release;
    mesh = readObj(file, scale);
    if (mesh) {
      if (auto ok = mesh->makeSolid(); !ok) mesh = ok.error();
    }
  }
  TriangleMesh m = take(std::move(mesh));
  auto b = std::make_shared<PyMesh>();
  b->source.kind = SourceShape::Kind::Mesh;
  b->source.facePlanes = m.convexFacePlanes();
  b->solid = std::make_shared<MeshShape>(std::make_shared<const TriangleMesh>(std::move(m)));
  b->repr = "volpar.Mesh(" + str(py::repr(py::str(file))) + ", scale=" + repr(scale) + ")";
  return b;
}

PyCloud fill(const PyShape& shape, double radius, const std::string& lattice, py::object spacing, double reach,
             const std::string& normals) {
  FillSettings f;
  f.lattice = oneOf(lattice, "lattice", "lattice", {"cubic", "hcp"}) == "hcp" ? Lattice::Hcp : Lattice::Cubic;
  f.radius = positive(radius, "radius", "particle radius", "m");
  if (!spacing.is_none()) f.spacing = positive(number(spacing, "spacing"), "spacing", "lattice spacing", "m");
  if (!(reach > 1.0 && reach <= 4.0))
    raise("reach: expected reach in (1, 4] lattice spacings (nearest neighbours sit at 1), got " + repr(reach));
  f.reach = reach;
  const bool estimated = oneOf(normals, "normals", "normals", {"shape", "estimated"}) == "estimated";
  // refuse absurd particle counts before filling (as the scene builder)
  const double s = f.spacing > 0.0 ? f.spacing : 2.0 * f.radius;
  const double estimate = shape.solid->volume() / latticeCellVolume(f.lattice, s);
  if (!(estimate < static_cast<double>(kMaxSceneParticles)))
    raise("filling the " + shape.solid->describe() + " with particles of radius " + format(f.radius) +
          " m would create about " + format(estimate) + " particles; expected at most " +
          std::to_string(kMaxSceneParticles) + " (use a larger radius)");
  PyCloud out;
  Result<ParticleCloud> cloud = Error{};
  {
    py::gil_scoped_release release;
    cloud = fillShape(*shape.solid, f);
    if (cloud && estimated) useEstimatedNormals(*cloud);
  }
  out.cloud = take(std::move(cloud));
  out.source = shape.source;
  out.source.estimatedNormals = estimated;
  out.lattice = f.lattice;
  out.reach = f.reach;
  out.filled = true;
  return out;
}

using Doubles = py::array_t<double, py::array::c_style | py::array::forcecast>;

PyCloud particleList(const py::object& positions, const py::object& radii, const py::object& connectors,
                     const py::object& reach) {
  ParticleListSettings s;
  const Doubles p = Doubles::ensure(positions);
  if (!p || p.ndim() != 2 || p.shape(1) != 3 || p.shape(0) == 0) {
    PyErr_Clear();
    raise("positions: expected a non-empty list of positions [[x, y, z], ...]");
  }
  const auto n = static_cast<std::size_t>(p.shape(0));
  const auto pv = p.unchecked<2>();
  for (py::ssize_t i = 0; i < p.shape(0); ++i)
    s.positions.push_back(vec3({pv(i, 0), pv(i, 1), pv(i, 2)}, "positions", "position", kMaxLength, "m"));
  const Doubles r = Doubles::ensure(radii);
  if (!r || r.ndim() > 1) {
    PyErr_Clear();
    raise("radii: expected a radius [m] for all particles or a list of " + std::to_string(n) + " radii, one per position");
  }
  const auto count = static_cast<std::size_t>(r.size());
  if (r.ndim() == 1 && count != n && count != 1)
    raise("radii: expected a list of " + std::to_string(n) + " radii, one per position, got " + std::to_string(count));
  for (py::ssize_t i = 0; i < r.size(); ++i) s.radii.push_back(positive(r.data()[i], "radii", "particle radius", "m"));
  if (!connectors.is_none()) {
    using Indices = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;
    const Indices c = Indices::ensure(connectors);
    if (!c) PyErr_Clear();
    if (!c || (c.size() > 0 && !(c.ndim() == 2 && c.shape(1) == 2)))
      raise("connectors: expected a list of particle index pairs [[i, j], ...]");
    if (c.size() > 0) {
      const auto cv = c.unchecked<2>();
      for (py::ssize_t k = 0; k < c.shape(0); ++k) {
        for (int e = 0; e < 2; ++e)
          if (cv(k, e) < 0 || cv(k, e) >= static_cast<std::int64_t>(n))
            raise("connectors: particle index " + std::to_string(cv(k, e)) + " out of range; expected 0 to " +
                  std::to_string(n - 1));
        s.connectors.push_back({static_cast<std::uint32_t>(cv(k, 0)), static_cast<std::uint32_t>(cv(k, 1))});
      }
    }
    s.explicitConnectors = true;
    if (!reach.is_none()) raise("reach: 'reach' cannot be combined with explicit 'connectors'");
  }
  if (!reach.is_none()) s.reach = positive(number(reach, "reach"), "reach", "reach", "m");
  PyCloud out;
  Result<ParticleCloud> cloud = Error{};
  {
    py::gil_scoped_release release;
    cloud = buildParticleList(s);
  }
  out.cloud = take(std::move(cloud));
  out.source.estimatedNormals = true;  // (a particle list has no solid: its normals are always estimated)
  return out;
}

Material makeMaterial(const std::string& name, double density, double restitution, double friction,
                      double rollingResistance, py::object rodStrength, py::object rodCompressiveStrength,
                      py::object strainLimit, py::object youngsModulus, double poissonRatio, py::object tensileStrength,
                      py::object shearStrength, py::object weibullModulus) {
  // the scene loader's checks of the same keys (engine/scene/scene_loader.cpp: material)
  Material m;
  m.name = name;
  m.density = positive(density, "density", "density", "kg/m^3");
  m.restitution = inRange(restitution, "restitution", "restitution", 0.0, 1.0);
  m.friction = nonNegative(friction, "friction", "friction", "-");
  m.rollingResistance = nonNegative(rollingResistance, "rolling_resistance", "rolling resistance", "-");
  const auto optionalPositive = [](const py::object& v, const char* arg, const char* what, const char* unit, double unset) {
    return v.is_none() ? unset : positive(number(v, arg), arg, what, unit);
  };
  m.rodStrength = optionalPositive(rodStrength, "rod_strength", "rod strength", "N", kInf);
  m.rodCompressiveStrength = optionalPositive(rodCompressiveStrength, "rod_compressive_strength", "rod compressive strength", "N", 0.0);
  m.strainLimit = optionalPositive(strainLimit, "strain_limit", "spring strain limit", "-", kInf);
  m.youngsModulus = optionalPositive(youngsModulus, "youngs_modulus", "Young's modulus", "Pa", 0.0);
  if (!(poissonRatio > -1.0 && poissonRatio < 0.5))
    raise("poisson_ratio: expected a Poisson's ratio in (-1, 0.5), got " + repr(poissonRatio));
  m.poissonRatio = poissonRatio;
  m.tensileStrength = optionalPositive(tensileStrength, "tensile_strength", "tensile strength", "Pa", kInf);
  m.shearStrength = optionalPositive(shearStrength, "shear_strength", "shear strength", "Pa", kInf);
  m.weibullModulus = optionalPositive(weibullModulus, "weibull_modulus", "Weibull modulus", "-", 0.0);
  return m;
}

py::object orNone(double v, double unset) { return v == unset ? py::object(py::none()) : py::object(py::float_(v)); }

}  // namespace

void bindBuilders(py::module_& m) {
  // ---- shapes
  py::class_<PyShape, std::shared_ptr<PyShape>>(m, "Shape", R"doc(
A solid shape that fill_shape() fills with particles: Box, Sphere, Cylinder, Capsule or Mesh. Primitives are
centred at the origin of their shape frame (cylinders and capsules along its z axis); a mesh keeps its file's
coordinates. Lengths in metres.
)doc")
      .def_property_readonly("volume", [](const PyShape& s) { return s.solid->volume(); }, "Exact volume [m^3].")
      .def_property_readonly(
          "bounds",
          [](const PyShape& s) {
            const auto b = s.solid->bounds();
            return py::make_tuple(py::make_tuple(b.min().x(), b.min().y(), b.min().z()),
                                  py::make_tuple(b.max().x(), b.max().y(), b.max().z()));
          },
          "Axis-aligned bounds in the shape frame: ((xmin, ymin, zmin), (xmax, ymax, zmax)) [m].")
      .def_property_readonly("description", [](const PyShape& s) { return s.solid->describe(); },
                             "Short description, e.g. 'box 0.3 x 0.3 x 0.3 m'.")
      .def("__repr__", [](const PyShape& s) { return s.repr; }, "The shape as the call that makes it.");
  py::class_<PyBox, PyShape, std::shared_ptr<PyBox>>(m, "Box", "A box of full side lengths `size` (x, y, z) [m].")
      .def(py::init(&makeBox), py::arg("size"), "Box(size): size is a sequence of 3 positive side lengths [m].");
  py::class_<PySphere, PyShape, std::shared_ptr<PySphere>>(m, "Sphere", "A sphere of radius `radius` [m].")
      .def(py::init(&makeSphere), py::arg("radius"), "Sphere(radius) [m].");
  py::class_<PyCylinder, PyShape, std::shared_ptr<PyCylinder>>(
      m, "Cylinder", "A cylinder of radius `radius` and total height `height` [m], its axis along shape z.")
      .def(py::init(&makeCylinder), py::arg("radius"), py::arg("height"), "Cylinder(radius, height) [m].");
  py::class_<PyCapsule, PyShape, std::shared_ptr<PyCapsule>>(
      m, "Capsule",
      "A capsule: the points within `radius` of a segment of length `length` along shape z [m]; its total length is "
      "length + 2 radius.")
      .def(py::init(&makeCapsule), py::arg("radius"), py::arg("length"), "Capsule(radius, length) [m].");
  py::class_<PyMesh, PyShape, std::shared_ptr<PyMesh>>(
      m, "Mesh",
      "A closed, consistently oriented triangle mesh read from a Wavefront OBJ file, scaled by `scale`; it keeps the "
      "file's coordinates [m].")
      .def(py::init(&makeMesh), py::arg("path"), py::arg("scale") = 1.0, R"doc(
Mesh(path, scale=1.0): reads the OBJ file (at most 256 MiB) and checks that it is a closed solid. Raises
volpar.Error ('PATH:LINE:COLUMN: ...') for a file that cannot be read or is no closed solid.
)doc");

  // ---- particle clouds
  py::class_<PyCloud>(m, "ParticleCloud", R"doc(
Particles in a shape frame, ready to become a body (World.add_body): what fill_shape() and particle_list()
make. The arrays are copies.
)doc")
      .def("__len__", [](const PyCloud& c) { return c.cloud.size(); }, "Number of particles.")
      .def_property_readonly("positions", [](const PyCloud& c) { return rows3(c.cloud.positions); },
                             "Particle centres in the shape frame, float64 array [N, 3] [m] (a copy).")
      .def_property_readonly("radii", [](const PyCloud& c) { return py::array_t<double>(py::cast(c.cloud.radii)); },
                             "Particle radii, float64 array [N] [m] (a copy).")
      .def_property_readonly("volumes", [](const PyCloud& c) { return py::array_t<double>(py::cast(c.cloud.volumes)); },
                             "The volume each particle stands for, float64 array [N] [m^3] (a copy).")
      .def_property_readonly("normals", [](const PyCloud& c) { return rows3(c.cloud.normals); },
                             "Outward unit normals of surface particles (zero for interior ones), shape frame, float64 [N, 3].")
      .def_property_readonly(
          "connectors",
          [](const PyCloud& c) {
            py::array_t<std::uint32_t> a({static_cast<py::ssize_t>(c.cloud.connectors.size()), py::ssize_t{2}});
            auto w = a.mutable_unchecked<2>();
            for (std::size_t k = 0; k < c.cloud.connectors.size(); ++k) {
              w(static_cast<py::ssize_t>(k), 0) = c.cloud.connectors[k][0];
              w(static_cast<py::ssize_t>(k), 1) = c.cloud.connectors[k][1];
            }
            return a;
          },
          "Joined particle pairs (i < j), uint32 array [C, 2] (a copy).")
      .def_property_readonly("spacing", [](const PyCloud& c) { return c.cloud.spacing; },
                             "Lattice spacing [m]; 0 for a particle list.")
      .def_property_readonly(
          "pinned",
          [](const PyCloud& c) {
            py::array_t<bool> a(static_cast<py::ssize_t>(c.cloud.size()));
            auto w = a.mutable_unchecked<1>();
            for (std::size_t i = 0; i < c.cloud.size(); ++i)
              w(static_cast<py::ssize_t>(i)) = i < c.cloud.pinned.size() && c.cloud.pinned[i] != 0;
            return a;
          },
          "Whether each particle is held fixed in space (deformable bodies only), bool array [N] (a copy).")
      .def(
          "pin",
          [](PyCloud& c, const std::array<double, 3>& lo, const std::array<double, 3>& hi) {
            const Vec3 a = vec3(lo, "min", "pin min", kMaxLength, "m"), b = vec3(hi, "max", "pin max", kMaxLength, "m");
            if (!(a.array() <= b.array()).all()) raise("max: expected pin max >= pin min in every coordinate");
            const Eigen::AlignedBox3d box(a, b);
            c.cloud.pinned.resize(c.cloud.size(), 0);
            std::size_t held = 0;
            for (std::size_t i = 0; i < c.cloud.size(); ++i)
              if (box.contains(c.cloud.positions[i])) {
                c.cloud.pinned[i] = 1;
                ++held;
              }
            if (held == 0) raise("this pin box holds no particle of the body (in its shape frame)");
            return held;
          },
          py::arg("min"), py::arg("max"), R"doc(
Holds the particles inside the box [min, max] (shape frame [m]) fixed in space, as a scene's `pin` does; only
a deformable body keeps them fixed. Returns how many particles the box holds; raises volpar.Error where it
holds none.
)doc");

  m.def("fill_shape", &fill, py::arg("shape"), py::arg("radius"), py::kw_only(), py::arg("lattice") = "cubic",
        py::arg("spacing") = py::none(), py::arg("reach") = 1.5, py::arg("normals") = "shape", R"doc(
Fills a Shape with particles on a lattice and returns the ParticleCloud, as a scene body's `fill` does
(engine/builders/fill.hpp).

Arguments:
    shape (Shape): Box, Sphere, Cylinder, Capsule or Mesh.
    radius (float): particle radius [m].
    lattice (str): 'cubic' or 'hcp'.
    spacing (float | None): distance between nearest sites [m]; None: 2 x radius (touching).
    reach (float): particles closer than reach x spacing are joined by connectors, in (1, 4].
    normals (str): 'shape' (the solid's exact surface normals) or 'estimated' (from the particles alone).

Raises volpar.Error for arguments out of range (worded as the scene loader's messages), when no particle fits,
or when the fill would create more than 50 000 000 particles.
)doc");
  m.def("particle_list", &particleList, py::arg("positions"), py::arg("radii"), py::kw_only(),
        py::arg("connectors") = py::none(), py::arg("reach") = py::none(), R"doc(
An explicit particle list as a ParticleCloud (a scene's `shape: {particles: ...}`).

Arguments:
    positions (array-like [N, 3]): centres in the shape frame [m].
    radii (float or array-like [N]): one radius for all [m], or one per particle.
    connectors (array-like [C, 2] of int | None): exactly these particle pairs are joined; None: particles
        closer than `reach` are.
    reach (float | None): [m]; None: 1.5 x the largest diameter. Not with `connectors`.

Each particle stands for the volume of its sphere; surface normals are estimated from the connectors.
)doc");

  // ---- materials
  py::class_<Material>(m, "Material", R"doc(
Surface and bulk properties of bodies and planes (a scene's `materials` entry; engine/core/material.hpp).
SI units. The thresholds left at None are not set: connectors of bodies made of the material then never
break (rods, springs), bonds take their own.
)doc")
      .def(py::init(&makeMaterial), py::arg("name") = "default", py::kw_only(), py::arg("density") = 1000.0,
           py::arg("restitution") = 0.5, py::arg("friction") = 0.5, py::arg("rolling_resistance") = 0.0,
           py::arg("rod_strength") = py::none(), py::arg("rod_compressive_strength") = py::none(),
           py::arg("strain_limit") = py::none(), py::arg("youngs_modulus") = py::none(),
           py::arg("poisson_ratio") = 0.25, py::arg("tensile_strength") = py::none(),
           py::arg("shear_strength") = py::none(), py::arg("weibull_modulus") = py::none(), R"doc(
Material(name='default', *, density=1000.0 [kg/m^3], restitution=0.5 [-, 0 to 1], friction=0.5 [-],
rolling_resistance=0.0 [-], rod_strength=None [N], rod_compressive_strength=None [N] (None: 10 x
rod_strength), strain_limit=None [-] (springs), youngs_modulus=None [Pa] (bonds, glue, springs calibrated
from it), poisson_ratio=0.25 [-], tensile_strength=None [Pa], shear_strength=None [Pa] (bonds),
weibull_modulus=None [-] (bond strengths drawn at random)).

Values are checked as the scene loader checks them; volpar.Error names the argument.
)doc")
      .def_readonly("name", &Material::name, "Name (str).")
      .def_readonly("density", &Material::density, "[kg/m^3]")
      .def_readonly("restitution", &Material::restitution, "[-]")
      .def_readonly("friction", &Material::friction, "Coulomb coefficient [-]")
      .def_readonly("rolling_resistance", &Material::rollingResistance, "[-]")
      .def_property_readonly("rod_strength", [](const Material& x) { return orNone(x.rodStrength, kInf); }, "[N] or None")
      .def_property_readonly("rod_compressive_strength",
                             [](const Material& x) { return orNone(x.rodCompressiveStrength, 0.0); }, "[N] or None")
      .def_property_readonly("strain_limit", [](const Material& x) { return orNone(x.strainLimit, kInf); }, "[-] or None")
      .def_property_readonly("youngs_modulus", [](const Material& x) { return orNone(x.youngsModulus, 0.0); }, "[Pa] or None")
      .def_readonly("poisson_ratio", &Material::poissonRatio, "[-]")
      .def_property_readonly("tensile_strength", [](const Material& x) { return orNone(x.tensileStrength, kInf); }, "[Pa] or None")
      .def_property_readonly("shear_strength", [](const Material& x) { return orNone(x.shearStrength, kInf); }, "[Pa] or None")
      .def_property_readonly("weibull_modulus", [](const Material& x) { return orNone(x.weibullModulus, 0.0); }, "[-] or None")
      .def(
          "__repr__",
          [](const Material& x) {
            return "volpar.Material(" + str(py::repr(py::str(x.name))) + ", density=" + repr(x.density) +
                   ", restitution=" + repr(x.restitution) + ", friction=" + repr(x.friction) + ")";
          },
          "The material's name, density, restitution and friction.");

  // ---- connectors
  py::class_<ConnectorParams>(m, "Connectors", R"doc(
How the particles of a body are joined (a scene body's `connectors`; engine/core/connector_store.hpp). Made
by Connectors.rods(), Connectors.springs() or Connectors.bonds(); World.add_body takes rods when given none.
What is left at None comes from the body's material, as in a scene.
)doc")
      .def_static(
          "rods",
          [](py::object strength, py::object compressiveStrength) {
            ConnectorParams c;
            if (!strength.is_none()) c.breakLimit = positive(number(strength, "strength"), "strength", "rod strength", "N");
            if (!compressiveStrength.is_none())
              c.compressionLimit = positive(number(compressiveStrength, "compressive_strength"), "compressive_strength",
                                            "rod compressive strength", "N");
            return c;
          },
          py::kw_only(), py::arg("strength") = py::none(), py::arg("compressive_strength") = py::none(), R"doc(
Rigid rods (rigid, static and deformable bodies). strength: the tensile force above which a rod breaks [N];
compressive_strength: the compressive force above which it crushes [N]. None: the material's rod_strength
(and rod_compressive_strength, or 10 x the strength).
)doc")
      .def_static(
          "springs",
          [](py::object stiffness, double damping, py::object strainLimit) {
            ConnectorParams c;
            c.kind = ConnectorKind::Spring;
            if (!stiffness.is_none()) c.stiffness = positive(number(stiffness, "stiffness"), "stiffness", "spring stiffness", "N/m");
            c.damping = nonNegative(damping, "damping", "spring damping", "N s/m");
            if (!strainLimit.is_none())
              c.breakLimit = positive(number(strainLimit, "strain_limit"), "strain_limit", "spring strain limit", "-");
            return c;
          },
          py::kw_only(), py::arg("stiffness") = py::none(), py::arg("damping") = 0.0, py::arg("strain_limit") = py::none(),
          R"doc(
Springs (deformable bodies only). stiffness [N/m]; None: calibrated from the material's youngs_modulus and
poisson_ratio for the lattice of a cloud from fill_shape(). damping [N s/m]. strain_limit: the strain above
which a spring breaks [-]; None: the material's.
)doc")
      .def_static(
          "bonds",
          [](py::object tensileStrength, py::object shearStrength, py::object weibullModulus, double radius) {
            ConnectorParams c;
            c.kind = ConnectorKind::Bond;
            if (!tensileStrength.is_none())
              c.bond.tensileStrength = positive(number(tensileStrength, "tensile_strength"), "tensile_strength", "tensile strength", "Pa");
            if (!shearStrength.is_none())
              c.bond.shearStrength = positive(number(shearStrength, "shear_strength"), "shear_strength", "shear strength", "Pa");
            if (!weibullModulus.is_none())
              c.bond.weibullModulus = positive(number(weibullModulus, "weibull_modulus"), "weibull_modulus", "Weibull modulus", "-");
            if (!(radius > 0.0 && radius <= 1.0))
              raise("radius: expected a bond radius in (0, 1] (a fraction of the smaller particle radius), got " + repr(radius));
            c.bond.radiusFactor = radius;
            return c;
          },
          py::kw_only(), py::arg("tensile_strength") = py::none(), py::arg("shear_strength") = py::none(),
          py::arg("weibull_modulus") = py::none(), py::arg("radius") = 1.0, R"doc(
Elastic bonds (rigid and static bodies; docs/fracture.md): beams that carry forces and moments and break by
their stress. Their Young's modulus and Poisson's ratio are the material's (which needs youngs_modulus);
tensile_strength, shear_strength [Pa] and weibull_modulus [-] left at None are the material's. radius: the
bond's radius as a fraction of the smaller particle radius, in (0, 1].
)doc")
      .def_property_readonly(
          "kind",
          [](const ConnectorParams& c) {
            return c.kind == ConnectorKind::Rod ? "rods" : c.kind == ConnectorKind::Spring ? "springs" : "bonds";
          },
          "'rods', 'springs' or 'bonds'.")
      .def(
          "__repr__",
          [](const ConnectorParams& c) {
            return std::string("volpar.Connectors.") +
                   (c.kind == ConnectorKind::Rod ? "rods" : c.kind == ConnectorKind::Spring ? "springs" : "bonds") + "(...)";
          },
          "The kind of connectors.");
}

}  // namespace volpar::python
