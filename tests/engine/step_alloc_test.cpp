// A step allocates nothing once the world's buffers have grown to the scene's needs. A program of its own:
// it counts every allocation (allocation_counter.hpp), here those made while a step runs.
#include <gtest/gtest.h>

#include <vector>

#include "tests/support/allocation_counter.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"

namespace volpar {
namespace {

// pile-125 settling after its collapse, on one thread and on two: its pairs still come and go and their
// planes are solved afresh every step, but the buffers that hold them have nearly reached their size, so a
// step allocates only where a buffer grows past its largest yet (amortised: rarely), never per patch, pair
// or point.
TEST(Step, AllocatesNothingOnceItsBuffersHaveGrown) {
  for (const int threads : {1, 2}) {
    auto desc = loadScene(VOLPAR_SOURCE_DIR "/scenes/bench/pile-125.yaml");
    ASSERT_TRUE(desc.ok()) << desc.error().toString();
    auto built = buildScene(*desc);
    ASSERT_TRUE(built.ok()) << built.error().toString();
    World& world = built->world;
    if (threads > 1) world.setThreads(threads, /*shareAll=*/true);
    for (int i = 0; i < 400; ++i) world.step();
    constexpr int kSteps = 200;
    std::vector<long> perStep(kSteps, 0);
    std::size_t fresh = 0;
    for (int i = 0; i < kSteps; ++i) {
      const long before = test::allocationCount();
      world.step();
      perStep[static_cast<std::size_t>(i)] = test::allocationCount() - before;
      fresh += world.stats().patches - world.stats().patchesReused;
    }
    long total = 0;
    int allocating = 0;
    for (const long n : perStep) {
      total += n;
      allocating += n > 0 ? 1 : 0;
    }
    // (the steps must have planes to solve, or they would prove nothing about the narrow phase; a buffer
    // that grows is amortised over them, so allocations stay far fewer than the patches solved afresh)
    EXPECT_GT(fresh, 1000u) << threads << " thread(s)";
    EXPECT_LT(static_cast<double>(total), 0.1 * static_cast<double>(fresh))
        << threads << " thread(s): " << total << " allocations in " << allocating << " of " << kSteps << " steps, "
        << fresh << " patches solved afresh";
  }
}

}  // namespace
}  // namespace volpar
