#pragma once
// Animations of volpar render: raw RGB frames piped into the ffmpeg program, which writes MP4 (H.264) or GIF.

#include <sys/types.h>

#include <memory>
#include <string>
#include <utility>

#include "volpar/engine/core/status.hpp"
#include "tools/render/canvas.hpp"

namespace volpar::render {

enum class VideoFormat { Mp4, Gif };

/// The full path of `program` on PATH, or "" when it is not there.
std::string findProgram(const std::string& program);

/// One ffmpeg process writing one file. Frames go to its standard input as raw rgb24; finish() waits for it.
/// Destroyed before finish(), it kills the process (the file it was writing is then the caller's to remove).
class VideoEncoder {
 public:
  /// Starts `ffmpeg` writing `path` (any name: the format is given, not guessed from it), `width` x `height`
  /// frames at `fps` frames per second. An error naming the Debian package where ffmpeg is not installed.
  static Result<std::unique_ptr<VideoEncoder>> start(VideoFormat format, const std::string& path, int width, int height,
                                                     double fps);
  ~VideoEncoder();
  VideoEncoder(const VideoEncoder&) = delete;
  VideoEncoder& operator=(const VideoEncoder&) = delete;

  /// Sends one frame (the canvas must have the size given to start()).
  Status frame(const Canvas& canvas);
  /// Closes ffmpeg's input and waits for it; an error unless it exits with status 0.
  Status finish();

 private:
  VideoEncoder(pid_t pid, int fd, std::string path) : pid_(pid), fd_(fd), path_(std::move(path)) {}
  Status exitStatus();

  pid_t pid_ = -1;
  int fd_ = -1;
  std::string path_;
};

}  // namespace volpar::render
