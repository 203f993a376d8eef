#include "tests/support/test_support.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <system_error>
#include <vector>

namespace volpar::test {

std::string sourcePath(const std::string& relative) { return std::string(VOLPAR_SOURCE_DIR) + "/" + relative; }

namespace {

/// The folders tempDir() made in this process: removed when it exits, unless a test failed (they are then
/// kept to be looked at).
std::vector<std::filesystem::path>& madeDirs() {
  static std::vector<std::filesystem::path> dirs;
  static const bool registered = [] {
    return std::atexit([] {
      if (!::testing::UnitTest::GetInstance()->Passed()) return;
      std::error_code ignored;
      for (const auto& dir : madeDirs()) std::filesystem::remove_all(dir, ignored);
    }) == 0;
  }();
  (void)registered;
  return dirs;
}

}  // namespace

std::string tempDir() {
  static std::mt19937_64 rng(std::random_device{}());
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "volpar";
  for (char& c : name)
    if (c == '/') c = '_';
  const auto dir = std::filesystem::temp_directory_path() / ("volpar_" + name + "_" + std::to_string(rng() % 1000000));
  std::filesystem::create_directories(dir);
  madeDirs().push_back(dir);
  return dir.string();
}

Result<SceneDesc> sceneFromString(const std::string& text, const std::string& name) {
  // (scenes here may use the test meshes too)
  LoadOptions options;
  options.allowedDirs = {sourcePath("tests/data")};
  return parseScene(text, sourcePath("scenes/" + name), options);
}

World worldFromString(const std::string& text, const std::string& name) {
  auto desc = sceneFromString(text, name);
  if (!desc) {
    ADD_FAILURE() << desc.error().toString();
    return World(WorldSettings{});
  }
  auto built = buildScene(*desc);
  if (!built) {
    ADD_FAILURE() << built.error().toString();
    return World(WorldSettings{});
  }
  return std::move(built->world);
}

CommandResult runCommand(const std::string& command) {
  CommandResult r;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(pipe);
  r.exitCode = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string volparBinary() { return VOLPAR_BINARY; }

std::string exactNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string positionList(const std::vector<Vec3>& xs) {
  std::string s;
  for (const Vec3& x : xs)
    s += (s.empty() ? "[" : ", [") + exactNumber(x.x()) + ", " + exactNumber(x.y()) + ", " + exactNumber(x.z()) + "]";
  return s;
}

SourceShape meshSource(const TriangleMesh& mesh) {
  SourceShape s;
  s.kind = SourceShape::Kind::Mesh;
  s.facePlanes = mesh.convexFacePlanes();
  return s;
}

std::shared_ptr<TriangleMesh> turnedBoxMesh(const Quat& turn, const Vec3& half) {
  auto mesh = std::make_shared<TriangleMesh>();
  for (int i = 0; i < 8; ++i)
    mesh->vertices.push_back(turn * Vec3(i & 1 ? half.x() : -half.x(), i & 2 ? half.y() : -half.y(), i & 4 ? half.z() : -half.z()));
  const std::array<std::array<std::uint32_t, 4>, 6> faces{{{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}}};
  for (const auto& f : faces) {
    mesh->triangles.push_back({f[0], f[1], f[2]});
    mesh->triangles.push_back({f[0], f[2], f[3]});
  }
  return mesh;
}

}  // namespace volpar::test
