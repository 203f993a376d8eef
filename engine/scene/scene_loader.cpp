#include "volpar/engine/scene/scene_loader.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <optional>
#include <set>
#include <sstream>

#include "volpar/engine/core/input_file.hpp"
#include "volpar/engine/core/limits.hpp"

namespace volpar {

namespace {

constexpr double kAnyFinite = std::numeric_limits<double>::max();

// ---------------------------------------------------------------------------------------------
// error plumbing: the loader throws LoadError internally; parseScene turns it into a Result.

struct LoadError {
  Error error;
};

std::string joinKeys(const std::vector<std::string>& keys) {
  std::string out;
  for (std::size_t i = 0; i < keys.size(); ++i) out += (i ? ", " : "") + keys[i];
  return out;
}

std::size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1)});
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string suggestion(const std::string& key, const std::vector<std::string>& allowed) {
  std::string best;
  std::size_t bestDist = 3;
  for (const auto& a : allowed) {
    const std::size_t d = editDistance(key, a);
    if (d < bestDist) {
      bestDist = d;
      best = a;
    }
  }
  return best.empty() ? "" : " (did you mean '" + best + "'?)";
}

class Ctx {
 public:
  explicit Ctx(std::string path, std::vector<std::filesystem::path> roots = {})
      : path_(std::move(path)), roots_(std::move(roots)) {}
  /// The folders files the scene names must lie in (resolved, links followed).
  [[nodiscard]] const std::vector<std::filesystem::path>& roots() const { return roots_; }
  [[noreturn]] void fail(const YAML::Mark& m, const std::string& message) const {
    const bool known = !m.is_null();
    throw LoadError{Error{path_, known ? m.line + 1 : 0, known ? m.column + 1 : 0, message}};
  }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::vector<std::filesystem::path> roots_;
};

/// Whether `file` (resolved) lies inside folder `root` (resolved).
bool inside(const std::filesystem::path& file, const std::filesystem::path& root) {
  auto f = file.begin();
  for (auto r = root.begin(); r != root.end(); ++r, ++f) {
    if (r->empty()) continue;  // a trailing separator
    if (f == file.end() || *f != *r) return false;
  }
  return true;
}

/// Where `text` is not UTF-8 (names and the scene's text are stored as UTF-8 strings in trajectories).
std::optional<Error> notUtf8(const std::string& text, const std::string& path) {
  int line = 1, column = 1;
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool ok = n > 0 && i + n <= text.size() && c != 0xC0 && c != 0xC1 && c < 0xF5;
    for (std::size_t k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(text[i + k]) >> 6) == 0x2;
    if (!ok) return Error{path, line, column, "not valid UTF-8; expected a UTF-8 (or plain ASCII) scene file"};
    if (c == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
    i += n;
  }
  return std::nullopt;
}

/// Refuses text nested deeper than kMaxSceneNesting (flow brackets, block indentation levels, "- - -")
/// before the YAML parser recurses into it. A scan, not a parse: quotes and comments are followed closely
/// enough for any scene.
std::optional<Error> tooDeep(const std::string& text, const std::string& path) {
  std::vector<std::size_t> indents;  // open block levels
  int flow = 0, line = 1, column = 0;
  std::size_t indent = 0;
  bool lineStart = true, comment = false, escaped = false;
  char quote = 0, previous = '\n';
  const auto deeper = [&] {
    return Error{path, line, column, "lists and maps nested deeper than " + std::to_string(kMaxSceneNesting) +
                                         " levels; expected a scene (it needs about six)"};
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '\n') {
      ++line;
      column = 0;
      indent = 0;
      lineStart = quote == 0 && flow == 0;
      comment = false;
      previous = c;
      continue;
    }
    ++column;
    if (comment) continue;
    if (quote) {
      if (quote == '"' && c == '\\' && !escaped) escaped = true;
      else if (c == quote && !escaped) quote = 0;
      else escaped = false;
      continue;
    }
    if (lineStart) {
      if (c == ' ') {
        ++indent;
        continue;
      }
      lineStart = false;
      if (c != '#' && c != '\r') {
        while (!indents.empty() && indents.back() >= indent) indents.pop_back();
        indents.push_back(indent);
        // compact nesting: "- - - x" opens a level per dash
        for (std::size_t k = i; k + 1 < text.size() && text[k] == '-' && text[k + 1] == ' '; k += 2) indents.push_back(indent + (k - i) + 2);
        if (indents.size() > static_cast<std::size_t>(kMaxSceneNesting)) return deeper();
      }
    }
    const bool scalarStart = previous == '\n' || previous == ' ' || previous == '\t' || previous == '[' || previous == '{' ||
                             previous == ',' || previous == ':' || previous == '-';
    if (c == '#' && (previous == ' ' || previous == '\t' || previous == '\n')) comment = true;
    else if ((c == '"' || c == '\'') && scalarStart) quote = c;
    else if (c == '[' || c == '{') {
      if (++flow + static_cast<int>(indents.size()) > kMaxSceneNesting) return deeper();
    } else if ((c == ']' || c == '}') && flow > 0) --flow;
    previous = c;
  }
  return std::nullopt;
}

std::string describe(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Null: return "nothing";
    case YAML::NodeType::Scalar: return "'" + n.Scalar() + "'";
    case YAML::NodeType::Sequence: return "a list";
    case YAML::NodeType::Map: return "a map";
    default: return "an undefined value";
  }
}

/// A YAML map whose keys are checked against an allowed set (unknown and duplicate keys are errors).
class MapReader {
 public:
  MapReader(const Ctx& ctx, const YAML::Node& node, const std::string& what, std::vector<std::string> allowed)
      : ctx_(ctx), node_(node), what_(what) {
    if (!node.IsMap()) ctx.fail(node.Mark(), "expected a map for " + what + ", got " + describe(node));
    std::set<std::string> seen;
    for (auto it = node.begin(); it != node.end(); ++it) {
      const YAML::Node key = it->first;
      if (!key.IsScalar()) ctx.fail(key.Mark(), "expected a plain key in " + what);
      const std::string& k = key.Scalar();
      if (std::find(allowed.begin(), allowed.end(), k) == allowed.end())
        ctx.fail(key.Mark(), "unknown key '" + k + "' in " + what + suggestion(k, allowed) +
                                 "; expected one of: " + joinKeys(allowed));
      if (!seen.insert(k).second) ctx.fail(key.Mark(), "duplicate key '" + k + "' in " + what);
      keyMarks_[k] = key.Mark();
    }
  }
  [[nodiscard]] bool has(const std::string& key) const { return keyMarks_.contains(key); }
  [[nodiscard]] YAML::Node get(const std::string& key) const { return node_[key]; }
  [[nodiscard]] YAML::Node require(const std::string& key) const {
    if (!has(key)) ctx_.fail(node_.Mark(), "missing key '" + key + "' in " + what_);
    return node_[key];
  }
  [[nodiscard]] YAML::Mark mark() const { return node_.Mark(); }
  [[nodiscard]] YAML::Mark keyMark(const std::string& key) const { return keyMarks_.at(key); }
  [[nodiscard]] std::size_t size() const { return keyMarks_.size(); }
  [[nodiscard]] const std::string& what() const { return what_; }

 private:
  const Ctx& ctx_;
  YAML::Node node_;
  std::string what_;
  std::map<std::string, YAML::Mark> keyMarks_;
};

// ---------------------------------------------------------------------------------------------
// scalars

std::string text(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) ctx.fail(n.Mark(), "expected a string for " + what + ", got " + describe(n));
  return n.Scalar();
}

double number(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (!n.IsScalar()) ctx.fail(n.Mark(), "expected a number for " + what + ", got " + describe(n));
  std::string s = n.Scalar();
  if (!s.empty() && s[0] == '+') s.erase(0, 1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || ptr != s.data() + s.size() || s.empty())
    ctx.fail(n.Mark(), "expected a number for " + what + ", got " + describe(n));
  if (!std::isfinite(v)) ctx.fail(n.Mark(), "expected a finite number for " + what + ", got " + describe(n));
  return v;
}

/// Lengths (sizes, radii, positions) are at most kMaxLength: beyond it particle grids and contact sums lose
/// their meaning long before they overflow.
void checkLength(const Ctx& ctx, const YAML::Node& n, double v, const std::string& what, const std::string& unit) {
  if (unit == "m" && !(std::abs(v) <= kMaxLength)) {
    std::ostringstream m;
    m << "expected " << what << " of at most " << kMaxLength << " m in magnitude, got " << n.Scalar();
    ctx.fail(n.Mark(), m.str());
  }
}

double positive(const Ctx& ctx, const YAML::Node& n, const std::string& what, const std::string& unit) {
  const double v = number(ctx, n, what);
  if (!(v > 0.0)) ctx.fail(n.Mark(), "expected a positive " + what + " [" + unit + "], got " + n.Scalar());
  checkLength(ctx, n, v, what, unit);
  return v;
}

double nonNegative(const Ctx& ctx, const YAML::Node& n, const std::string& what, const std::string& unit) {
  const double v = number(ctx, n, what);
  if (!(v >= 0.0)) ctx.fail(n.Mark(), "expected a non-negative " + what + " [" + unit + "], got " + n.Scalar());
  checkLength(ctx, n, v, what, unit);
  return v;
}

double inRange(const Ctx& ctx, const YAML::Node& n, const std::string& what, double lo, double hi) {
  const double v = number(ctx, n, what);
  if (!(v >= lo && v <= hi)) {
    std::ostringstream m;
    m << "expected " << what << " in [" << lo << ", " << hi << "], got " << n.Scalar();
    ctx.fail(n.Mark(), m.str());
  }
  return v;
}

std::int64_t integer(const Ctx& ctx, const YAML::Node& n, const std::string& what, std::int64_t lo, std::int64_t hi) {
  const double v = number(ctx, n, what);
  if (std::floor(v) != v) ctx.fail(n.Mark(), "expected an integer for " + what + ", got " + n.Scalar());
  if (v < static_cast<double>(lo) || v > static_cast<double>(hi))
    ctx.fail(n.Mark(), "expected " + what + " in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " +
                           n.Scalar());
  return static_cast<std::int64_t>(v);
}

bool boolean(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  if (n.IsScalar()) {
    const std::string& s = n.Scalar();
    if (s == "true") return true;
    if (s == "false") return false;
  }
  ctx.fail(n.Mark(), "expected true or false for " + what + ", got " + describe(n));
}

/// Three numbers, each at most `limit` in magnitude (`unit` names it in messages).
Vec3 vec3(const Ctx& ctx, const YAML::Node& n, const std::string& what, double limit = kMaxLength,
          const char* unit = "m") {
  if (!n.IsSequence() || n.size() != 3)
    ctx.fail(n.Mark(), "expected a list of 3 numbers [x, y, z] for " + what + ", got " + describe(n));
  const Vec3 v(number(ctx, n[0], what), number(ctx, n[1], what), number(ctx, n[2], what));
  for (int k = 0; k < 3; ++k)
    if (!(std::abs(v[k]) <= limit)) {
      std::ostringstream m;
      m << "expected components of " << what << " of at most " << limit << " " << unit << " in magnitude, got "
        << n[k].Scalar();
      ctx.fail(n[k].Mark(), m.str());
    }
  return v;
}

/// A direction given by any finite, non-zero components (however large or small): scaled by its largest
/// component before normalising, so that its length neither overflows nor underflows.
template <class V>
std::optional<V> unitDirection(V v) {
  const double largest = v.cwiseAbs().maxCoeff();
  if (!(largest > 0.0)) return std::nullopt;
  v /= largest;
  return v.normalized();
}

Vec3 positiveVec3(const Ctx& ctx, const YAML::Node& n, const std::string& what, const std::string& unit) {
  const Vec3 v = vec3(ctx, n, what);
  for (int k = 0; k < 3; ++k)
    if (!(v[k] > 0.0)) ctx.fail(n[k].Mark(), "expected positive components for " + what + " [" + unit + "], got " + n[k].Scalar());
  return v;
}

std::string oneOf(const Ctx& ctx, const YAML::Node& n, const std::string& what, const std::vector<std::string>& options) {
  const std::string s = text(ctx, n, what);
  if (std::find(options.begin(), options.end(), s) == options.end())
    ctx.fail(n.Mark(), "unknown " + what + " '" + s + "'" + suggestion(s, options) + "; expected one of: " + joinKeys(options));
  return s;
}

// ---------------------------------------------------------------------------------------------
// compound values

/// An axis and angle: {axis: [x, y, z], angle: rad | angle_deg: deg}.
std::pair<Vec3, double> axisAngle(const Ctx& ctx, const YAML::Node& n, const std::string& what) {
  const MapReader m(ctx, n, what, {"axis", "angle", "angle_deg"});
  const YAML::Node axisNode = m.require("axis");
  const auto axis = unitDirection(vec3(ctx, axisNode, "rotation axis", kAnyFinite, ""));
  if (!axis) ctx.fail(axisNode.Mark(), "expected a non-zero rotation axis, got a zero-length vector");
  if (m.has("angle") == m.has("angle_deg"))
    ctx.fail(m.mark(), "expected exactly one of 'angle' [rad] or 'angle_deg' [deg] in " + what);
  const double angle = m.has("angle") ? number(ctx, m.get("angle"), "angle")
                                      : number(ctx, m.get("angle_deg"), "angle_deg") * std::numbers::pi / 180.0;
  return {*axis, angle};
}

Quat rotation(const Ctx& ctx, const YAML::Node& n) {
  const MapReader m(ctx, n, "orientation", {"axis", "angle", "angle_deg", "quaternion"});
  if (m.has("quaternion")) {
    if (m.size() != 1) ctx.fail(m.mark(), "'quaternion' cannot be combined with 'axis' or 'angle' in orientation");
    const YAML::Node q = m.get("quaternion");
    if (!q.IsSequence() || q.size() != 4)
      ctx.fail(q.Mark(), "expected a quaternion [w, x, y, z] of 4 numbers, got " + describe(q));
    const Eigen::Vector4d wxyz(number(ctx, q[0], "quaternion"), number(ctx, q[1], "quaternion"),
                               number(ctx, q[2], "quaternion"), number(ctx, q[3], "quaternion"));
    const auto unit = unitDirection(wxyz);
    if (!unit) ctx.fail(q.Mark(), "expected a non-zero quaternion [w, x, y, z]");
    return Quat((*unit)[0], (*unit)[1], (*unit)[2], (*unit)[3]);
  }
  const auto [axis, angle] = axisAngle(ctx, n, "orientation");
  return Quat(Eigen::AngleAxisd(angle, axis));
}

/// One rotation, or a list applied in order (each about the world axes).
Quat orientation(const Ctx& ctx, const YAML::Node& n) {
  if (n.IsSequence()) {
    if (n.size() == 0) ctx.fail(n.Mark(), "expected at least one rotation in the orientation list");
    Quat q = Quat::Identity();
    for (const auto& r : n) q = rotation(ctx, r) * q;
    return q.normalized();
  }
  return rotation(ctx, n);
}

Material material(const Ctx& ctx, const YAML::Node& n, const std::string& name) {
  const MapReader m(ctx, n, "material '" + name + "'",
                    {"density", "restitution", "friction", "rolling_resistance", "rod_strength",
                     "rod_compressive_strength", "strain_limit", "youngs_modulus", "poisson_ratio",
                     "tensile_strength", "shear_strength", "weibull_modulus"});
  Material mat;
  mat.name = name;
  if (m.has("density")) mat.density = positive(ctx, m.get("density"), "density", "kg/m^3");
  if (m.has("restitution")) mat.restitution = inRange(ctx, m.get("restitution"), "restitution", 0.0, 1.0);
  if (m.has("friction")) mat.friction = nonNegative(ctx, m.get("friction"), "friction", "-");
  if (m.has("rolling_resistance"))
    mat.rollingResistance = nonNegative(ctx, m.get("rolling_resistance"), "rolling resistance", "-");
  if (m.has("rod_strength")) mat.rodStrength = positive(ctx, m.get("rod_strength"), "rod strength", "N");
  if (m.has("rod_compressive_strength"))
    mat.rodCompressiveStrength = positive(ctx, m.get("rod_compressive_strength"), "rod compressive strength", "N");
  if (m.has("strain_limit")) mat.strainLimit = positive(ctx, m.get("strain_limit"), "spring strain limit", "-");
  if (m.has("youngs_modulus")) mat.youngsModulus = positive(ctx, m.get("youngs_modulus"), "Young's modulus", "Pa");
  if (m.has("poisson_ratio")) {
    const YAML::Node v = m.get("poisson_ratio");
    mat.poissonRatio = number(ctx, v, "Poisson's ratio");
    if (!(mat.poissonRatio > -1.0 && mat.poissonRatio < 0.5))
      ctx.fail(v.Mark(), "expected a Poisson's ratio in (-1, 0.5), got " + v.Scalar());
  }
  if (m.has("tensile_strength")) mat.tensileStrength = positive(ctx, m.get("tensile_strength"), "tensile strength", "Pa");
  if (m.has("shear_strength")) mat.shearStrength = positive(ctx, m.get("shear_strength"), "shear strength", "Pa");
  if (m.has("weibull_modulus")) mat.weibullModulus = positive(ctx, m.get("weibull_modulus"), "Weibull modulus", "-");
  return mat;
}

PlaneDesc plane(const Ctx& ctx, const YAML::Node& n) {
  const MapReader m(ctx, n, "plane", {"normal", "offset", "point", "material"});
  PlaneDesc p;
  p.mark = {n.Mark().line + 1, n.Mark().column + 1};
  const YAML::Node nn = m.require("normal");
  const auto normal = unitDirection(vec3(ctx, nn, "plane normal", kAnyFinite, ""));
  if (!normal) ctx.fail(nn.Mark(), "expected a non-zero plane normal");
  p.normal = *normal;
  if (m.has("offset") && m.has("point")) ctx.fail(m.mark(), "expected either 'offset' or 'point' for a plane, not both");
  if (m.has("offset")) {
    p.offset = number(ctx, m.get("offset"), "plane offset");
    checkLength(ctx, m.get("offset"), p.offset, "plane offset", "m");
  }
  if (m.has("point")) p.offset = p.normal.dot(vec3(ctx, m.get("point"), "plane point"));
  if (m.has("material")) p.material = text(ctx, m.get("material"), "material");
  return p;
}

ShapeDesc shape(const Ctx& ctx, const YAML::Node& n, const std::filesystem::path& sceneDir) {
  const MapReader m(ctx, n, "shape", {"box", "sphere", "cylinder", "capsule", "mesh", "particles"});
  if (m.size() != 1)
    ctx.fail(m.mark(), "expected exactly one shape kind (box, sphere, cylinder, capsule, mesh or particles)");
  if (m.has("box")) {
    const MapReader b(ctx, m.get("box"), "box", {"size"});
    return BoxDesc{positiveVec3(ctx, b.require("size"), "box size", "m")};
  }
  if (m.has("sphere")) {
    const MapReader s(ctx, m.get("sphere"), "sphere", {"radius"});
    return SphereDesc{positive(ctx, s.require("radius"), "sphere radius", "m")};
  }
  if (m.has("cylinder")) {
    const MapReader c(ctx, m.get("cylinder"), "cylinder", {"radius", "height"});
    return CylinderDesc{positive(ctx, c.require("radius"), "cylinder radius", "m"),
                        positive(ctx, c.require("height"), "cylinder height", "m")};
  }
  if (m.has("capsule")) {
    const MapReader c(ctx, m.get("capsule"), "capsule", {"radius", "length"});
    return CapsuleDesc{positive(ctx, c.require("radius"), "capsule radius", "m"),
                       nonNegative(ctx, c.require("length"), "capsule segment length", "m")};
  }
  if (m.has("mesh")) {
    const MapReader me(ctx, m.get("mesh"), "mesh", {"file", "scale"});
    MeshDesc d;
    const YAML::Node fileNode = me.require("file");
    d.file = text(ctx, fileNode, "mesh file");
    std::filesystem::path p(d.file);
    if (p.is_relative()) p = sceneDir / p;
    d.path = p.lexically_normal().string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(p, ec))
      ctx.fail(fileNode.Mark(), "cannot open mesh file '" + d.file + "' (looked for " + d.path +
                                    "); expected a path to an OBJ file, relative to the scene file");
    // confinement: a scene reads files in its own folder (or folders the command line allows), whatever
    // its paths say and wherever links point
    const std::filesystem::path resolved = std::filesystem::canonical(p, ec);
    bool allowed = false;
    for (const std::filesystem::path& root : ctx.roots()) allowed = allowed || (!ec && inside(resolved, root));
    if (!allowed)
      ctx.fail(fileNode.Mark(), "mesh file '" + d.file + "' resolves to " + resolved.string() +
                                    ", outside the scene's folder; expected a file inside it (or in a folder given "
                                    "with --allow-dir)");
    if (me.has("scale")) d.scale = positive(ctx, me.get("scale"), "mesh scale", "-");
    return d;
  }
  const MapReader pm(ctx, m.get("particles"), "particles", {"positions", "radius", "radii", "connectors", "reach"});
  ParticlesDesc d;
  const YAML::Node pos = pm.require("positions");
  if (!pos.IsSequence() || pos.size() == 0)
    ctx.fail(pos.Mark(), "expected a non-empty list of positions [[x, y, z], ...], got " + describe(pos));
  for (const auto& p : pos) d.positions.push_back(vec3(ctx, p, "particle position"));
  if (pm.has("radius") == pm.has("radii"))
    ctx.fail(pm.mark(), "expected exactly one of 'radius' (all particles) or 'radii' (one per particle)");
  if (pm.has("radius")) {
    d.radii.push_back(positive(ctx, pm.get("radius"), "particle radius", "m"));
  } else {
    const YAML::Node r = pm.get("radii");
    if (!r.IsSequence() || r.size() != pos.size())
      ctx.fail(r.Mark(), "expected a list of " + std::to_string(pos.size()) + " radii, one per position");
    for (const auto& x : r) d.radii.push_back(positive(ctx, x, "particle radius", "m"));
  }
  if (pm.has("connectors")) {
    const YAML::Node c = pm.get("connectors");
    if (!c.IsSequence()) ctx.fail(c.Mark(), "expected a list of particle index pairs [[i, j], ...]");
    d.explicitConnectors = true;
    const auto maxIndex = static_cast<std::int64_t>(pos.size()) - 1;
    for (const auto& pair : c) {
      if (!pair.IsSequence() || pair.size() != 2) ctx.fail(pair.Mark(), "expected a particle index pair [i, j]");
      const auto i = integer(ctx, pair[0], "particle index", 0, maxIndex);
      const auto j = integer(ctx, pair[1], "particle index", 0, maxIndex);
      if (i == j) ctx.fail(pair.Mark(), "a connector must join two different particles");
      d.connectors.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)});
    }
  }
  if (pm.has("reach")) {
    if (d.explicitConnectors) ctx.fail(pm.keyMark("reach"), "'reach' cannot be combined with explicit 'connectors'");
    d.reach = positive(ctx, pm.get("reach"), "reach", "m");
  }
  return d;
}

FillSettings fill(const Ctx& ctx, const YAML::Node& n) {
  const MapReader m(ctx, n, "fill", {"lattice", "radius", "spacing", "reach"});
  FillSettings f;
  if (m.has("lattice")) f.lattice = oneOf(ctx, m.get("lattice"), "lattice", {"cubic", "hcp"}) == "hcp" ? Lattice::Hcp : Lattice::Cubic;
  f.radius = positive(ctx, m.require("radius"), "particle radius", "m");
  if (m.has("spacing")) f.spacing = positive(ctx, m.get("spacing"), "lattice spacing", "m");
  if (m.has("reach")) {
    const YAML::Node r = m.get("reach");
    f.reach = number(ctx, r, "reach");
    if (!(f.reach > 1.0 && f.reach <= 4.0))
      ctx.fail(r.Mark(), "expected reach in (1, 4] lattice spacings (nearest neighbours sit at 1), got " + r.Scalar());
  }
  return f;
}

/// `bonds` of a body or a glue: strengths left out come from the material (scene_build.cpp).
void bondKeys(const Ctx& ctx, const MapReader& m, BondParams& b) {
  if (m.has("tensile_strength")) b.tensileStrength = positive(ctx, m.get("tensile_strength"), "tensile strength", "Pa");
  if (m.has("shear_strength")) b.shearStrength = positive(ctx, m.get("shear_strength"), "shear strength", "Pa");
  if (m.has("weibull_modulus")) b.weibullModulus = positive(ctx, m.get("weibull_modulus"), "Weibull modulus", "-");
  if (m.has("radius")) {
    const YAML::Node r = m.get("radius");
    b.radiusFactor = number(ctx, r, "bond radius");
    if (!(b.radiusFactor > 0.0 && b.radiusFactor <= 1.0))
      ctx.fail(r.Mark(), "expected a bond radius in (0, 1] (a fraction of the smaller particle radius), got " + r.Scalar());
  }
}

ConnectorParams connectors(const Ctx& ctx, const YAML::Node& n, BodyKind kind) {
  ConnectorParams c;
  auto bondsOnly = [&](const YAML::Node& where) {
    if (kind == BodyKind::Deformable)
      ctx.fail(where.Mark(), "bonds join the particles of rigid bodies; a deformable body takes springs or rods");
    c.kind = ConnectorKind::Bond;
  };
  if (n.IsScalar()) {
    if (oneOf(ctx, n, "connector kind", {"rigid", "rods", "bonds"}) == "bonds") bondsOnly(n);
    return c;
  }
  const MapReader m(ctx, n, "connectors", {"rods", "springs", "bonds"});
  if (m.size() != 1) ctx.fail(m.mark(), "expected exactly one of 'rods', 'bonds' or 'springs' in connectors");
  if (m.has("bonds")) {
    const YAML::Node r = m.get("bonds");
    bondsOnly(r);
    if (r.IsNull() || (r.IsMap() && r.size() == 0)) return c;
    const MapReader bm(ctx, r, "bonds", {"tensile_strength", "shear_strength", "weibull_modulus", "radius"});
    for (const char* key : {"tensile_strength", "shear_strength"})
      if (bm.has(key) && kind == BodyKind::Static)
        ctx.fail(bm.keyMark(key), "static bodies never break; give the bonds a strength on a rigid body");
    bondKeys(ctx, bm, c.bond);
    return c;
  }
  if (m.has("rods")) {
    const YAML::Node r = m.get("rods");
    if (r.IsNull() || (r.IsMap() && r.size() == 0)) return c;
    const MapReader rm(ctx, r, "rods", {"strength", "compressive_strength"});
    for (const char* key : {"strength", "compressive_strength"})
      if (rm.has(key) && kind == BodyKind::Static)
        ctx.fail(rm.keyMark(key), "static bodies never break; give the rods a strength on a rigid or deformable body");
    if (rm.has("strength")) c.breakLimit = positive(ctx, rm.get("strength"), "rod strength", "N");
    if (rm.has("compressive_strength"))
      c.compressionLimit = positive(ctx, rm.get("compressive_strength"), "rod compressive strength", "N");
    return c;
  }
  if (kind != BodyKind::Deformable)
    ctx.fail(m.keyMark("springs"), "springs need 'kind: deformable'; rigid and static bodies are joined by rods");
  const MapReader sm(ctx, m.get("springs"), "springs", {"stiffness", "damping", "strain_limit"});
  c.kind = ConnectorKind::Spring;
  // without a stiffness, the springs are calibrated from the material's Young's modulus (scene_build.cpp)
  if (sm.has("stiffness")) c.stiffness = positive(ctx, sm.get("stiffness"), "spring stiffness", "N/m");
  if (sm.has("damping")) c.damping = nonNegative(ctx, sm.get("damping"), "spring damping", "N s/m");
  if (sm.has("strain_limit")) c.breakLimit = positive(ctx, sm.get("strain_limit"), "spring strain limit", "-");
  return c;
}

SurfaceNormals surfaceNormals(const Ctx& ctx, const YAML::Node& n) {
  return oneOf(ctx, n, "normals", {"shape", "estimated"}) == "estimated" ? SurfaceNormals::Estimated : SurfaceNormals::Shape;
}

RepeatDesc repeat(const Ctx& ctx, const YAML::Node& n) {
  const MapReader m(ctx, n, "repeat", {"count", "spacing", "rotation_step"});
  RepeatDesc r;
  const YAML::Node c = m.require("count");
  if (!c.IsSequence() || c.size() != 3) ctx.fail(c.Mark(), "expected a list of 3 counts [nx, ny, nz], got " + describe(c));
  std::int64_t total = 1;
  for (int k = 0; k < 3; ++k) {
    r.count[static_cast<std::size_t>(k)] = static_cast<int>(integer(ctx, c[k], "repeat count", 1, 1000000));
    total *= r.count[static_cast<std::size_t>(k)];
  }
  if (total > 10000000) ctx.fail(c.Mark(), "repeat would create " + std::to_string(total) + " bodies; expected at most 10000000");
  r.spacing = vec3(ctx, m.require("spacing"), "repeat spacing");
  if (m.has("rotation_step")) {
    const YAML::Node steps = m.get("rotation_step");
    if (steps.IsSequence()) {
      for (const auto& st : steps) r.rotationStep.push_back(axisAngle(ctx, st, "rotation_step"));
    } else {
      r.rotationStep.push_back(axisAngle(ctx, steps, "rotation_step"));
    }
  }
  return r;
}

BodyDesc body(const Ctx& ctx, const YAML::Node& n, std::size_t index, const std::filesystem::path& sceneDir) {
  const MapReader m(ctx, n, "body",
                    {"name", "kind", "shape", "fill", "connectors", "material", "mass", "particle_mass", "position",
                     "orientation", "velocity", "angular_velocity", "repeat", "pin", "normals", "mass_properties"});
  BodyDesc b;
  b.mark = {n.Mark().line + 1, n.Mark().column + 1};
  b.name = m.has("name") ? text(ctx, m.get("name"), "body name") : "body" + std::to_string(index);
  if (m.has("kind")) {
    const std::string k = oneOf(ctx, m.get("kind"), "body kind", {"rigid", "deformable", "static"});
    b.kind = k == "rigid" ? BodyKind::Rigid : k == "deformable" ? BodyKind::Deformable : BodyKind::Static;
  }
  b.shape = shape(ctx, m.require("shape"), sceneDir);
  const bool isList = std::holds_alternative<ParticlesDesc>(b.shape);
  if (isList && m.has("fill"))
    ctx.fail(m.keyMark("fill"), "an explicit particle list takes no 'fill'; radii and reach go under 'particles'");
  if (!isList) b.fill = fill(ctx, m.require("fill"));
  if (m.has("normals")) {
    const YAML::Node nn = m.get("normals");
    b.normals = surfaceNormals(ctx, nn);
    if (isList && b.normals == SurfaceNormals::Shape)
      ctx.fail(nn.Mark(), "an explicit particle list has no solid to take normals from; expected 'normals: estimated' "
                          "(its default) or no 'normals'");
  }
  if (m.has("mass_properties"))
    b.massModel = oneOf(ctx, m.get("mass_properties"), "mass_properties", {"solid", "particles"}) == "particles"
                      ? MassModel::Particles
                      : MassModel::Solid;
  if (m.has("connectors")) b.connectors = connectors(ctx, m.get("connectors"), b.kind);
  else if (b.kind == BodyKind::Deformable)
    ctx.fail(m.mark(), "missing key 'connectors' in body '" + b.name + "'; a deformable body needs {springs: {...}} or rods");
  if (m.has("material")) b.material = text(ctx, m.get("material"), "material");
  if (m.has("mass") && m.has("particle_mass")) ctx.fail(m.mark(), "expected at most one of 'mass' or 'particle_mass'");
  if (m.has("mass")) b.mass = positive(ctx, m.get("mass"), "body mass", "kg");
  if (m.has("particle_mass")) b.particleMass = positive(ctx, m.get("particle_mass"), "particle mass", "kg");
  if (m.has("position")) b.position = vec3(ctx, m.get("position"), "position");
  if (m.has("orientation")) b.orientation = orientation(ctx, m.get("orientation"));
  if (m.has("velocity")) b.velocity = vec3(ctx, m.get("velocity"), "velocity", kMaxSpeed, "m/s");
  if (m.has("angular_velocity"))
    b.angularVelocity = vec3(ctx, m.get("angular_velocity"), "angular velocity", kMaxSpeed, "rad/s");
  if (m.has("repeat")) b.repeat = repeat(ctx, m.get("repeat"));
  if (m.has("pin")) {
    if (b.kind != BodyKind::Deformable) ctx.fail(m.keyMark("pin"), "only deformable bodies can have pinned particles");
    auto box = [&](const YAML::Node& node) {
      const MapReader pm(ctx, node, "pin", {"min", "max"});
      const YAML::Node hi = pm.require("max");
      const Vec3 lo = vec3(ctx, pm.require("min"), "pin min"), up = vec3(ctx, hi, "pin max");
      if (!(lo.array() <= up.array()).all()) ctx.fail(hi.Mark(), "expected pin max >= pin min in every coordinate");
      b.pins.emplace_back(lo, up);
      b.pinMarks.push_back({node.Mark().line + 1, node.Mark().column + 1});
    };
    const YAML::Node pins = m.get("pin");
    if (pins.IsSequence()) {
      for (const auto& node : pins) box(node);
    } else {
      box(pins);
    }
  }
  if (b.kind == BodyKind::Static && (b.velocity.norm() > 0.0 || b.angularVelocity.norm() > 0.0))
    ctx.fail(m.mark(), "a static body cannot have a velocity");
  return b;
}

GlueDesc glue(const Ctx& ctx, const YAML::Node& n, std::size_t index) {
  const MapReader m(ctx, n, "glue", {"name", "bodies", "pairs", "material", "reach", "radius"});
  GlueDesc g;
  g.mark = {n.Mark().line + 1, n.Mark().column + 1};
  g.name = m.has("name") ? text(ctx, m.get("name"), "glue name") : "glued" + std::to_string(index);
  if (m.has("bodies") == m.has("pairs")) ctx.fail(m.mark(), "expected exactly one of 'bodies' (all their touching pairs) or 'pairs' in glue");
  auto name = [&](const YAML::Node& v, std::vector<std::string>& into, std::vector<SourceMark>& marks) {
    into.push_back(text(ctx, v, "body name"));
    marks.push_back({v.Mark().line + 1, v.Mark().column + 1});
  };
  if (m.has("bodies")) {
    const YAML::Node list = m.get("bodies");
    if (!list.IsSequence() || list.size() == 0) ctx.fail(list.Mark(), "expected a list of body names to glue, got " + describe(list));
    for (const auto& v : list) name(v, g.bodies, g.bodyMarks);
  } else {
    const YAML::Node list = m.get("pairs");
    if (!list.IsSequence() || list.size() == 0) ctx.fail(list.Mark(), "expected a list of body name pairs [[a, b], ...], got " + describe(list));
    for (const auto& pair : list) {
      if (!pair.IsSequence() || pair.size() != 2) ctx.fail(pair.Mark(), "expected a pair of body names [a, b], got " + describe(pair));
      std::vector<std::string> two;
      std::vector<SourceMark> marks;
      name(pair[0], two, marks);
      name(pair[1], two, marks);
      g.pairs.push_back({two[0], two[1]});
      g.pairMarks.push_back(marks[0]);
    }
  }
  if (m.has("material")) g.material = text(ctx, m.get("material"), "material");
  if (m.has("reach")) {
    const YAML::Node r = m.get("reach");
    g.reach = number(ctx, r, "reach");
    if (!(g.reach > 1.0 && g.reach <= 4.0))
      ctx.fail(r.Mark(), "expected reach in (1, 4] times the two particles' radii summed (touching particles sit at 1), got " + r.Scalar());
  }
  if (m.has("radius")) {
    const YAML::Node r = m.get("radius");
    g.radius = number(ctx, r, "bond radius");
    if (!(g.radius > 0.0 && g.radius <= 1.0))
      ctx.fail(r.Mark(), "expected a bond radius in (0, 1] (a fraction of the smaller particle radius), got " + r.Scalar());
  }
  return g;
}

SceneDesc scene(const Ctx& ctx, const YAML::Node& root, const std::filesystem::path& sceneDir) {
  const MapReader m(ctx, root, "scene",
                    {"name", "dt", "steps", "duration", "gravity", "solver", "output", "materials", "planes",
                     "bodies", "allow_initial_overlap", "normals", "glue", "seed"});
  SceneDesc s;
  s.materials["default"] = Material{"default"};
  if (m.has("name")) s.name = text(ctx, m.get("name"), "scene name");
  const YAML::Node dt = m.require("dt");
  s.dt = positive(ctx, dt, "time step dt", "s");
  if (s.dt > 1.0) ctx.fail(dt.Mark(), "expected a time step dt of at most 1 s, got " + dt.Scalar());
  if (m.has("steps") == m.has("duration"))
    ctx.fail(m.mark(), "expected exactly one of 'steps' or 'duration' [s] in scene");
  if (m.has("steps")) s.steps = integer(ctx, m.get("steps"), "steps", 1, 1000000000000);
  if (m.has("duration")) {
    const YAML::Node d = m.get("duration");
    s.duration = positive(ctx, d, "duration", "s");
    if (*s.duration / s.dt > 1e12) ctx.fail(d.Mark(), "duration / dt exceeds 1e12 steps");
  }
  if (m.has("gravity")) s.gravity = vec3(ctx, m.get("gravity"), "gravity", kMaxSpeed, "m/s^2");
  if (m.has("solver")) {
    const MapReader sm(ctx, m.get("solver"), "solver", {"iterations", "substeps", "raw_normals"});
    if (sm.has("raw_normals")) s.rawNormals = boolean(ctx, sm.get("raw_normals"), "raw_normals");
    if (sm.has("iterations")) s.solverIterations = static_cast<int>(integer(ctx, sm.get("iterations"), "solver iterations", 1, 1000));
    if (sm.has("substeps")) s.substeps = static_cast<int>(integer(ctx, sm.get("substeps"), "substeps", 1, 1000));
  }
  if (m.has("output")) {
    const MapReader om(ctx, m.get("output"), "output", {"every"});
    if (om.has("every")) s.outputEvery = static_cast<int>(integer(ctx, om.get("every"), "output every", 1, 1000000000));
  }
  if (m.has("normals")) s.normals = surfaceNormals(ctx, m.get("normals"));
  if (m.has("seed")) s.seed = static_cast<std::uint64_t>(integer(ctx, m.get("seed"), "seed", 0, 9007199254740992));
  if (m.has("allow_initial_overlap")) s.allowInitialOverlap = boolean(ctx, m.get("allow_initial_overlap"), "allow_initial_overlap");
  if (m.has("materials")) {
    const YAML::Node mats = m.get("materials");
    if (!mats.IsMap()) ctx.fail(mats.Mark(), "expected a map of materials {name: {density, restitution, friction, rolling_resistance, rod_strength, rod_compressive_strength, strain_limit, youngs_modulus, poisson_ratio, tensile_strength, shear_strength, weibull_modulus}}");
    std::set<std::string> seen;
    for (auto it = mats.begin(); it != mats.end(); ++it) {
      const std::string name = text(ctx, it->first, "material name");
      if (!seen.insert(name).second) ctx.fail(it->first.Mark(), "duplicate material '" + name + "'");
      s.materials[name] = material(ctx, it->second, name);
    }
  }
  auto checkMaterial = [&](const std::string& name, const YAML::Node& where) {
    if (s.materials.contains(name)) return;
    std::vector<std::string> names;
    for (const auto& [k, v] : s.materials) names.push_back(k);
    ctx.fail(where.Mark(), "unknown material '" + name + "'" + suggestion(name, names) + "; expected one of: " + joinKeys(names));
  };
  if (m.has("planes")) {
    const YAML::Node planes = m.get("planes");
    if (!planes.IsSequence()) ctx.fail(planes.Mark(), "expected a list of planes");
    for (const auto& p : planes) {
      s.planes.push_back(plane(ctx, p));
      if (p.IsMap() && p["material"]) checkMaterial(s.planes.back().material, p["material"]);
    }
  }
  const YAML::Node bodies = m.require("bodies");
  if (!bodies.IsSequence() || bodies.size() == 0) ctx.fail(bodies.Mark(), "expected a non-empty list of bodies");
  std::set<std::string> names;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    s.bodies.push_back(body(ctx, bodies[i], i, sceneDir));
    if (bodies[i]["material"]) checkMaterial(s.bodies.back().material, bodies[i]["material"]);
    if (!names.insert(s.bodies.back().name).second)
      ctx.fail(bodies[i].Mark(), "duplicate body name '" + s.bodies.back().name + "'");
  }
  if (m.has("glue")) {
    const YAML::Node list = m.get("glue");
    if (!list.IsSequence() || list.size() == 0) ctx.fail(list.Mark(), "expected a list of glues [{bodies: [...], material: ...}]");
    for (std::size_t i = 0; i < list.size(); ++i) {
      s.glue.push_back(glue(ctx, list[i], i));
      if (list[i]["material"]) checkMaterial(s.glue.back().material, list[i]["material"]);
      if (!names.insert(s.glue.back().name).second)
        ctx.fail(list[i].Mark(), "duplicate body name '" + s.glue.back().name + "' (a glue names the body it makes)");
    }
  }
  return s;
}

}  // namespace

std::int64_t SceneDesc::stepCount() const {
  if (steps) return *steps;
  if (duration) return std::max<std::int64_t>(1, static_cast<std::int64_t>(std::llround(*duration / dt)));
  return 0;
}

SurfaceNormals SceneDesc::normalsOf(const BodyDesc& body) const {
  if (std::holds_alternative<ParticlesDesc>(body.shape)) return SurfaceNormals::Estimated;
  return body.normals.value_or(normals);
}

Result<SceneDesc> parseScene(const std::string& sceneText, const std::string& path, const LoadOptions& options) {
  namespace fs = std::filesystem;
  std::vector<fs::path> roots;
  for (const std::string& dir : options.allowedDirs) {
    std::error_code ec;
    const fs::path r = fs::canonical(fs::path(dir.empty() ? "." : dir), ec);
    if (!ec) roots.push_back(r);
  }
  {
    std::error_code ec;
    const fs::path own = fs::path(path).parent_path();
    const fs::path r = fs::canonical(own.empty() ? fs::path(".") : own, ec);
    if (!ec) roots.push_back(r);
  }
  const Ctx ctx(path, std::move(roots));
  if (auto bad = notUtf8(sceneText, path)) return *bad;
  if (auto deep = tooDeep(sceneText, path)) return *deep;
  try {
    YAML::Node root;
    try {
      root = YAML::Load(sceneText);
    } catch (const YAML::ParserException& e) {
      ctx.fail(e.mark, "invalid YAML: " + e.msg);
    }
    if (!root.IsDefined() || root.IsNull()) return Error{path, 1, 1, "the scene is empty; expected a map with dt, steps or duration, and bodies"};
    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    SceneDesc s = scene(ctx, root, dir);
    s.path = path;
    s.text = sceneText;
    if (s.name.empty()) s.name = std::filesystem::path(path).stem().string();
    return s;
  } catch (const LoadError& e) {
    return e.error;
  } catch (const YAML::Exception& e) {
    return Error{path, e.mark.is_null() ? 0 : e.mark.line + 1, e.mark.is_null() ? 0 : e.mark.column + 1, e.msg};
  }
}

Result<SceneDesc> loadScene(const std::string& path, const LoadOptions& options) {
  auto text = readInputFile(path, kMaxSceneFileBytes, "scene file");
  if (!text) return text.error();
  return parseScene(*text, path, options);
}

}  // namespace volpar
