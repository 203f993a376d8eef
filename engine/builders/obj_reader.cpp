#include "volpar/engine/builders/obj_reader.hpp"

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>

#include "volpar/engine/core/input_file.hpp"
#include "volpar/engine/core/limits.hpp"

namespace volpar {

namespace {

struct Token {
  std::string_view text;
  int column;  // 1-based
};

std::vector<Token> tokenize(std::string_view line) {
  std::vector<Token> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    if (i >= line.size() || line[i] == '#') break;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r' && line[i] != '#') ++i;
    out.push_back({line.substr(start, i - start), static_cast<int>(start) + 1});
  }
  return out;
}

bool parseDouble(std::string_view s, double& out) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size() && std::isfinite(out);
}

bool parseInt(std::string_view s, long& out) {
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && ptr == s.data() + s.size();
}

struct FaceRef {
  long index;
  int line;
  int column;
};

}  // namespace

Result<TriangleMesh> parseObj(const std::string& text, const std::string& source, double scale) {
  auto fail = [&](int line, int column, const std::string& message) -> Error {
    return Error{source, line, column, message};
  };
  std::vector<Vec3> raw;
  std::vector<std::array<FaceRef, 3>> faces;
  std::istringstream in(text);
  std::string line;
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    const auto tokens = tokenize(line);
    if (tokens.empty()) continue;
    const std::string_view key = tokens[0].text;
    if (key == "v") {
      if (tokens.size() != 4 && tokens.size() != 5)
        return fail(lineNo, tokens[0].column, "expected a vertex 'v x y z' with 3 coordinates");
      Vec3 v;
      for (int k = 0; k < 3; ++k) {
        if (!parseDouble(tokens[1 + k].text, v[k]))
          return fail(lineNo, tokens[1 + k].column, "expected a finite number for a vertex coordinate");
        if (!(std::abs(v[k] * scale) <= kMaxLength))
          return fail(lineNo, tokens[1 + k].column,
                      "vertex coordinate (times the scale " + std::to_string(scale) + ") beyond " +
                          std::to_string(static_cast<long long>(kMaxLength)) + " m; expected coordinates within it");
      }
      raw.push_back(v * scale);
    } else if (key == "f") {
      if (tokens.size() < 4) return fail(lineNo, tokens[0].column, "expected a face with at least 3 vertices");
      std::vector<FaceRef> refs;
      for (std::size_t k = 1; k < tokens.size(); ++k) {
        const std::string_view t = tokens[k].text;
        const std::string_view first = t.substr(0, t.find('/'));
        long idx = 0;
        if (!parseInt(first, idx) || idx == 0)
          return fail(lineNo, tokens[k].column, "expected a vertex index (non-zero integer, optionally '/texture/normal')");
        // negative indices count back from the vertices read so far
        if (idx < 0) idx = static_cast<long>(raw.size()) + idx + 1;
        if (idx < 1) return fail(lineNo, tokens[k].column, "relative vertex index points before the first vertex");
        refs.push_back({idx, lineNo, tokens[k].column});
      }
      for (std::size_t k = 1; k + 1 < refs.size(); ++k) faces.push_back({refs[0], refs[k], refs[k + 1]});
    } else if (key == "vn" || key == "vt" || key == "vp" || key == "o" || key == "g" || key == "s" || key == "l" ||
               key == "usemtl" || key == "mtllib") {
      continue;
    } else {
      // (what the line holds is not repeated: a file that is not a mesh may be anything)
      return fail(lineNo, tokens[0].column,
                  "not an OBJ statement; expected v or f (vn, vt, vp, o, g, s, l, usemtl and mtllib are ignored)");
    }
  }
  if (faces.empty()) return fail(0, 0, "no faces found; expected a closed triangle mesh ('f' statements)");

  // weld vertices with identical coordinates
  TriangleMesh mesh;
  mesh.source = source;
  std::map<std::array<double, 3>, std::uint32_t> weld;
  std::vector<std::uint32_t> remap(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    const std::array<double, 3> key{raw[i].x(), raw[i].y(), raw[i].z()};
    const auto [it, inserted] = weld.emplace(key, static_cast<std::uint32_t>(mesh.vertices.size()));
    if (inserted) {
      mesh.vertices.push_back(raw[i]);
      mesh.vertexNumber.push_back(static_cast<int>(i) + 1);
    }
    remap[i] = it->second;
  }
  for (const auto& f : faces) {
    std::array<std::uint32_t, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      if (f[k].index > static_cast<long>(raw.size()))
        return fail(f[k].line, f[k].column,
                    "vertex index " + std::to_string(f[k].index) + " is out of range; the file has " +
                        std::to_string(raw.size()) + " vertices");
      tri[k] = remap[static_cast<std::size_t>(f[k].index - 1)];
    }
    mesh.triangles.push_back(tri);
    mesh.triangleLine.push_back(f[0].line);
  }
  return mesh;
}

Result<TriangleMesh> readObj(const std::string& path, double scale) {
  auto text = readInputFile(path, kMaxMeshFileBytes, "mesh file");
  if (!text) return text.error();
  return parseObj(*text, path, scale);
}

}  // namespace volpar
