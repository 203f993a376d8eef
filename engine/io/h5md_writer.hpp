#pragma once
// Trajectory output in the H5MD 1.1 layout (docs/trajectory-format.md). Every time-dependent element is
// a chunked, compressed dataset extended one frame at a time; the file is flushed after every frame and then
// /parameters@frames_complete counts it, so a run killed (or a disk that fills) mid-way leaves a readable file
// whose first frames_complete frames are whole. HDF5 types stay in the .cpp.

#include <memory>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {

struct TrajectoryMeta {
  std::string sceneName;
  std::string sceneFile;
  std::string sceneText;
  std::vector<std::string> extraFiles;  ///< files the scene uses (meshes), stored under /parameters/files
  int outputEvery = 1;
  std::int64_t stepsRequested = 0;
  /// The run writes checkpoints: /checkpoint is made with the file, so that writing one later changes
  /// nothing outside it (a run killed while it writes a checkpoint keeps every frame before).
  bool checkpoints = false;
};

class H5mdWriter {
 public:
  /// Creates (truncates) `path` and writes the time-independent data of `world`.
  [[nodiscard]] static Result<std::unique_ptr<H5mdWriter>> create(const std::string& path, const World& world,
                                                                  const TrajectoryMeta& meta);
  ~H5mdWriter();
  H5mdWriter(const H5mdWriter&) = delete;
  H5mdWriter& operator=(const H5mdWriter&) = delete;

  /// Appends the world's current state as one frame and flushes the file.
  [[nodiscard]] Status writeFrame(const World& world);
  /// Writes the world's whole state (World::saveState) as the checkpoint of its step into the slot of
  /// /checkpoint (slot_0, slot_1) that does not hold the current one, flushes it, then makes it the file's
  /// (/checkpoint@step and @slot, rewritten in place): a run killed while it writes keeps every frame and
  /// the checkpoint before. Call it after writeFrame, so that the frames
  /// and breakage records up to the checkpoint are complete in the file. `endStep`: the step the run is to
  /// end at (a resumed run goes on to it).
  [[nodiscard]] Status writeCheckpoint(const World& world, std::int64_t endStep);
  /// The step of the last checkpoint written (-1: none).
  [[nodiscard]] std::int64_t checkpointStep() const { return checkpointStep_; }
  /// Appends the connectors that broke in the world's last step to /breakage (written with the next flush).
  [[nodiscard]] Status writeBreakEvents(const World& world);
  /// Writes the XDMF sidecar of `h5Path` (this file, or the name it was renamed to) for the frames so far
  /// (see xdmf_writer.hpp).
  [[nodiscard]] Status writeSidecar(const std::string& h5Path) const;
  /// Flushes and closes the file (also done by the destructor).
  [[nodiscard]] Status close();

  [[nodiscard]] std::size_t frames() const { return times_.size(); }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  struct Impl;
  H5mdWriter(std::unique_ptr<Impl> impl, std::string path, std::size_t particles);
  void writeContacts(const ContactSet& contacts);  // throws the file's internal failure type
  void writePatches(const PatchSet& patches);      // likewise

  std::unique_ptr<Impl> impl_;
  std::string path_;
  std::size_t particles_ = 0;
  std::uint64_t largestFrame_ = 0;  ///< the most bytes a frame has added to the file
  std::vector<double> times_;
  std::vector<std::int64_t> steps_;
  std::vector<std::int64_t> patchOffsets_;  // per frame: its first row in /patches
  std::vector<std::int64_t> patchCounts_;   // per frame: its patches
  std::int64_t checkpointStep_ = -1;
  int checkpointSlot_ = -1;  ///< the slot of /checkpoint that holds the checkpoint (-1: none)
};

}  // namespace volpar
