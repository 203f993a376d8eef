// Every scene file in scenes/ loads, builds and runs; the same scene run twice, or with more worker
// threads, gives bit-identical trajectories.

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "volpar/engine/io/h5md_reader.hpp"
#include "volpar/engine/run_loop.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

std::vector<std::string> sceneFiles() {
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::recursive_directory_iterator(test::sourcePath("scenes")))
    if (e.path().extension() == ".yaml") files.push_back(std::filesystem::relative(e.path(), test::sourcePath("scenes")).string());
  std::sort(files.begin(), files.end());
  return files;
}

/// A test name from a scene path: every character other than a letter or digit becomes '_'.
std::string paramName(const ::testing::TestParamInfo<std::string>& info) {
  std::string name = info.param;
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return name;
}

/// Two trajectory files with the same frames: the same count (more than `minFrames`) and the same
/// particle positions in each.
void expectSameFrames(const std::string& a, const std::string& b, std::size_t minFrames) {
  auto ra = H5mdReader::open(a);
  auto rb = H5mdReader::open(b);
  ASSERT_TRUE(ra.ok() && rb.ok());
  const std::size_t frames = (*ra)->summary()->frames;
  ASSERT_EQ(frames, (*rb)->summary()->frames);
  ASSERT_GT(frames, minFrames);
  for (std::size_t t = 0; t < frames; ++t) EXPECT_EQ((*ra)->positions(t).value(), (*rb)->positions(t).value());
}

class EveryScene : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryScene, LoadsBuildsAndRuns) {
  const std::string path = test::sourcePath("scenes/" + GetParam());
  auto desc = loadScene(path);
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto built = buildScene(*desc);
  ASSERT_TRUE(built.ok()) << built.error().toString();
  World& w = built->world;
  EXPECT_GT(w.particles().size(), 0u);
  // (the scenes of fracture at scale take seconds a step here: a few steps before their impacts show that
  // they build and run; tools/scripts/fracture_cost.py times them in a Release build, docs/fracture.md)
  std::int64_t steps = std::min<std::int64_t>(desc->stepCount(), 120);
  if (GetParam() == "examples/wall_break_fine.yaml") steps = 5;
  if (GetParam() == "examples/slab_impact.yaml") steps = 1;
  for (std::int64_t i = 0; i < steps; ++i) ASSERT_EQ(w.step(), StepStatus::Ok) << "step " << i;
}

INSTANTIATE_TEST_SUITE_P(Scenes, EveryScene, ::testing::ValuesIn(sceneFiles()), paramName);

std::string readBytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

TEST(Determinism, SameSceneTwiceGivesIdenticalTrajectoryFiles) {
  const std::string dir = test::tempDir();
  const std::string scene = test::sourcePath("scenes/examples/demo.yaml");
  for (const char* name : {"a.h5", "b.h5"}) {
    const auto r = test::runCommand(test::volparBinary() + " run " + scene + " --steps 200 -o " + dir + "/" + name);
    ASSERT_EQ(r.exitCode, 0) << r.output;
  }
  const std::string a = readBytes(dir + "/a.h5"), b = readBytes(dir + "/b.h5");
  ASSERT_GT(a.size(), 10000u);
  EXPECT_TRUE(a == b) << "trajectory files differ";
  // and the data itself, frame by frame
  expectSameFrames(dir + "/a.h5", dir + "/b.h5", 10);
}

// The threaded step computes exactly what the single-threaded one does: every particle's position and
// velocity, bit for bit, at every step, for rigid piles, deformables and bodies that break apart. (These
// scenes are small: the two-thread world shares all work so that every threaded path runs.)
class ThreadedStep : public ::testing::TestWithParam<std::string> {};

TEST_P(ThreadedStep, GivesBitIdenticalStates) {
  const std::string path = test::sourcePath("scenes/" + GetParam());
  auto desc = loadScene(path);
  ASSERT_TRUE(desc.ok()) << desc.error().toString();
  auto one = buildScene(*desc);
  auto two = buildScene(*desc);
  auto three = buildScene(*desc);
  ASSERT_TRUE(one.ok() && two.ok() && three.ok());
  two->world.setThreads(2, /*shareAll=*/true);  // every stage threaded, however small
  three->world.setThreads(3);                    // threaded where the work is large enough
  const std::int64_t steps = std::min<std::int64_t>(desc->stepCount(), 240);
  std::size_t patches = 0;
  for (std::int64_t i = 0; i < steps; ++i) {
    ASSERT_EQ(one->world.step(), StepStatus::Ok);
    ASSERT_EQ(two->world.step(), StepStatus::Ok);
    ASSERT_EQ(three->world.step(), StepStatus::Ok);
    patches += one->world.stats().patches;
    for (const World* w : {&two->world, &three->world}) {
      ASSERT_EQ(w->particles().size(), one->world.particles().size()) << "step " << i;
      ASSERT_TRUE(w->particles().position == one->world.particles().position) << "positions differ at step " << i;
      ASSERT_TRUE(w->particles().velocity == one->world.particles().velocity) << "velocities differ at step " << i;
      ASSERT_EQ(w->bodies().size(), one->world.bodies().size()) << "step " << i;
    }
  }
  EXPECT_GT(patches, 0u) << "the scene never touched anything: nothing of the threaded paths was compared";
}

INSTANTIATE_TEST_SUITE_P(Scenes, ThreadedStep,
                         ::testing::Values("bench/pile-125.yaml", "examples/wall_break.yaml", "examples/jelly.yaml",
                                           "examples/peg_in_slot.yaml", "examples/bridge.yaml", "examples/heavy_stacks.yaml",
                                           "examples/brick_wall.yaml"),
                         paramName);

TEST(Determinism, ThreadedRunWritesTheSameTrajectory) {
  const std::string dir = test::tempDir();
  const std::string scene = test::sourcePath("scenes/bench/pile-125.yaml");
  for (const char* threads : {"1", "2"}) {
    const auto r = test::runCommand(test::volparBinary() + " run " + scene + " --steps 240 --threads " + threads +
                                    " -o " + dir + "/t" + threads + ".h5");
    ASSERT_EQ(r.exitCode, 0) << r.output;
    // (the runs over a second apart: a time HDF5 recorded in the file would differ)
    if (threads[0] == '1') std::this_thread::sleep_for(std::chrono::milliseconds(1100));
  }
  expectSameFrames(dir + "/t1.h5", dir + "/t2.h5", 2);
  EXPECT_TRUE(readBytes(dir + "/t1.h5") == readBytes(dir + "/t2.h5")) << "trajectory files differ";
}

}  // namespace
}  // namespace volpar
