#pragma once
// Reading volpar trajectories back (for `volpar inspect`, `volpar xdmf` and tests).

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "volpar/engine/core/state_archive.hpp"
#include "volpar/engine/core/status.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

struct TrajectorySummary {
  std::string creatorName;
  std::string creatorVersion;
  std::string sceneName;
  std::string sceneText;
  std::size_t frames = 0;       ///< complete frames
  std::size_t tornFrames = 0;   ///< frames written after the last commit (a killed run, a full disk): ignored
  std::size_t particles = 0;
  std::size_t bodies = 0;
  std::vector<std::int64_t> step;    ///< [T]
  std::vector<double> time;          ///< [T] [s]
  std::vector<double> kinetic;       ///< [T] [J]
  std::vector<double> potential;     ///< [T] [J]
  std::vector<double> total;         ///< [T] [J]
  std::vector<std::string> bodyNames;  ///< [B]
  /// Per frame: its first row and number of rows in /patches, [T] each (empty when the file has no /patches).
  std::vector<std::int64_t> patchOffset;
  std::vector<std::int64_t> patchCount;
  std::int64_t checkpointStep = -1;  ///< the step of the file's checkpoint (-1: none)
  double dt = 0.0;                   ///< the time step [s] (/parameters@dt; 0 where the file has none)
  std::size_t breakages = 0;         ///< connectors broken up to the last complete frame (/breakage)
  std::size_t bodiesAlive = 0;       ///< bodies existing in the last complete frame
  std::int64_t contacts = -1;        ///< touching contacts in the last complete frame (-1: not recorded)
  std::int64_t patches = -1;         ///< contact patches in the last complete frame (-1: not recorded)
  std::size_t connectors = 0;        ///< C, the length of /connectors/particle_a (0 where the file has none)
  /// Per frame: the first of its C rows in /connectors/lines, [T] (empty where the file has no lines).
  std::vector<std::int64_t> connectorLineOffset;
};

/// A trajectory's checkpoint (H5mdWriter::writeCheckpoint) and what it takes to build its world again.
struct Checkpoint {
  std::int64_t step = 0;           ///< the step the state is of
  std::int64_t endStep = 0;        ///< the step the run that wrote it was to end at
  std::string sceneFile;           ///< the scene file's path as the run was given it
  std::string sceneText;           ///< the scene as it was run
  std::int64_t seed = 0;           ///< the seed the run used
  int outputEvery = 1;             ///< steps between frames
  StateArchive state;              ///< World::saveState's arrays
};

/// Ragged rows of one frame of /contacts or /patches: points [m] and, for patches, unit normals.
struct FrameRows {
  std::vector<Vec3> point;   ///< [N] world frame
  std::vector<Vec3> normal;  ///< [N] world frame (patches only)
};

/// The connectors of a trajectory (/connectors) and the step each broke at (/breakage), for `volpar render`.
struct ConnectorTable {
  std::vector<std::int32_t> particleA;  ///< [C] particle index
  std::vector<std::int32_t> particleB;  ///< [C] particle index
  std::vector<std::int32_t> kind;       ///< [C] 0 rod, 1 spring, 2 bond
  /// [C] gone in frames with step >= breakStep (INT64_MAX: never broke; INT64_MIN: broken before the first
  /// frame, /connectors/broken_before)
  std::vector<std::int64_t> breakStep;
};

class H5mdReader {
 public:
  [[nodiscard]] static Result<std::unique_ptr<H5mdReader>> open(const std::string& path);
  ~H5mdReader();
  H5mdReader(const H5mdReader&) = delete;
  H5mdReader& operator=(const H5mdReader&) = delete;

  [[nodiscard]] Result<TrajectorySummary> summary() const;
  /// Particle positions of frame t [m], [P].
  [[nodiscard]] Result<std::vector<Vec3>> positions(std::size_t frame) const;
  /// Body centres of mass of frame t [m], [B].
  [[nodiscard]] Result<std::vector<Vec3>> bodyPositions(std::size_t frame) const;
  /// The file's checkpoint; an error where it has none or it cannot be read whole.
  [[nodiscard]] Result<Checkpoint> checkpoint() const;
  /// Body shape-frame orientations of frame t, [B].
  [[nodiscard]] Result<std::vector<Quat>> bodyOrientations(std::size_t frame) const;
  /// Particle radii [m], [P], each finite and above 0.
  [[nodiscard]] Result<std::vector<double>> radii() const;
  /// The scene's planes (/parameters/planes): unit normal (3) and offset [m] of n.x = offset, [n].
  [[nodiscard]] Result<std::vector<std::array<double, 4>>> planes() const;
  /// Body kinds ("rigid", "deformable", "static"), [B].
  [[nodiscard]] Result<std::vector<std::string>> bodyKinds() const;
  /// The body index of each particle in frame t, [P], each from 0 to `bodies` - 1.
  [[nodiscard]] Result<std::vector<std::int32_t>> particleBodies(std::size_t frame, std::size_t bodies) const;
  /// Whether the file has /connectors (files of volpar 0.1 before it was written do not).
  [[nodiscard]] bool hasConnectors() const;
  /// /connectors with their break steps from /breakage; an error where the file has no /connectors.
  [[nodiscard]] Result<ConnectorTable> connectors(std::size_t particles) const;
  /// The contact points of frame t (/contacts, ragged by offset and count).
  [[nodiscard]] Result<FrameRows> contactPoints(std::size_t frame) const;
  /// The patch points and normals of frame t (/patches, ragged by offset and count).
  [[nodiscard]] Result<FrameRows> patchNormals(std::size_t frame) const;

 private:
  struct Impl;
  explicit H5mdReader(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace volpar
