// volpar render: frames of a trajectory drawn as shaded spheres, to PNG files or (through ffmpeg) MP4 or GIF.

#include "tools/render_command.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "volpar/engine/io/h5md_reader.hpp"
#include "tools/commands.hpp"
#include "tools/render/camera.hpp"
#include "tools/render/canvas.hpp"
#include "tools/render/font.hpp"
#include "tools/render/palette.hpp"
#include "tools/render/png_writer.hpp"
#include "tools/render/video_encoder.hpp"

namespace volpar::cli {

namespace {

namespace fs = std::filesystem;
using render::Bounds;
using render::Camera;
using render::Canvas;
using render::Rgb;

constexpr int kMinSide = 16;
constexpr int kMaxSide = 8192;
constexpr double kMaxPixels = 64.0 * 1024.0 * 1024.0;
constexpr double kMaxCoordinate = 1e9;        ///< [m] positions farther out are refused
constexpr double kBallAndStick = 0.4;         ///< with --connectors, spheres are drawn at this share of their radius

enum class Format { Png, PngSequence, Mp4, Gif };

const char* formatName(Format f) {
  switch (f) {
    case Format::Png: return "png";
    case Format::PngSequence: return "png-sequence";
    case Format::Mp4: return "mp4";
    case Format::Gif: return "gif";
  }
  return "png";
}

/// An error of the command line (no file to name).
Error usage(const std::string& message) { return Error{"", 0, 0, message}; }

bool parseInt(const std::string& text, long long& out) {
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, out);
  return ec == std::errc() && ptr == end && !text.empty();
}

/// "WIDTHxHEIGHT", each from kMinSide to kMaxSide.
std::optional<Error> parseSize(const std::string& text, int& width, int& height) {
  const std::size_t x = text.find('x');
  long long w = 0, h = 0;
  const std::string expected = "--size " + text + ": expected WIDTHxHEIGHT in pixels, each from " + std::to_string(kMinSide) +
                               " to " + std::to_string(kMaxSide) + " (e.g. 960x720)";
  if (x == std::string::npos || !parseInt(text.substr(0, x), w) || !parseInt(text.substr(x + 1), h)) return usage(expected);
  if (w < kMinSide || h < kMinSide || w > kMaxSide || h > kMaxSide) return usage(expected);
  if (static_cast<double>(w) * static_cast<double>(h) > kMaxPixels)
    return usage("--size " + text + ": expected at most 64 Mpixels");
  width = static_cast<int>(w);
  height = static_cast<int>(h);
  return std::nullopt;
}

/// A frame index from -frames to frames - 1 (negative: counted from the end), or "" for `fallback`.
std::optional<Error> frameIndex(const std::string& text, const std::string& option, std::size_t frames, std::size_t fallback,
                                std::size_t& out) {
  if (text.empty()) {
    out = fallback;
    return std::nullopt;
  }
  long long v = 0;
  const auto n = static_cast<long long>(frames);
  const std::string range = "expected a frame index from 0 to " + std::to_string(n - 1) + " (or -1 for the last, -2 ...); the "
                            "trajectory has " + std::to_string(n) + " complete frames";
  if (!parseInt(text, v)) return usage(option + ": '" + text + "' is not a whole number; " + range);
  if (v < -n || v >= n) return usage(option + ": frame " + text + " is out of range; " + range);
  out = static_cast<std::size_t>(v < 0 ? v + n : v);
  return std::nullopt;
}

/// The frames of FIRST:LAST[:STRIDE] (LAST included; FIRST and LAST may be left out or negative).
std::optional<Error> parseFrames(const std::string& text, std::size_t frames, std::vector<std::size_t>& out) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (true) {
    const std::size_t colon = text.find(':', start);
    parts.push_back(text.substr(start, colon == std::string::npos ? std::string::npos : colon - start));
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  if (parts.size() < 2 || parts.size() > 3)
    return usage("--frames " + text + ": expected FIRST:LAST or FIRST:LAST:STRIDE (frame indices, LAST included)");
  std::size_t first = 0, last = 0;
  if (auto e = frameIndex(parts[0], "--frames " + text + " (FIRST)", frames, 0, first)) return e;
  if (auto e = frameIndex(parts[1], "--frames " + text + " (LAST)", frames, frames - 1, last)) return e;
  long long stride = 1;
  if (parts.size() == 3 && !parts[2].empty() && (!parseInt(parts[2], stride) || stride < 1 || stride > 2147483647))
    return usage("--frames " + text + ": STRIDE '" + parts[2] + "' is not a whole number from 1 to 2147483647");
  if (last < first) return usage("--frames " + text + ": LAST comes before FIRST; expected FIRST <= LAST");
  for (std::size_t t = first; t <= last; t += static_cast<std::size_t>(stride)) out.push_back(t);
  return std::nullopt;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

/// Same file (by any path or link) or same path once made absolute.
bool samePath(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec)) return true;
  return fs::weakly_canonical(a, ec) == fs::weakly_canonical(b, ec);
}

/// A name next to `target` to write it under first (renamed onto it once whole).
fs::path temporaryFor(const fs::path& target) {
  return target.parent_path() / ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid()));
}

/// Removes the temporary files left by a render that failed.
struct Temporaries {
  std::vector<fs::path> paths;
  ~Temporaries() {
    std::error_code ec;
    for (const fs::path& p : paths) fs::remove(p, ec);
  }
};

std::string json(const Vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "[%.17g, %.17g, %.17g]", v.x(), v.y(), v.z());
  return buf;
}

std::string json(Rgb c) { return "[" + std::to_string(c.r) + ", " + std::to_string(c.g) + ", " + std::to_string(c.b) + "]"; }

std::string json(const std::string& s) {
  std::string out = "\"";
  for (const unsigned char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out + "\"";
}

/// 1, 2 or 5 times a power of ten, the nearest at or below x.
double niceLength(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (const double m : {5.0, 2.0}) if (m * p <= x) return m * p;
  return p;
}

/// Everything read once per trajectory.
struct Scene {
  TrajectorySummary summary;
  std::vector<double> radius;               ///< [P] m
  std::vector<bool> bodyStatic;             ///< [B]
  std::vector<std::array<double, 4>> planes;
  std::optional<ConnectorTable> connectors;
};

/// The time label of frame t.
std::string label(const TrajectorySummary& s, std::size_t t) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "t = %.3f s  step %lld", s.time[t], static_cast<long long>(s.step[t]));
  return buf;
}

/// Where the label goes: its box in pixels.
struct LabelBox {
  int x = 0, y = 0, width = 0, height = 0, scale = 1, pad = 0;
};

LabelBox labelBox(const std::string& text, int imageHeight) {
  LabelBox b;
  b.scale = std::max(1, imageHeight / 360);
  b.pad = 3 * b.scale;
  b.x = 4 * b.scale;
  b.y = 4 * b.scale;
  b.width = render::textWidth(text, b.scale) + 2 * b.pad;
  b.height = render::kGlyphHeight * b.scale + 2 * b.pad;
  return b;
}

}  // namespace

int renderTrajectory(const RenderArgs& args) {
  // ---- the command line, before anything is read
  int width = 0, height = 0;
  if (auto e = parseSize(args.size, width, height)) return fail(*e);
  render::View view{};
  if (!render::parseView(args.view, view)) return fail(usage("--view " + args.view + ": expected iso, front, side or top"));
  if (!std::isfinite(args.fps) || !(args.fps > 0.0) || args.fps > 240.0)
    return fail(usage("--fps: expected a number of frames per second above 0 and at most 240"));
  const fs::path input = args.input;
  fs::path output = args.output;
  if (output.empty()) output = input.stem().string() + ".png";
  if (samePath(output, input)) return fail(usage("-o " + output.string() + " is the trajectory itself; expected another file"));
  const std::string ext = lower(output.extension().string());
  Format format = Format::Png;
  if (ext == ".png") format = args.frames.empty() ? Format::Png : Format::PngSequence;
  else if (ext == ".mp4") format = Format::Mp4;
  else if (ext == ".gif") format = Format::Gif;
  else return fail(usage("-o " + output.string() + ": expected a file name ending in .png, .mp4 or .gif"));
  const bool video = format == Format::Mp4 || format == Format::Gif;
  if (format == Format::Mp4 && (width % 2 != 0 || height % 2 != 0))
    return fail(usage("--size " + args.size + ": MP4 (H.264 in yuv420p) needs an even width and height"));
  {
    std::error_code ec;
    const fs::path folder = output.parent_path().empty() ? fs::path(".") : output.parent_path();
    if (!fs::is_directory(folder, ec)) return fail(usage("-o " + output.string() + ": the folder " + folder.string() + " does not exist"));
    if (fs::is_directory(output, ec)) return fail(usage("-o " + output.string() + " is a folder; expected a file name"));
  }
  if (video && render::findProgram("ffmpeg").empty())
    return fail(Error{output.string(), 0, 0,
                      "writing MP4 or GIF needs the ffmpeg program, which is not on PATH; install the Debian package ffmpeg "
                      "(apt-get install ffmpeg)"});

  // ---- the trajectory, checked as inspect checks it, then what the picture needs
  std::error_code ec;
  if (!fs::is_regular_file(input, ec)) return fail(Error{input.string(), 0, 0, "no such file; expected a trajectory (.h5)"});
  if (const auto damaged = readsSafely(input.string())) return fail(*damaged);
  auto reader = H5mdReader::open(input.string());
  if (!reader) return fail(reader.error());
  const H5mdReader& r = **reader;
  Scene scene;
  {
    auto s = r.summary();
    if (!s) return fail(s.error());
    scene.summary = std::move(*s);
    auto radius = r.radii();
    if (!radius) return fail(radius.error());
    scene.radius = std::move(*radius);
    auto kinds = r.bodyKinds();
    if (!kinds) return fail(kinds.error());
    if (kinds->size() != scene.summary.bodies)
      return fail(Error{input.string(), 0, 0, "/particles/bodies/kind has " + std::to_string(kinds->size()) +
                                                  " entries but /particles/bodies/name " + std::to_string(scene.summary.bodies) +
                                                  "; expected one kind per body"});
    for (const std::string& k : *kinds) scene.bodyStatic.push_back(k == "static");
    auto planes = r.planes();
    if (!planes) return fail(planes.error());
    scene.planes = std::move(*planes);
    if (args.connectors) {
      auto c = r.connectors(scene.summary.particles);
      if (!c) return fail(c.error());
      scene.connectors = std::move(*c);
    }
  }
  const TrajectorySummary& sum = scene.summary;
  const std::size_t particles = sum.particles;

  // ---- which frames
  std::vector<std::size_t> frames;
  if (!args.frames.empty()) {
    if (auto e = parseFrames(args.frames, sum.frames, frames)) return fail(*e);
  } else {
    std::size_t one = 0;
    if (auto e = frameIndex(args.frame, "--frame", sum.frames, sum.frames - 1, one)) return fail(*e);
    if (video && args.frame.empty()) {
      for (std::size_t t = 0; t < sum.frames; ++t) frames.push_back(t);
    } else {
      frames.push_back(one);
    }
  }

  // ---- the outputs, each written under a temporary name first
  std::vector<fs::path> outputs;
  if (format == Format::PngSequence) {
    const fs::path stem = output.parent_path() / output.stem();
    for (std::size_t k = 0; k < frames.size(); ++k) {
      char number[32];
      std::snprintf(number, sizeof number, "-%04zu.png", k);
      outputs.push_back(stem.string() + number);
      if (samePath(outputs.back(), input))
        return fail(usage("-o " + output.string() + ": " + outputs.back().string() + " is the trajectory itself; expected another file"));
    }
  } else {
    outputs.push_back(output);
  }
  Temporaries temporaries;

  // ---- the camera: the bounds of every particle over the frames rendered
  const auto readPositions = [&](std::size_t t) -> Result<std::vector<Vec3>> {
    auto x = r.positions(t);
    if (!x) return x;
    if (x->size() != particles)
      return Error{input.string(), 0, 0, "/particles/all/position/value frame " + std::to_string(t) + " has " +
                                             std::to_string(x->size()) + " particles; expected " + std::to_string(particles)};
    for (std::size_t i = 0; i < x->size(); ++i)
      if (!(*x)[i].allFinite() || (*x)[i].cwiseAbs().maxCoeff() > kMaxCoordinate)
        return Error{input.string(), 0, 0, "/particles/all/position/value frame " + std::to_string(t) + " particle " +
                                               std::to_string(i) + " is not a finite position within 1e9 m"};
    return x;
  };
  Bounds bounds;
  for (const std::size_t t : frames) {
    auto x = readPositions(t);
    if (!x) return fail(x.error());
    for (std::size_t i = 0; i < particles; ++i) bounds.add((*x)[i], scene.radius[i]);
  }
  if (bounds.empty()) return fail(Error{input.string(), 0, 0, "the trajectory has no particles; nothing to draw"});
  const Camera cam = Camera::framing(view, bounds, width, height);

  // the planes: squares about the bounds' centre, three quarters of the bounds' diagonal from it each way
  struct Floor {
    Vec3 centre, normal;
  };
  std::vector<Floor> floors;
  const double floorHalf = 0.75 * bounds.diagonal();
  const double cell = niceLength(floorHalf / 5.0);
  for (const auto& p : scene.planes) {
    const Vec3 n(p[0], p[1], p[2]);
    const Vec3 c = bounds.centre() - n * (n.dot(bounds.centre()) - p[3]);
    floors.push_back({c, n});
  }

  // ---- the frames
  const render::Lighting lighting;
  const int thickness = std::max(1, static_cast<int>(std::lround(height / 400.0)));
  double meanRadius = 0.0;
  for (const double rad : scene.radius) meanRadius += rad;
  meanRadius /= static_cast<double>(std::max<std::size_t>(particles, 1));
  const double drawnShare = args.connectors ? kBallAndStick : 1.0;

  std::unique_ptr<render::VideoEncoder> encoder;
  if (video) {
    temporaries.paths.push_back(temporaryFor(outputs[0]));
    auto e = render::VideoEncoder::start(format == Format::Mp4 ? render::VideoFormat::Mp4 : render::VideoFormat::Gif,
                                         temporaries.paths[0].string(), width, height, args.fps);
    if (!e) return fail(Error{outputs[0].string(), 0, 0, e.error().message});
    encoder = std::move(*e);
  }
  Canvas canvas(width, height);
  LabelBox box;
  std::string lastLabel;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const std::size_t t = frames[k];
    auto x = readPositions(t);
    if (!x) return fail(x.error());
    auto body = r.particleBodies(t, sum.bodies);
    if (!body) return fail(body.error());
    canvas.clear(render::kBackgroundTop, render::kBackgroundBottom);
    for (const Floor& f : floors)
      canvas.floor(cam, f.centre, f.normal, floorHalf, cell, render::kFloorLight, render::kFloorDark, lighting);
    for (std::size_t i = 0; i < particles; ++i) {
      const auto b = static_cast<std::size_t>((*body)[i]);
      canvas.sphere(cam, (*x)[i], drawnShare * scene.radius[i], render::bodyColour(b, scene.bodyStatic[b]), lighting);
    }
    if (scene.connectors) {
      const ConnectorTable& c = *scene.connectors;
      const Rgb byKind[3] = {render::kRod, render::kSpring, render::kBond};
      for (std::size_t j = 0; j < c.particleA.size(); ++j) {
        if (sum.step[t] >= c.breakStep[j]) continue;
        canvas.line(cam, (*x)[static_cast<std::size_t>(c.particleA[j])], (*x)[static_cast<std::size_t>(c.particleB[j])], thickness,
                    byKind[c.kind[j]], true);
      }
    }
    if (args.contacts) {
      auto rows = r.contactPoints(t);
      if (!rows) return fail(rows.error());
      for (const Vec3& p : rows->point) {
        const render::ScreenPoint s = cam.project(p);
        canvas.marker(s.x, s.y, 2 * thickness + 1, render::kContact, Rgb{0, 0, 0});
      }
    }
    if (args.normals) {
      auto rows = r.patchNormals(t);
      if (!rows) return fail(rows.error());
      const double length = 4.0 * meanRadius;
      for (std::size_t j = 0; j < rows->point.size(); ++j) {
        const Vec3& p = rows->point[j];
        const Vec3 n = rows->normal[j].normalized();
        if (!n.allFinite()) continue;
        const Vec3 tip = p + length * n;
        canvas.line(cam, p, tip, thickness, render::kNormal, false);
        // the head: two strokes back from the tip, across the normal as seen on the screen
        const Vec3 across = n.cross(cam.forward);
        if (across.norm() > 1e-6) {
          const Vec3 side = across.normalized() * (0.15 * length);
          canvas.line(cam, tip, tip - 0.3 * length * n + side, thickness, render::kNormal, false);
          canvas.line(cam, tip, tip - 0.3 * length * n - side, thickness, render::kNormal, false);
        }
      }
    }
    lastLabel = label(sum, t);
    box = labelBox(lastLabel, height);
    canvas.rect(box.x, box.y, box.width, box.height, render::kLabelBox);
    render::drawText(canvas, box.x + box.pad, box.y + box.pad, lastLabel, box.scale, render::kLabelText);

    if (video) {
      if (auto ok = encoder->frame(canvas); !ok) return fail(Error{outputs[0].string(), 0, 0, ok.error().message});
    } else {
      temporaries.paths.push_back(temporaryFor(outputs[k]));
      if (auto ok = render::writePng(temporaries.paths.back().string(), canvas); !ok)
        return fail(Error{outputs[k].string(), 0, 0, ok.error().message});
    }
  }
  if (encoder) {
    if (auto ok = encoder->finish(); !ok) return fail(Error{outputs[0].string(), 0, 0, ok.error().message});
  }

  // ---- every file whole: each takes its name
  for (std::size_t k = 0; k < outputs.size(); ++k) {
    fs::rename(temporaries.paths[k], outputs[k], ec);
    if (ec) return fail(Error{outputs[k].string(), 0, 0, "cannot rename " + temporaries.paths[k].string() + " to it: " + ec.message()});
  }
  temporaries.paths.clear();

  if (args.json) {
    std::ostringstream j;
    j << "{\"file\": " << json(input.string()) << ", \"output\": " << json(output.string()) << ", \"format\": \"" << formatName(format)
      << "\", \"outputs\": [";
    for (std::size_t k = 0; k < outputs.size(); ++k) j << (k ? ", " : "") << json(outputs[k].string());
    j << "], \"frame_indices\": [";
    for (std::size_t k = 0; k < frames.size(); ++k) j << (k ? ", " : "") << frames[k];
    char num[64];
    std::snprintf(num, sizeof num, "%.17g", args.fps);
    j << "], \"frames\": " << frames.size() << ", \"fps\": " << num;
    std::snprintf(num, sizeof num, "%.17g", static_cast<double>(frames.size()) / args.fps);
    j << ", \"duration\": " << num << ", \"width\": " << width << ", \"height\": " << height << ", \"view\": \""
      << render::viewName(view) << "\"";
    std::snprintf(num, sizeof num, "%.17g", cam.scale);
    j << ", \"camera\": {\"projection\": \"orthographic\", \"eye\": " << json(cam.eye) << ", \"target\": " << json(cam.target)
      << ", \"forward\": " << json(cam.forward) << ", \"right\": " << json(cam.right) << ", \"up\": " << json(cam.up)
      << ", \"scale\": " << num << "}";
    j << ", \"bounds\": {\"lo\": " << json(bounds.lo) << ", \"hi\": " << json(bounds.hi) << "}";
    j << ", \"palette\": [";
    for (std::size_t k = 0; k < render::kBodyPalette.size(); ++k) j << (k ? ", " : "") << json(render::kBodyPalette[k]);
    j << "], \"static_colour\": " << json(render::kStaticBody) << ", \"floor_colours\": [" << json(render::kFloorLight) << ", "
      << json(render::kFloorDark) << "], \"background\": [" << json(render::kBackgroundTop) << ", "
      << json(render::kBackgroundBottom) << "]";
    j << ", \"label\": {\"x\": " << box.x << ", \"y\": " << box.y << ", \"width\": " << box.width << ", \"height\": " << box.height
      << ", \"text\": " << json(lastLabel) << "}}";
    std::cout << j.str() << std::endl;
  } else if (video) {
    std::printf("%s (%zu frames, %dx%d, %.6g fps)\n", outputs[0].c_str(), frames.size(), width, height, args.fps);
  } else {
    for (const fs::path& p : outputs) std::printf("%s\n", p.c_str());
  }
  return 0;
}

}  // namespace volpar::cli
