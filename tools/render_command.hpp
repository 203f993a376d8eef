#pragma once
// volpar render: pictures and animations of a trajectory, headless.

#include <string>

namespace volpar::cli {

struct RenderArgs {
  std::string input;         ///< the trajectory (.h5)
  std::string output;        ///< .png, .mp4 or .gif ("": the trajectory's name with .png, in the current folder)
  std::string view = "iso";  ///< iso | front | side | top
  std::string size = "960x720";
  std::string frames;        ///< FIRST:LAST[:STRIDE] ("": see frame)
  std::string frame;         ///< one frame index ("": the last complete frame for a PNG, every frame for MP4/GIF)
  double fps = 30.0;         ///< [frames/s] of an animation
  bool connectors = false;
  bool contacts = false;
  bool normals = false;
  bool json = false;
};

/// Renders the frames `args` selects; exit status 0, or 1 with "volpar: error: ..." on stderr.
int renderTrajectory(const RenderArgs& args);

}  // namespace volpar::cli
