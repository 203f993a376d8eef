#pragma once
// Trajectory output in the H5MD 1.1 layout (docs/trajectory-format.md). Every time-dependent element is
// a chunked, compressed dataset extended one frame at a time; the file is flushed after every frame, so a
// run killed mid-way leaves a readable file holding every frame written so far. HDF5 types stay in the .cpp.

#include <memory>
#include <string>
#include <vector>

#include "engine/core/status.hpp"
#include "engine/world.hpp"

namespace volpar {

struct TrajectoryMeta {
  std::string sceneName;
  std::string sceneFile;
  std::string sceneText;
  std::vector<std::string> extraFiles;  ///< files the scene uses (meshes), stored under /parameters/files
  int outputEvery = 1;
  std::int64_t stepsRequested = 0;
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
  /// Appends the connectors that broke in the world's last step to /breakage (written with the next flush).
  [[nodiscard]] Status writeBreakEvents(const World& world);
  /// Writes the XDMF sidecar for the frames so far (see xdmf_writer.hpp).
  [[nodiscard]] Status writeSidecar() const;
  /// Flushes and closes the file (also done by the destructor).
  [[nodiscard]] Status close();

  [[nodiscard]] std::size_t frames() const { return times_.size(); }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  struct Impl;
  explicit H5mdWriter(std::unique_ptr<Impl> impl, std::string path);
  void writeContacts(const ContactSet& contacts);  // throws the file's internal failure type
  void writePatches(const PatchSet& patches);      // likewise

  std::unique_ptr<Impl> impl_;
  std::string path_;
  std::vector<double> times_;
  std::vector<std::int64_t> steps_;
  std::vector<std::int64_t> patchOffsets_;  // per frame: its first row in /patches
  std::vector<std::int64_t> patchCounts_;   // per frame: its patches
};

}  // namespace volpar
