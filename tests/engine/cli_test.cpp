// The volpar command line: exit codes, error messages, --json, inspect, and that a bad scene never
// touches an existing output file.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

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

TEST(Cli, SeedOverridesTheScenesAndIsRecorded) {
  // the plate's bonds have Weibull strengths drawn with the seed (the scene's is 1)
  const std::string dir = test::tempDir();
  const std::string scene = test::sourcePath("scenes/examples/plate_impact.yaml");
  auto broken = [&](const std::string& extra, const std::string& name) {
    const auto r = test::runCommand(test::volparBinary() + " run " + scene + " --steps 150 --json -o " + dir + "/" + name + extra);
    EXPECT_EQ(r.exitCode, 0) << r.output;
    const std::size_t at = r.output.find("\"connectors_broken\": ");
    EXPECT_NE(at, std::string::npos) << r.output;
    return at == std::string::npos ? -1L : std::stol(r.output.substr(at + 21));
  };
  const long scene1 = broken("", "a.h5"), seed1 = broken(" --seed 1", "b.h5"), seed2 = broken(" --seed 2", "c.h5");
  EXPECT_GT(scene1, 0);
  EXPECT_EQ(seed1, scene1);
  EXPECT_NE(seed2, scene1);
  const auto h5 = test::runCommand("h5dump -a /parameters/seed " + dir + "/c.h5");
  EXPECT_NE(h5.output.find("(0): 2"), std::string::npos) << h5.output;
  const auto bad = test::runCommand(test::volparBinary() + " run " + scene + " --seed -3 --no-output");
  EXPECT_EQ(bad.exitCode, 1) << bad.output;
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
    EXPECT_EQ(b.exitCode, 1) << bad;
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
  EXPECT_EQ(missing.exitCode, 1);
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

// Every option is checked for its type and range (no overflow taken for a huge count, no NaN or infinity, no
// duration that rounds to one step or to more steps than a run may have); every command-line error exits
// with status 1 and names the option and what it expected.
TEST(Cli, OptionErrorsNameTheOptionAndExitWithOne) {
  const std::string dir = test::tempDir();
  const std::string scene = writeFile(dir + "/fall.yaml", kFall);
  struct Case {
    const char* args;
    const char* says;
  };
  const Case cases[] = {
      {"--steps 99999999999999999999", "--steps: expected a whole number from 1 to 1000000000000"},
      {"--steps 0", "--steps: expected a whole number from 1"},
      {"--steps -3", "--steps: expected a whole number from 1"},
      {"--steps 1e3", "--steps: expected a whole number, got 1e3"},
      {"--steps 2.5", "--steps: expected a whole number, got 2.5"},
      {"--duration nan", "--duration: expected a finite number above 0, got nan"},
      {"--duration inf", "--duration: expected a finite number above 0, got inf"},
      {"--duration -1", "--duration: expected a finite number above 0, got -1"},
      {"--duration 0", "--duration: expected a finite number above 0, got 0"},
      {"--duration 1e300", "expected at most 1000000000000 steps"},
      {"--every 0", "--every: expected a whole number from 1"},
      {"--every 4294967296", "--every: expected a whole number from 1 to 2147483647"},
      {"--threads 1.5", "--threads: expected a whole number"},
      {"--bogus", "--bogus"},
  };
  for (const Case& c : cases) {
    const auto r = test::runCommand(test::volparBinary() + " run " + scene + " --no-output " + c.args);
    EXPECT_EQ(r.exitCode, 1) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << c.args << "\n" << r.output;
  }
  const auto check = test::runCommand(test::volparBinary() + " check " + scene + " --duration nan");
  EXPECT_EQ(check.exitCode, 1) << check.output;
  const auto details = test::runCommand(test::volparBinary() + " check " + scene + " --details -1");
  EXPECT_EQ(details.exitCode, 1) << details.output;
  const auto none = test::runCommand(test::volparBinary());
  EXPECT_EQ(none.exitCode, 1) << none.output;
  EXPECT_NE(none.output.find("subcommand"), std::string::npos) << none.output;
  const auto unknown = test::runCommand(test::volparBinary() + " frobnicate");
  EXPECT_EQ(unknown.exitCode, 1) << unknown.output;
}

// The trajectory is never written over the run's inputs: the scene (by name, by another path to it or by a
// link) or a mesh it reads; nor over a folder. Each is refused before the run, with status 1.
TEST(Cli, OutputOverAnInputIsRefused) {
  const std::string dir = test::tempDir();
  std::filesystem::create_directories(dir + "/meshes");
  std::filesystem::copy_file(test::sourcePath("scenes/examples/meshes/l_shape.obj"), dir + "/meshes/l.obj");
  const std::string scene = writeFile(dir + "/s.yaml", std::string(kFall) +
                                                           "  - shape: {mesh: {file: meshes/l.obj}}\n"
                                                           "    fill: {radius: 0.1}\n    position: [5, 0, 0]\n");
  std::filesystem::create_symlink(dir + "/s.yaml", dir + "/link.yaml");
  const auto original = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  const std::string sceneText = original(scene), meshText = original(dir + "/meshes/l.obj");
  for (const std::string& out : {scene, dir + "/./s.yaml", dir + "/link.yaml", dir + "/meshes/l.obj", dir + "/meshes"}) {
    const auto r = test::runCommand(test::volparBinary() + " run " + scene + " --steps 2 -o " + out);
    EXPECT_EQ(r.exitCode, 1) << out << "\n" << r.output;
    const bool named = r.output.find("refusing to write over an input") != std::string::npos ||
                       r.output.find("the output is a folder") != std::string::npos;
    EXPECT_TRUE(named) << out << "\n" << r.output;
  }
  EXPECT_EQ(original(scene), sceneText);
  EXPECT_EQ(original(dir + "/meshes/l.obj"), meshText);
  EXPECT_TRUE(std::filesystem::is_directory(dir + "/meshes"));
}

}  // namespace
}  // namespace volpar
