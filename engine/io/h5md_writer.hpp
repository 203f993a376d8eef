#pragma once
// Trajectory output in the H5MD 1.1 layout (docs/trajectory-format.md). Every time-dependent element is
// a chunked, compressed dataset extended one frame at a time; frames are committed (the file flushed, then
// /parameters@frames_complete counts them) after every frame or every few seconds, so a run killed (or a disk
// that fills) mid-way leaves a readable file whose first frames_complete frames are whole. HDF5 types stay in the .cpp.

#include <array>
#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "volpar/engine/core/status.hpp"
#include "volpar/engine/io/file_processes.hpp"
#include "volpar/engine/io/xdmf_writer.hpp"
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
  /// Creates (truncates) `path` and writes the time-independent data of `world`. With `processes` (more than
  /// one), every one of them holds the same world and makes every call of this class alike: they create the file
  /// together with parallel HDF5 and each writes its share of every dataset's rows (process 0 the blocks too
  /// small to divide, and the XDMF sidecar alone). `processes` must outlive the writer.
  [[nodiscard]] static Result<std::unique_ptr<H5mdWriter>> create(const std::string& path, const World& world,
                                                                  const TrajectoryMeta& meta,
                                                                  const FileProcesses* processes = nullptr);
  ~H5mdWriter();
  H5mdWriter(const H5mdWriter&) = delete;
  H5mdWriter& operator=(const H5mdWriter&) = delete;

  /// Appends the world's current state as one frame; commits the frames written (commit()) when the last
  /// commit is `commitInterval` seconds or more ago.
  [[nodiscard]] Status writeFrame(const World& world);
  /// Flushes the frames written so far to the disk and then counts them complete
  /// (/parameters@frames_complete, flushed again): a run killed at any point keeps every frame of the last
  /// commit. Also done by writeCheckpoint and close.
  [[nodiscard]] Status commit();
  /// Seconds between commits (0, the default: after every frame). A longer interval writes faster (a flush
  /// costs a few milliseconds) and a run killed with SIGKILL loses at most the frames of that interval.
  void setCommitInterval(double seconds) { commitSeconds_ = seconds; }
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
  /// After a failure, for a process about to end: closes the file (committing every frame written) where
  /// this process writes alone or where every process met the failure together (a lack of room, agreed
  /// before a frame or a checkpoint); otherwise leaves it unclosed, since closing is a collective call
  /// that the other processes may never make: the frames committed before are on disk.
  void closeAfterFailure();
  /// Bytes this process has written into the file's datasets.
  [[nodiscard]] std::uint64_t bytesWritten() const;

  /// Frames written; committedFrames(): those counted complete in the file.
  [[nodiscard]] std::size_t frames() const { return times_.size(); }
  [[nodiscard]] std::size_t committedFrames() const { return committed_; }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  struct Impl;
  H5mdWriter(std::unique_ptr<Impl> impl, std::string path, std::size_t particles);
  void writeContacts(const ContactSet& contacts);  // throws the file's internal failure type
  void writePatches(const PatchSet& patches);      // likewise

  /// Whether any of the processes writing together says yes (alone: `mine`).
  [[nodiscard]] bool agree(bool mine) const;
  /// The file's size in bytes; false where it cannot be told.
  [[nodiscard]] bool fileSize(std::uint64_t& size) const;

  std::unique_ptr<Impl> impl_;
  const FileProcesses* processes_ = nullptr;  ///< with more than one process writing together
  std::uint64_t bytesWritten_ = 0;
  bool failedTogether_ = false;  ///< the last failure was every process's (agreed)
  std::string path_;
  std::size_t particles_ = 0;
  std::uint64_t largestCommit_ = 0;  ///< the most bytes a commit has added to the file
  std::uint64_t sizeAtCommit_ = 0;   ///< the file's size at the last commit
  double commitSeconds_ = 0.0;
  std::chrono::steady_clock::time_point lastCommit_ = std::chrono::steady_clock::now();
  std::size_t committed_ = 0;        ///< frames counted complete in the file
  std::size_t connectors_ = 0;        ///< for the sidecar: connectors, and per frame the first row of its lines
  std::vector<std::int64_t> linesOffsets_;
  std::vector<std::array<double, 4>> planes_;
  XdmfBounds bounds_;                 ///< the particles' bounds over the frames written
  std::vector<double> times_;
  std::vector<std::int64_t> steps_;
  std::vector<std::int64_t> patchOffsets_;  // per frame: its first row in /patches
  std::vector<std::int64_t> patchCounts_;   // per frame: its patches
  std::int64_t checkpointStep_ = -1;
  int checkpointSlot_ = -1;  ///< the slot of /checkpoint that holds the checkpoint (-1: none)
};

}  // namespace volpar
