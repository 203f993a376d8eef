#include "tests/support/test_support.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <random>

namespace volpar::test {

std::string sourcePath(const std::string& relative) { return std::string(VOLPAR_SOURCE_DIR) + "/" + relative; }

std::string tempDir() {
  static std::mt19937_64 rng(std::random_device{}());
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "_" + info->name() : "volpar";
  for (char& c : name)
    if (c == '/') c = '_';
  const auto dir = std::filesystem::temp_directory_path() / ("volpar_" + name + "_" + std::to_string(rng() % 1000000));
  std::filesystem::create_directories(dir);
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

}  // namespace volpar::test
