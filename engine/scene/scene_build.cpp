#include "volpar/engine/scene/scene_build.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <sstream>

#include "volpar/engine/builders/elastic_calibration.hpp"
#include "volpar/engine/builders/obj_reader.hpp"

namespace volpar {

namespace {

/// Where only a tensile strength is given, rods crush at this multiple of it.
constexpr double kCompressiveOverTensile = 10.0;

Error at(const SceneDesc& desc, const SourceMark& mark, const std::string& message) {
  return Error{desc.path, mark.line, mark.column, message};
}

std::string format(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::unique_ptr<SolidShape> primitive(const ShapeDesc& shape) {
  if (const auto* b = std::get_if<BoxDesc>(&shape)) return std::make_unique<BoxShape>(b->size);
  if (const auto* s = std::get_if<SphereDesc>(&shape)) return std::make_unique<SphereShape>(s->radius);
  if (const auto* c = std::get_if<CylinderDesc>(&shape)) return std::make_unique<CylinderShape>(c->radius, c->height);
  if (const auto* c = std::get_if<CapsuleDesc>(&shape)) return std::make_unique<CapsuleShape>(c->radius, c->length);
  return nullptr;
}

SourceShape sourceOf(const ShapeDesc& shape) {
  SourceShape s;
  if (const auto* b = std::get_if<BoxDesc>(&shape)) {
    s.kind = SourceShape::Kind::Box;
    s.size = b->size;
  } else if (const auto* sp = std::get_if<SphereDesc>(&shape)) {
    s.kind = SourceShape::Kind::Sphere;
    s.radius = sp->radius;
  } else if (const auto* c = std::get_if<CylinderDesc>(&shape)) {
    s.kind = SourceShape::Kind::Cylinder;
    s.radius = c->radius;
    s.length = c->height;
  } else if (const auto* cp = std::get_if<CapsuleDesc>(&shape)) {
    s.kind = SourceShape::Kind::Capsule;
    s.radius = cp->radius;
    s.length = cp->length;
  } else if (std::holds_alternative<MeshDesc>(shape)) {
    s.kind = SourceShape::Kind::Mesh;
  }
  return s;
}

std::string instanceName(const BodyDesc& b, int i, int j, int k) {
  const auto& c = b.repeat.count;
  if (c[0] * c[1] * c[2] == 1) return b.name;
  return b.name + "[" + std::to_string(i) + "," + std::to_string(j) + "," + std::to_string(k) + "]";
}

/// Particles within `reach` of one particle, in a region of `count` particles at `cellVolume` each.
double neighbours(double count, double reach, double cellVolume) {
  const double ball = 4.0 / 3.0 * std::numbers::pi * reach * reach * reach;
  return std::min(std::max(count - 1.0, 0.0), ball / cellVolume);
}

std::string gib(double bytes) {
  std::ostringstream s;
  s.precision(3);
  s << bytes / double(std::uint64_t{1} << 30) << " GiB";
  return s.str();
}

}  // namespace

std::uint64_t defaultMemoryLimit() {
  double total = static_cast<double>(sysconf(_SC_PHYS_PAGES)) * static_cast<double>(sysconf(_SC_PAGE_SIZE));
  // a container's share (cgroup v2) and the process's address-space limit, where smaller
  if (std::ifstream cg("/sys/fs/cgroup/memory.max"); cg) {
    double v = 0.0;
    if (cg >> v && v > 0.0) total = std::min(total, v);
  }
  struct rlimit as {};
  if (getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) total = std::min(total, static_cast<double>(as.rlim_cur));
  return total > 0.0 ? static_cast<std::uint64_t>(0.8 * total) : std::uint64_t{1} << 32;
}

Result<SceneEstimate> estimateScene(const SceneDesc& desc) {
  SceneEstimate total;
  double mostBytes = -1.0;
  for (const BodyDesc& body : desc.bodies) {
    double particles = 0.0, connectors = 0.0;
    if (const auto* list = std::get_if<ParticlesDesc>(&body.shape)) {
      particles = static_cast<double>(list->positions.size());
      if (list->explicitConnectors) {
        connectors = static_cast<double>(list->connectors.size());
      } else {
        const double largest = list->radii.empty() ? 0.0 : *std::max_element(list->radii.begin(), list->radii.end());
        const double reach = list->reach > 0.0 ? list->reach : 3.0 * largest;
        Eigen::AlignedBox3d box;
        for (const Vec3& p : list->positions) box.extend(p);
        const Vec3 extent = box.sizes().array() + reach;
        connectors = 0.5 * particles * neighbours(particles, reach, extent.prod() / particles);
      }
    } else {
      double volume = 0.0;
      std::string what;
      if (const auto* mesh = std::get_if<MeshDesc>(&body.shape)) {
        auto m = readObj(mesh->path, mesh->scale);
        if (!m) return at(desc, body.mark, "body '" + body.name + "': " + m.error().toString());
        volume = std::abs(m->volume());
        what = "mesh " + mesh->file;
      } else {
        const auto shape = primitive(body.shape);
        volume = shape->volume();
        what = shape->describe();
      }
      const double s = body.fill.spacing > 0.0 ? body.fill.spacing : 2.0 * body.fill.radius;
      const double cell = latticeCellVolume(body.fill.lattice, s);
      particles = volume / cell;
      connectors = 0.5 * particles * neighbours(particles, body.fill.reach * s, cell);
      if (!(particles < static_cast<double>(kMaxSceneParticles)))
        return at(desc, body.mark,
                  "body '" + body.name + "': filling the " + what + " with particles of radius " + format(body.fill.radius) +
                      " m would create about " + format(particles) + " particles; expected at most " +
                      std::to_string(kMaxSceneParticles) + " (use a larger radius)");
    }
    const auto& c = body.repeat.count;
    const double copies = static_cast<double>(c[0]) * c[1] * c[2];
    total.particles += copies * particles;
    total.connectors += copies * connectors;
    total.bodies += copies;
    const double bytes = copies * (particles * kBytesPerParticle + connectors * kBytesPerConnector);
    if (bytes > mostBytes) {
      mostBytes = bytes;
      total.largest = body.mark;
    }
  }
  total.bytes = total.particles * kBytesPerParticle + total.connectors * kBytesPerConnector + total.bodies * kBytesPerBody;
  return total;
}

Result<ParticleCloud> buildCloud(const SceneDesc& desc, const BodyDesc& body, SourceShape* source) {
  const bool estimated = desc.normalsOf(body) == SurfaceNormals::Estimated;
  if (source) {
    *source = sourceOf(body.shape);
    source->estimatedNormals = estimated;
  }
  auto wrap = [&](const Error& e) {
    return at(desc, body.mark, "body '" + body.name + "': " + e.toString());
  };
  if (const auto* list = std::get_if<ParticlesDesc>(&body.shape)) {
    ParticleListSettings s;
    s.positions = list->positions;
    s.radii = list->radii;
    s.connectors = list->connectors;
    s.explicitConnectors = list->explicitConnectors;
    s.reach = list->reach;
    auto cloud = buildParticleList(s);  // estimated normals: a particle list has no solid
    if (!cloud) return wrap(cloud.error());
    return cloud;
  }
  std::unique_ptr<SolidShape> shape;
  if (const auto* mesh = std::get_if<MeshDesc>(&body.shape)) {
    auto m = readObj(mesh->path, mesh->scale);
    if (!m) return wrap(m.error());
    if (auto ok = m->makeSolid(); !ok) return wrap(ok.error());
    if (source) source->facePlanes = m->convexFacePlanes();
    shape = std::make_unique<MeshShape>(std::make_shared<const TriangleMesh>(std::move(m.value())));
  } else {
    shape = primitive(body.shape);
  }
  // refuse absurd particle counts before filling
  const double s = body.fill.spacing > 0.0 ? body.fill.spacing : 2.0 * body.fill.radius;
  const double estimate = shape->volume() / latticeCellVolume(body.fill.lattice, s);
  if (!(estimate < static_cast<double>(kMaxSceneParticles)))
    return at(desc, body.mark,
              "body '" + body.name + "': filling the " + shape->describe() + " with particles of radius " +
                  format(body.fill.radius) + " m would create about " + format(estimate) +
                  " particles; expected at most " + std::to_string(kMaxSceneParticles) + " (use a larger radius)");
  auto cloud = fillShape(*shape, body.fill);
  if (!cloud) return wrap(cloud.error());
  // normals: estimated replaces the solid's exact normals by those of the particles alone
  if (estimated) useEstimatedNormals(*cloud);
  return cloud;
}

std::optional<std::string> latticeFitNote(const std::string& body, const ParticleCloud& cloud) {
  if (!(cloud.solidSize.minCoeff() > 0.0) || cloud.size() == 0) return std::nullopt;
  Eigen::AlignedBox3d reach;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    reach.extend(cloud.positions[i] - Vec3::Constant(cloud.radii[i]));
    reach.extend(cloud.positions[i] + Vec3::Constant(cloud.radii[i]));
  }
  const Vec3 solid = cloud.solidSize, particles = reach.sizes();
  if (!((solid - particles).maxCoeff() > 1e-6 * solid.maxCoeff())) return std::nullopt;
  auto size = [](const Vec3& v) { return format(v.x()) + " x " + format(v.y()) + " x " + format(v.z()) + " m"; };
  return "body '" + body + "': its particles span " + size(particles) + " of its solid's " + size(solid) +
         " (lattice sites " + format(cloud.spacing) +
         " m apart are filled only where a whole particle fits inside; a smaller radius, or one that divides the "
         "size, fills it more closely); it collides at the particles' size and has the whole solid's mass and inertia";
}

/// A body's or a glue's bonds take what they do not set from their material; they need its Young's modulus.
std::optional<Error> bondsFromMaterial(const SceneDesc& desc, const std::string& material, const SourceMark& mark,
                                       const std::string& who, ConnectorParams& c) {
  const Material& mat = desc.materials.at(material);
  takeBondDefaults(mat, c);
  if (!(mat.youngsModulus > 0.0))
    return at(desc, mark,
              who + ": bonds need their material's Young's modulus; expected 'youngs_modulus' [Pa] in material '" + material + "'");
  return std::nullopt;
}

/// Glues the bodies each glue names (World::glue).
std::optional<Error> glueBodies(const SceneDesc& desc, BuiltScene& built) {
  World& world = built.world;
  // each name: a body entry's (all its copies) or one copy's
  std::map<std::string, std::vector<BodyId>> byName;
  for (std::size_t i = 0; i < built.bodySource.size(); ++i) {
    const BodyId id(i);
    byName[desc.bodies[built.bodySource[i]].name].push_back(id);
    const std::string& own = world.bodies().info[i].name;
    if (own != desc.bodies[built.bodySource[i]].name) byName[own].push_back(id);
  }
  std::vector<std::uint8_t> used(world.bodies().size(), 0);
  for (const GlueDesc& g : desc.glue) {
    std::vector<BodyId> parts;
    std::map<std::size_t, std::uint32_t> slot;  // body index -> index in parts
    auto take = [&](const std::string& name, const SourceMark& mark) -> std::optional<Error> {
      const auto it = byName.find(name);
      if (it == byName.end()) return at(desc, mark, "glue '" + g.name + "': no body named '" + name + "'");
      for (const BodyId id : it->second) {
        if (slot.contains(id.index())) continue;
        if (used[id.index()])
          return at(desc, mark, "glue '" + g.name + "': body '" + world.bodies().info[id.index()].name + "' is already glued by another glue");
        slot[id.index()] = static_cast<std::uint32_t>(parts.size());
        parts.push_back(id);
      }
      return std::nullopt;
    };
    GlueDef def;
    def.name = g.name;
    def.reach = g.reach;
    def.bonds.kind = ConnectorKind::Bond;
    def.bonds.bond.radiusFactor = g.radius;
    if (auto bad = bondsFromMaterial(desc, g.material, g.mark, "glue '" + g.name + "'", def.bonds)) return bad;
    for (std::size_t k = 0; k < g.bodies.size(); ++k)
      if (auto bad = take(g.bodies[k], g.bodyMarks[k])) return bad;
    for (std::size_t k = 0; k < g.pairs.size(); ++k) {
      if (auto bad = take(g.pairs[k][0], g.pairMarks[k])) return bad;
      if (auto bad = take(g.pairs[k][1], g.pairMarks[k])) return bad;
      for (const BodyId a : byName.at(g.pairs[k][0]))
        for (const BodyId b : byName.at(g.pairs[k][1])) def.pairs.push_back({slot.at(a.index()), slot.at(b.index())});
    }
    for (const BodyId id : parts) {
      if (world.bodies().info[id.index()].kind != BodyKind::Rigid)
        return at(desc, g.mark, "glue '" + g.name + "': body '" + world.bodies().info[id.index()].name +
                                    "' is not rigid; only rigid bodies are glued");
      used[id.index()] = 1;
    }
    auto glued = world.glue(parts, def);
    if (!glued) return at(desc, g.mark, glued.error().message);
    built.bodySource.push_back(built.bodySource[parts.front().index()]);
    used.push_back(1);
  }
  return std::nullopt;
}

Result<BuiltScene> buildScene(const SceneDesc& desc, const BuildOptions& options) {
  // what the scene will need, before anything is allocated for it
  const auto estimate = estimateScene(desc);
  if (!estimate) return estimate.error();
  const std::uint64_t limit = options.memoryLimit > 0 ? options.memoryLimit : defaultMemoryLimit();
  if (!(estimate->bytes <= static_cast<double>(limit))) {
    std::ostringstream m;
    m.precision(3);
    m << "the scene (this body the most) needs about " << gib(estimate->bytes) << " of memory (" << estimate->particles << " particles, "
      << estimate->connectors << " connectors, " << estimate->bodies << " bodies); the limit is " << gib(double(limit))
      << (options.memoryLimit > 0 ? " (--memory-limit)" : " (80 % of this machine's memory)")
      << "; expected a smaller scene (larger particles, a smaller reach), or a higher --memory-limit";
    return at(desc, estimate->largest, m.str());
  }
  WorldSettings settings;
  settings.dt = desc.dt;
  settings.gravity = desc.gravity;
  settings.solverIterations = desc.solverIterations;
  settings.substeps = desc.substeps;
  settings.rawNormals = desc.rawNormals;
  settings.seed = desc.seed;
  BuiltScene built{World(settings), {}, {}, {}};
  World& world = built.world;

  std::map<std::string, MaterialId> materialIds;
  for (const auto& [name, mat] : desc.materials) materialIds[name] = world.addMaterial(mat);
  for (const PlaneDesc& p : desc.planes) world.addPlane(Plane{p.normal, p.offset, materialIds.at(p.material)});

  std::size_t totalParticles = 0;
  for (std::size_t d = 0; d < desc.bodies.size(); ++d) {
    const BodyDesc& b = desc.bodies[d];
    SourceShape source;
    auto cloud = buildCloud(desc, b, &source);
    if (!cloud) return cloud.error();
    if (!b.pins.empty()) {
      cloud->pinned.assign(cloud->size(), 0);
      for (std::size_t k = 0; k < b.pins.size(); ++k) {
        std::size_t held = 0;
        for (std::size_t i = 0; i < cloud->size(); ++i)
          if (b.pins[k].contains(cloud->positions[i])) {
            cloud->pinned[i] = 1;
            ++held;
          }
        if (held == 0) return at(desc, b.pinMarks[k], "this pin box holds no particle of the body (in its shape frame)");
      }
    }
    if (b.connectors.kind == ConnectorKind::Spring && !(b.connectors.stiffness > 0.0)) {
      // springs given by the material's modulus: calibrated for the lattice
      const Material& mat = desc.materials.at(b.material);
      if (std::holds_alternative<ParticlesDesc>(b.shape))
        return at(desc, b.mark, "body '" + b.name + "': springs of an explicit particle list need a 'stiffness' [N/m] (there is no lattice to calibrate them for)");
      if (!(mat.youngsModulus > 0.0))
        return at(desc, b.mark, "body '" + b.name + "': springs need a 'stiffness' [N/m], or their material's 'youngs_modulus' [Pa] (material '" + b.material + "')");
      const double spacing = cloud->spacing;
      const SpringCalibration springs = calibrateSprings(b.fill.lattice, spacing, b.fill.reach, mat.youngsModulus, mat.poissonRatio);
      if (!(springs.nearest > 0.0) || !std::isfinite(springs.nearest))
        return at(desc, b.mark, "body '" + b.name + "': its lattice and reach cannot be calibrated for a Young's modulus (give the springs a 'stiffness')");
      cloud->connectorStiffness = calibratedStiffness(*cloud, springs, b.fill.lattice, spacing, b.fill.reach);
      if (std::abs(springs.poissonRatio - mat.poissonRatio) > 1e-3)
        built.notes.push_back("body '" + b.name + "': its lattice of springs has Poisson's ratio " + format(springs.poissonRatio) +
                              ", the nearest it reaches to the material's " + format(mat.poissonRatio));
    }
    if (const auto* mesh = std::get_if<MeshDesc>(&b.shape)) built.meshFiles.push_back(mesh->path);
    if (auto note = latticeFitNote(b.name, *cloud)) built.notes.push_back(std::move(*note));
    const auto& c = b.repeat.count;
    totalParticles += cloud->size() * static_cast<std::size_t>(c[0] * c[1] * c[2]);
    if (totalParticles > kMaxSceneParticles)
      return at(desc, b.mark, "the scene would create more than " + std::to_string(kMaxSceneParticles) + " particles");
    for (int k = 0; k < c[2]; ++k)
      for (int j = 0; j < c[1]; ++j)
        for (int i = 0; i < c[0]; ++i) {
          BodyDef def;
          def.name = instanceName(b, i, j, k);
          def.kind = b.kind;
          def.material = materialIds.at(b.material);
          def.position = b.position + Vec3(i * b.repeat.spacing.x(), j * b.repeat.spacing.y(), k * b.repeat.spacing.z());
          def.orientation = b.orientation;
          const int copy = i + c[0] * (j + c[1] * k);
          for (const auto& [axis, angle] : b.repeat.rotationStep)
            def.orientation = Quat(Eigen::AngleAxisd(angle * copy, axis)) * def.orientation;
          def.orientation.normalize();
          def.linearVelocity = b.velocity;
          def.angularVelocity = b.angularVelocity;
          def.connectors = b.connectors;
          if (b.kind != BodyKind::Static) {
            // the material's thresholds where the body sets none; rods that break in tension crush at ten
            // times that unless a compressive strength is given
            const Material& mat = desc.materials.at(b.material);
            const bool rods = def.connectors.kind == ConnectorKind::Rod;
            if (!std::isfinite(def.connectors.breakLimit)) def.connectors.breakLimit = rods ? mat.rodStrength : mat.strainLimit;
            if (rods && !std::isfinite(def.connectors.compressionLimit))
              def.connectors.compressionLimit =
                  mat.rodCompressiveStrength > 0.0 ? mat.rodCompressiveStrength : kCompressiveOverTensile * def.connectors.breakLimit;
          }
          if (def.connectors.kind == ConnectorKind::Bond) {
            if (auto bad = bondsFromMaterial(desc, b.material, b.mark, "body '" + b.name + "'", def.connectors)) return *bad;
          }
          def.particleMass = b.particleMass;
          def.totalMass = b.mass;
          def.source = source;
          def.massModel = b.massModel;
          auto id = world.addBody(def, *cloud);
          if (!id) return at(desc, b.mark, id.error().message);
          built.bodySource.push_back(d);
        }
  }

  if (auto bad = glueBodies(desc, built)) return *bad;

  world.refreshContacts();
  if (desc.allowInitialOverlap) return built;

  // bodies overlapping each other or a plane at start: the first offending group of contacts
  // (in the world's deterministic order) with its deepest overlap
  const BodyStore& bodies = world.bodies();
  const ContactSet& contacts = world.contacts();
  for (const ContactGroup& g : contacts.groups) {
    if (g.a == g.b) continue;  // a deformable body touching itself
    double deepest = 0.0;
    for (std::uint32_t k = g.first; k < g.first + g.count; ++k) {
      const ParticleContact& c = contacts.contacts[k];
      const double scale = world.particles().radius[c.a.index()] + (c.b.valid() ? world.particles().radius[c.b.index()] : 0.0);
      if (c.depth > 1e-6 * scale) deepest = std::max(deepest, c.depth);
    }
    if (deepest == 0.0) continue;
    if (g.plane.valid()) {
      const std::size_t k = g.plane.index();
      return at(desc, desc.bodies[built.bodySource[g.a.index()]].mark,
                "body '" + bodies.info[g.a.index()].name + "' overlaps plane " + std::to_string(k) + " (line " +
                    std::to_string(desc.planes[k].mark.line) + ") at start by " + format(deepest) +
                    " m; expected it above the plane (or set allow_initial_overlap: true)");
    }
    const BodyDesc& later = desc.bodies[std::max(built.bodySource[g.a.index()], built.bodySource[g.b.index()])];
    return at(desc, later.mark,
              "bodies '" + bodies.info[g.a.index()].name + "' and '" + bodies.info[g.b.index()].name +
                  "' overlap at start by " + format(deepest) +
                  " m; expected bodies apart (move them, or set allow_initial_overlap: true if this is intended)");
  }
  return built;
}

}  // namespace volpar
