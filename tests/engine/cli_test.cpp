// The volpar command line: exit codes, error messages, --json, inspect, and that a bad scene never
// touches an existing output file.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

std::string writeFile(const std::string& path, const std::string& text) {
  std::ofstream(path) << text;
  return path;
}

const char* kFall = R"(
name: fall
dt: 0.01
steps: 50
output: {every: 10}
bodies:
  - shape: {sphere: {radius: 0.2}}
    fill: {radius: 0.05}
    position: [0, 0, 10]
)";

TEST(Cli, RunWritesTrajectoryAndJsonSummary) {
  const std::string dir = test::tempDir();
  const std::string scene = writeFile(dir + "/fall.yaml", kFall);
  const auto r = test::runCommand(test::volparBinary() + " run " + scene + " -o " + dir + "/fall.h5 --json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  for (const char* key : {"\"steps\": 50", "\"frames\": 6", "\"bodies\": 1", "\"particles\": ", "\"wall_seconds\": ",
                          "\"steps_per_second\": "})
    EXPECT_NE(r.output.find(key), std::string::npos) << key << "\n" << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir + "/fall.h5"));
  EXPECT_TRUE(std::filesystem::exists(dir + "/fall.xdmf2"));

  const auto inspect = test::runCommand(test::volparBinary() + " inspect " + dir + "/fall.h5 --json");
  ASSERT_EQ(inspect.exitCode, 0) << inspect.output;
  EXPECT_NE(inspect.output.find("\"frames\": 6"), std::string::npos) << inspect.output;
  EXPECT_NE(inspect.output.find("\"scene\": \"fall\""), std::string::npos) << inspect.output;
}

TEST(Cli, OverridesStepsAndCadence) {
  const std::string dir = test::tempDir();
  const std::string scene = writeFile(dir + "/fall.yaml", kFall);
  const auto r = test::runCommand(test::volparBinary() + " run " + scene + " -o " + dir + "/o.h5 --steps 7 --every 3 --json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("\"steps\": 7"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"frames\": 4"), std::string::npos) << r.output;  // steps 0, 3, 6 and the final 7
  const auto both = test::runCommand(test::volparBinary() + " run " + scene + " --steps 7 --duration 1");
  EXPECT_NE(both.exitCode, 0);
  EXPECT_NE(both.output.find("excludes"), std::string::npos) << both.output;
}

TEST(Cli, ThreadsAreReportedAndOutOfRangeCountsRejected) {
  const std::string dir = test::tempDir();
  const std::string scene = writeFile(dir + "/fall.yaml", kFall);
  const auto r = test::runCommand(test::volparBinary() + " run " + scene + " -o " + dir + "/t.h5 --threads 2 --json");
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("\"threads\": 2"), std::string::npos) << r.output;
  const std::string out = writeFile(dir + "/keep.h5", "precious");
  for (const char* bad : {"0", "-1", "1000", "two"}) {
    const auto b = test::runCommand(test::volparBinary() + " run " + scene + " -o " + out + " --threads " + bad);
    EXPECT_NE(b.exitCode, 0) << bad;
    EXPECT_NE(b.output.find("--threads"), std::string::npos) << bad << "\n" << b.output;
  }
  std::ifstream in(out);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "precious");
}

TEST(Cli, BadSceneFailsWithLocationAndKeepsExistingOutput) {
  const std::string dir = test::tempDir();
  const std::string scene = writeFile(dir + "/bad.yaml", "dt: 0.01\nsteps: 5\nbodies:\n  - shape: {sphere: {radius: -1}}\n    fill: {radius: 0.1}\n");
  const std::string out = writeFile(dir + "/keep.h5", "precious");
  const auto r = test::runCommand(test::volparBinary() + " run " + scene + " -o " + out);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.output.find(scene + ":4:30: expected a positive sphere radius [m], got -1"), std::string::npos) << r.output;
  std::ifstream in(out);
  std::string content;
  std::getline(in, content);
  EXPECT_EQ(content, "precious");
}

TEST(Cli, MissingSceneAndHelp) {
  const auto missing = test::runCommand(test::volparBinary() + " run /nonexistent.yaml");
  EXPECT_NE(missing.exitCode, 0);
  EXPECT_NE(missing.output.find("/nonexistent.yaml"), std::string::npos) << missing.output;
  for (const char* cmd : {" --help", " run --help", " inspect --help", " xdmf --help"}) {
    const auto help = test::runCommand(test::volparBinary() + cmd);
    EXPECT_EQ(help.exitCode, 0) << cmd;
    EXPECT_NE(help.output.find("Usage"), std::string::npos) << help.output;
  }
}

TEST(Cli, InspectRejectsFilesThatAreNotTrajectories) {
  const std::string dir = test::tempDir();
  const std::string notH5 = writeFile(dir + "/x.h5", "not hdf5");
  const auto r = test::runCommand(test::volparBinary() + " inspect " + notH5);
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_NE(r.output.find("not an HDF5 file"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace volpar
