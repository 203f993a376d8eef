// Handing work to the thread pool allocates nothing. A program of its own: it counts every allocation
// (allocation_counter.hpp).
#include <gtest/gtest.h>

#include <vector>

#include "tests/support/allocation_counter.hpp"
#include "volpar/engine/core/thread_pool.hpp"

namespace volpar {
namespace {

TEST(ThreadPool, HandsOutWorkWithoutAllocating) {
  // the step hands out work many times per step and must not allocate: neither the pool nor the
  // references to the work it passes around may (work capturing several references would not fit in
  // std::function's small buffer)
  ThreadPool pool(2);
  std::vector<double> out(1000, 0.0);
  double scale = 2.0, offset = 1.0;
  const auto ranges = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) out[i] = scale * static_cast<double>(i) + offset;
  };
  const auto items = [&](int, std::size_t i) { out[i] += scale * offset; };
  const auto round = [&] {
    pool.run(out.size(), ranges);
    pool.runItems(out.size(), items);
    pool.runChunks(out.size(), ranges);
  };
  round();  // (anything made on first use is made here)
  const long before = test::allocationCount();
  for (int r = 0; r < 100; ++r) round();
  EXPECT_EQ(test::allocationCount() - before, 0);
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], 2.0 * static_cast<double>(i) + 1.0);
}

}  // namespace
}  // namespace volpar
