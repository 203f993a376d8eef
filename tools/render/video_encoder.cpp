#include "tools/render/video_encoder.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

extern char** environ;

namespace volpar::render {

std::string findProgram(const std::string& program) {
  const char* path = std::getenv("PATH");
  const std::string dirs = path ? path : "/usr/bin:/bin";
  std::size_t start = 0;
  while (start <= dirs.size()) {
    const std::size_t end = std::min(dirs.find(':', start), dirs.size());
    const std::string dir = end > start ? dirs.substr(start, end - start) : ".";
    const std::string full = dir + "/" + program;
    struct stat st {};
    if (::stat(full.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(full.c_str(), X_OK) == 0) return full;
    start = end + 1;
  }
  return {};
}

Result<std::unique_ptr<VideoEncoder>> VideoEncoder::start(VideoFormat format, const std::string& path, int width, int height,
                                                          double fps) {
  const std::string ffmpeg = findProgram("ffmpeg");
  if (ffmpeg.empty())
    return Error{path, 0, 0,
                 "writing MP4 or GIF needs the ffmpeg program, which is not on PATH; install the Debian package ffmpeg "
                 "(apt-get install ffmpeg)"};
  char rate[64];
  std::snprintf(rate, sizeof rate, "%.9g", fps);
  const std::string size = std::to_string(width) + "x" + std::to_string(height);
  std::vector<std::string> args = {ffmpeg, "-hide_banner", "-loglevel", "error", "-nostats", "-f", "rawvideo", "-pix_fmt", "rgb24",
                                   "-s", size, "-framerate", rate, "-i", "pipe:0"};
  if (format == VideoFormat::Mp4) {
    // H.264 in yuv420p, which every player takes; the index at the front so that it plays while loading
    args.insert(args.end(), {"-c:v", "libx264", "-pix_fmt", "yuv420p", "-crf", "18", "-movflags", "+faststart", "-f", "mp4"});
  } else {
    // one palette made from all the frames, then each frame mapped onto it
    args.insert(args.end(), {"-vf", "split[a][b];[a]palettegen=stats_mode=full[p];[b][p]paletteuse=dither=none", "-loop", "0",
                             "-f", "gif"});
  }
  args.insert(args.end(), {"-y", path});
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) return Error{path, 0, 0, std::string("cannot make a pipe to ffmpeg: ") + std::strerror(errno)};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[0], STDIN_FILENO);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = -1;
  const int rc = ::posix_spawn(&pid, ffmpeg.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[0]);
  if (rc != 0) {
    ::close(fds[1]);
    return Error{path, 0, 0, "cannot start " + ffmpeg + ": " + std::strerror(rc) + " (Debian package ffmpeg)"};
  }
  // a pipe whose reader died must give an error, not end volpar
  std::signal(SIGPIPE, SIG_IGN);
  return std::unique_ptr<VideoEncoder>(new VideoEncoder(pid, fds[1], path));
}

VideoEncoder::~VideoEncoder() {
  if (fd_ >= 0) ::close(fd_);
  if (pid_ > 0) {
    ::kill(pid_, SIGKILL);
    int status = 0;
    ::waitpid(pid_, &status, 0);
  }
}

Status VideoEncoder::frame(const Canvas& canvas) {
  const auto& bytes = canvas.pixels();
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string why = std::strerror(errno);
      ::close(fd_);
      fd_ = -1;
      if (auto st = exitStatus(); !st) return st;
      return Error{path_, 0, 0, "cannot send a frame to ffmpeg: " + why};
    }
    done += static_cast<std::size_t>(n);
  }
  return okStatus();
}

Status VideoEncoder::finish() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  return exitStatus();
}

Status VideoEncoder::exitStatus() {
  int status = 0;
  pid_t r = -1;
  do r = ::waitpid(pid_, &status, 0);
  while (r < 0 && errno == EINTR);
  pid_ = -1;
  if (r < 0) return Error{path_, 0, 0, std::string("cannot wait for ffmpeg: ") + std::strerror(errno)};
  if (WIFSIGNALED(status)) return Error{path_, 0, 0, "ffmpeg was killed by signal " + std::to_string(WTERMSIG(status))};
  if (WEXITSTATUS(status) != 0)
    return Error{path_, 0, 0, "ffmpeg exited with status " + std::to_string(WEXITSTATUS(status)) + " (its message is above)"};
  return okStatus();
}

}  // namespace volpar::render
