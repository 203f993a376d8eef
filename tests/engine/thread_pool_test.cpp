// The thread pool hands out every item exactly once, splits ranges as documented, and keeps working
// after its workers have gone to sleep.
#include "volpar/engine/core/thread_pool.hpp"
#include "volpar/engine/core/paced_split.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <chrono>
#include <numeric>
#include <thread>
#include <vector>

namespace volpar {
namespace {

TEST(ThreadPool, RunCoversEveryIndexOnceInContiguousOrderedRanges) {
  for (const int workers : {1, 2, 3}) {
    ThreadPool pool(workers);
    for (const std::size_t n : {1u, 2u, 5u, 1000u}) {
      std::vector<int> hits(n, 0);
      std::vector<std::size_t> begins(static_cast<std::size_t>(workers), n), ends(static_cast<std::size_t>(workers), n);
      pool.run(n, [&](int w, std::size_t begin, std::size_t end) {
        begins[static_cast<std::size_t>(w)] = begin;
        ends[static_cast<std::size_t>(w)] = end;
        for (std::size_t i = begin; i < end; ++i) ++hits[i];
      });
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i], 1) << "workers " << workers << ", n " << n << ", i " << i;
      // worker w's range is [n w / W, n (w + 1) / W)
      std::vector<std::size_t> bounds;
      pool.split(n, nullptr, bounds);
      for (std::size_t w = 0; w < static_cast<std::size_t>(workers); ++w) {
        EXPECT_EQ(bounds[w], n * w / static_cast<std::size_t>(workers));
        if (bounds[w] < bounds[w + 1]) {
          EXPECT_EQ(begins[w], bounds[w]);
          EXPECT_EQ(ends[w], bounds[w + 1]);
        }
      }
    }
  }
}

TEST(ThreadPool, WeightedSplitBalancesByCumulativeWeight) {
  ThreadPool pool(2);
  // one heavy item first: the first worker takes it alone
  const std::vector<std::size_t> weights{100, 1, 1, 1, 1, 1, 1, 1, 1, 1};
  std::vector<std::size_t> bounds;
  pool.split(weights.size(), &weights, bounds);
  ASSERT_EQ(bounds.size(), 3u);
  EXPECT_EQ(bounds[0], 0u);
  EXPECT_EQ(bounds[1], 1u);
  EXPECT_EQ(bounds[2], weights.size());
}

TEST(ThreadPool, RunItemsHandsOutEveryItemExactlyOnceWhateverItsCost) {
  for (const int workers : {1, 2, 4}) {
    ThreadPool pool(workers);
    const std::size_t n = 64;
    std::vector<std::atomic<int>> hits(n);
    std::vector<double> out(n, 0.0);
    pool.runItems(n, [&](int worker, std::size_t i) {
      ASSERT_GE(worker, 0);
      ASSERT_LT(worker, workers);
      hits[i].fetch_add(1);
      // uneven items: every eighth is long
      double x = static_cast<double>(i);
      for (int k = 0; k < (i % 8 == 0 ? 20000 : 10); ++k) x = x * 0.5 + 1.0;
      out[i] = x;
    });
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_EQ(hits[i].load(), 1) << "item " << i;
      EXPECT_GT(out[i], 0.0);
    }
  }
}

TEST(ThreadPool, RunChunksCoversEveryIndexOnceInConsecutiveRanges) {
  for (const int workers : {1, 2, 3}) {
    ThreadPool pool(workers);
    for (const std::size_t n : {1u, 7u, 16u, 1001u}) {
      std::vector<std::atomic<int>> hits(n);
      std::atomic<std::size_t> ranges{0};
      pool.runChunks(n, [&](int worker, std::size_t begin, std::size_t end) {
        ASSERT_GE(worker, 0);
        ASSERT_LT(worker, workers);
        ASSERT_LT(begin, end);
        ASSERT_LE(end, n);
        ranges.fetch_add(1);
        for (std::size_t i = begin; i < end; ++i) hits[i].fetch_add(1);
      });
      for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << "workers " << workers << ", n " << n << ", i " << i;
      // as many ranges as chunks per worker allow, never more than items
      EXPECT_EQ(ranges.load(), std::min(n, ThreadPool::kChunksPerWorker * static_cast<std::size_t>(workers)));
    }
  }
}

TEST(ThreadPool, WorkersWakeAfterSleepingAndResultsStayOrdered) {
  ThreadPool pool(2);
  std::vector<std::size_t> sums;
  for (int round = 0; round < 3; ++round) {
    // idle long enough for the workers to stop spinning and sleep
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::vector<std::size_t> partial(2, 0);
    pool.run(10000, [&](int w, std::size_t begin, std::size_t end) {
      for (std::size_t i = begin; i < end; ++i) partial[static_cast<std::size_t>(w)] += i;
    });
    sums.push_back(partial[0] + partial[1]);
  }
  for (const std::size_t s : sums) EXPECT_EQ(s, 10000u * 9999u / 2u);
}

TEST(SpinBarrier, NoThreadPassesBeforeAllArrive) {
  ThreadPool pool(3);
  SpinBarrier barrier;
  barrier.reset(3);
  std::atomic<int> arrived{0};
  std::vector<int> seenAfter(3, 0);
  pool.run(3, [&](int w, std::size_t, std::size_t) {
    for (int phase = 1; phase <= 50; ++phase) {
      arrived.fetch_add(1);
      barrier.wait();
      // everyone of this phase has arrived
      if (arrived.load() < 3 * phase) seenAfter[static_cast<std::size_t>(w)] = -1;
      barrier.wait();
    }
  });
  for (const int s : seenAfter) EXPECT_EQ(s, 0);
  EXPECT_EQ(arrived.load(), 150);
}

// The pieces of a PacedSplit are contiguous, in order, and cover every item once, whatever the number of
// items and wherever the boundaries have moved.
TEST(PacedSplit, PiecesCoverEveryItemOnceInOrder) {
  for (const int workers : {1, 2, 3, 5}) {
    PacedSplit split;
    const std::size_t pieces = PacedSplit::pieces(workers);
    for (int call = 0; call < 6; ++call) {
      for (const std::size_t n : {0u, 1u, 2u, 7u, 1000u}) {
        std::size_t next = 0;
        for (std::size_t p = 0; p < pieces; ++p) {
          const auto [begin, end] = split.piece(n, workers, p);
          ASSERT_EQ(begin, next) << "workers " << workers << ", n " << n << ", piece " << p;
          ASSERT_LE(begin, end);
          next = end;
        }
        ASSERT_EQ(next, n) << "workers " << workers << ", n " << n;
      }
      // uneven times move the boundaries for the next call
      for (std::size_t p = 0; p < pieces; ++p) split.record(p, 1e-3 * (1.0 + static_cast<double>(p * p) + call));
      split.adapt();
    }
  }
}

// Items whose cost varies along the range: the boundaries move until every worker's range costs the same.
TEST(PacedSplit, BoundariesFollowTheCostUntilTheRangesAreEven) {
  PacedSplit split;
  const int workers = 3;
  const std::size_t n = 6000, pieces = PacedSplit::pieces(workers);
  // seconds per item: 3 in the first third, 1 in the second, 2 in the last
  const auto cost = [&](std::size_t i) { return i < n / 3 ? 3.0 : i < 2 * n / 3 ? 1.0 : 2.0; };
  std::vector<double> ranges(workers);
  for (int call = 0; call < 40; ++call) {
    std::fill(ranges.begin(), ranges.end(), 0.0);
    for (std::size_t p = 0; p < pieces; ++p) {
      const auto [begin, end] = split.piece(n, workers, p);
      double seconds = 0.0;
      for (std::size_t i = begin; i < end; ++i) seconds += cost(i);
      split.record(p, seconds);
      ranges[p / PacedSplit::kPieces] += seconds;
    }
    if (call == 0) {
      EXPECT_GT(*std::max_element(ranges.begin(), ranges.end()), 1.4 * *std::min_element(ranges.begin(), ranges.end()))
          << "equal counts at first";
    }
    split.adapt();
  }
  EXPECT_LT(*std::max_element(ranges.begin(), ranges.end()), 1.01 * *std::min_element(ranges.begin(), ranges.end()));
  // each range costs a third of the 12000 s: the first ends at 4000 / 3 items, the second where the
  // second third's items have added 4000 s more
  EXPECT_NEAR(split.edges()[1] * n, 4000.0 / 3.0, 3.0);
  EXPECT_NEAR(split.edges()[2] * n, 2000.0 + 2000.0, 3.0);
}

// A call without usable times (a range took no measurable time, or a time is not finite) keeps the
// division as it was.
TEST(PacedSplit, KeepsTheDivisionWithoutUsableTimes) {
  PacedSplit split;
  (void)split.piece(100, 2, 0);
  const std::size_t k = PacedSplit::kPieces;
  for (std::size_t p = 0; p < k; ++p) {
    split.record(p, 2.0);
    split.record(k + p, 1.0);
  }
  split.adapt();
  const double moved = split.edges()[1];
  EXPECT_LT(moved, 0.5);
  for (const double bad : {0.0, -1.0, std::numeric_limits<double>::infinity(), std::nan("")}) {
    for (std::size_t p = 0; p < k; ++p) {
      split.record(p, 1.0);
      split.record(k + p, p == 0 ? bad : 0.0);
    }
    split.adapt();
    EXPECT_EQ(split.edges()[1], moved) << bad;
  }
}

// run() calls every piece exactly once, and a worker done with its own range takes over the pieces another
// worker has not reached (here: while that worker is held up in its first piece).
TEST(PacedSplit, RunCallsEveryPieceOnceAndHandsTheTailToAWorkerThatIsDone) {
  for (const int workers : {1, 2, 3}) {
    ThreadPool pool(workers);
    PacedSplit split;
    const std::size_t n = 1000, pieces = PacedSplit::pieces(workers);
    std::vector<std::atomic<int>> hits(n);
    std::vector<std::atomic<int>> ranBy(pieces);
    for (auto& r : ranBy) r.store(-1);
    // worker 0 is held up in its first piece until its other pieces have run (at most a minute: a split
    // that never hands them over fails below, after the wait, however busy the machine)
    std::atomic<std::size_t> restOfFirstRange{0};
    split.run(pool, workers, n, [&](int worker, std::size_t p, std::size_t begin, std::size_t end) {
      ranBy[p].store(worker);
      if (p == 0 && workers > 1) {
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
        while (restOfFirstRange.load() < PacedSplit::kPieces - 1 && std::chrono::steady_clock::now() < deadline)
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        std::this_thread::sleep_for(std::chrono::milliseconds(20));  // (and takes longer than any other range)
      }
      for (std::size_t i = begin; i < end; ++i) hits[i].fetch_add(1);
      if (p > 0 && p < PacedSplit::kPieces) restOfFirstRange.fetch_add(1);
    });
    for (std::size_t i = 0; i < n; ++i) ASSERT_EQ(hits[i].load(), 1) << "workers " << workers << ", item " << i;
    for (std::size_t p = 0; p < pieces; ++p) ASSERT_GE(ranBy[p].load(), 0) << "piece " << p << " never ran";
    if (workers > 1) {
      EXPECT_EQ(ranBy[0].load(), 0);
      for (std::size_t p = 1; p < PacedSplit::kPieces; ++p)
        EXPECT_NE(ranBy[p].load(), 0) << "worker 0's piece " << p << " waited for worker 0";
      // the held-up range took the time: the next call gives it fewer items
      EXPECT_LT(split.edges()[1], 1.0 / workers);
    }
  }
}

}  // namespace
}  // namespace volpar
