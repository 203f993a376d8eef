#pragma once
// A scene as plain data, produced by the loader (scene_loader.hpp) from YAML and turned into a World
// by buildScene (scene_build.hpp). Every field has a documented default; the loader rejects unknown keys.

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/connector_store.hpp"
#include "volpar/engine/core/material.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// Where something was written in the scene file (1-based; 0 = unknown).
struct SourceMark {
  int line = 0;
  int column = 0;
};

struct BoxDesc {
  Vec3 size = Vec3::Zero();  ///< full side lengths [m]
};
struct SphereDesc {
  double radius = 0.0;  ///< [m]
};
struct CylinderDesc {
  double radius = 0.0;  ///< [m]
  double height = 0.0;  ///< total height along shape z [m]
};
struct CapsuleDesc {
  double radius = 0.0;  ///< [m]
  double length = 0.0;  ///< segment length along shape z [m]; total length is length + 2 radius
};
struct MeshDesc {
  std::string file;      ///< as written in the scene
  std::string path;      ///< resolved against the scene's folder
  double scale = 1.0;    ///< [-]
};
struct ParticlesDesc {
  std::vector<Vec3> positions;  ///< shape frame [m]
  std::vector<double> radii;    ///< one for all, or one per particle [m]
  std::vector<std::array<std::uint32_t, 2>> connectors;
  bool explicitConnectors = false;
  double reach = 0.0;  ///< [m]; 0 = 1.5 x the largest diameter
};
using ShapeDesc = std::variant<BoxDesc, SphereDesc, CylinderDesc, CapsuleDesc, MeshDesc, ParticlesDesc>;

/// Where a body's surface normals come from (scene key `normals`). Not the narrow phase's NormalSource
/// (collision/separating_plane.hpp), which says where one patch's plane normal came from.
enum class SurfaceNormals : std::uint8_t {
  Shape,      ///< the exact normals of the solid the body was filled from (fillShape)
  Estimated,  ///< estimated from the particles and connectors alone (useEstimatedNormals), as a particle list gets them
};

struct RepeatDesc {
  std::array<int, 3> count{1, 1, 1};
  Vec3 spacing = Vec3::Zero();  ///< [m], world axes
  /// Copy n (x fastest, then y, then z) is also turned by each of these rotations with its angle
  /// multiplied by n, in order (about world axes), after the body's own orientation.
  std::vector<std::pair<Vec3, double>> rotationStep;  ///< (unit axis, angle [rad])
};

struct BodyDesc {
  std::string name;
  BodyKind kind = BodyKind::Rigid;
  ShapeDesc shape;
  FillSettings fill;                        ///< unused for explicit particle lists
  ConnectorParams connectors;
  std::string material = "default";
  std::optional<double> mass;               ///< total [kg]
  std::optional<double> particleMass;       ///< per particle [kg]
  Vec3 position = Vec3::Zero();             ///< shape-frame origin [m]
  Quat orientation = Quat::Identity();
  Vec3 velocity = Vec3::Zero();             ///< [m/s]
  Vec3 angularVelocity = Vec3::Zero();      ///< [rad/s]
  RepeatDesc repeat;
  /// As the body's `normals` key gives it; unset takes SceneDesc::normals (see SceneDesc::normalsOf). An
  /// explicit particle list has no solid, so its normals are always estimated (the loader rejects `shape`).
  std::optional<SurfaceNormals> normals;
  /// Scene key `mass_properties`: `solid` (the default: a rigid body filled from a solid takes its exact
  /// inertia) or `particles` (the sum over its particles, each standing for its lattice cell).
  MassModel massModel = MassModel::Solid;
  /// Deformable bodies: particles inside any of these boxes (shape frame, [m]) are held fixed in space.
  std::vector<Eigen::AlignedBox3d> pins;    ///< particles inside (shape frame) are held in place
  std::vector<SourceMark> pinMarks;         ///< where each pin box is in the scene file
  SourceMark mark;                          ///< the body's entry in the scene file
};

/// Bodies glued into one by bonds between their touching particles (World::glue).
struct GlueDesc {
  std::string name;                    ///< the glued body's name
  std::vector<std::string> bodies;     ///< body names (an entry's name takes all its repeat copies)
  std::vector<SourceMark> bodyMarks;
  std::vector<std::array<std::string, 2>> pairs;  ///< if given, only these pairs are glued
  std::vector<SourceMark> pairMarks;
  std::string material = "default";    ///< the glue's material (its bonds' modulus and strengths)
  double reach = 1.5;                  ///< particles closer than reach x (r_a + r_b) are bonded [-]
  double radius = 1.0;                 ///< bond radius as a fraction of the smaller particle radius [-]
  SourceMark mark;
};

struct PlaneDesc {
  Vec3 normal = Vec3::UnitZ();
  double offset = 0.0;  ///< [m]
  std::string material = "default";
  SourceMark mark;
};

struct SceneDesc {
  std::string name;
  std::string path;   ///< the scene file
  std::string text;   ///< its full text (stored in the trajectory's /parameters)
  double dt = 0.0;    ///< [s]
  std::optional<std::int64_t> steps;
  std::optional<double> duration;  ///< [s]
  Vec3 gravity = Vec3(0.0, 0.0, -9.81);
  int solverIterations = 10;
  int substeps = 4;
  int outputEvery = 1;
  bool allowInitialOverlap = false;
  bool rawNormals = false;  ///< solver uses centre-line normals instead of separating planes
  SurfaceNormals normals = SurfaceNormals::Shape;  ///< for bodies that set no `normals` of their own
  std::map<std::string, Material> materials;  ///< always holds "default"
  std::vector<PlaneDesc> planes;
  std::vector<BodyDesc> bodies;
  std::vector<GlueDesc> glue;
  std::uint64_t seed = 0;  ///< for what is drawn at random (bond strengths with a Weibull modulus)

  /// Number of steps the scene asks for: steps, or round(duration / dt).
  [[nodiscard]] std::int64_t stepCount() const;
  /// The normals `body` gets: its own `normals`, else this scene's; always Estimated for a particle list.
  [[nodiscard]] SurfaceNormals normalsOf(const BodyDesc& body) const;
};

}  // namespace volpar
