// A world stepped by MPI processes (run under mpirun with 1, 2 and 3 processes) against the same world stepped
// by one process alone: the bodies and particles equal bit for bit after every step, with one or two threads
// each. Each process makes in full only the contact points its share of the solver reads (those of its own
// nodes of the solver's tree), and the processes' counts of points made add up to at least all of them.

#include <gtest/gtest.h>
#include <mpi.h>

#include "tests/distributed/mpi_test_support.hpp"
#include "tests/support/test_support.hpp"
#include "volpar/distributed/mpi_process_group.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {
namespace {

using test::everywhere;
using test::sumOver;

bool sameState(const World& x, const World& y) {
  const BodyStore &a = x.bodies(), &b = y.bodies();
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const BodyState &s = a.state[i], &t = b.state[i];
    if (s.position != t.position || s.orientation.coeffs() != t.orientation.coeffs() ||
        s.linearVelocity != t.linearVelocity || s.angularVelocity != t.angularVelocity)
      return false;
  }
  return x.particles().position == y.particles().position && x.particles().velocity == y.particles().velocity;
}

struct Stepped {
  bool same = true;
  std::size_t points = 0, read = 0, dividedSteps = 0, divisibleSteps = 0;  // steps divided, steps that could be
};

Stepped stepBoth(ProcessGroup& exchange, int threads, int steps) {
  Stepped result;
  World shared = test::worldFromString(test::kHeapScene, "heap.yaml");
  World alone = test::worldFromString(test::kHeapScene, "heap.yaml");
  shared.setProcesses(&exchange);
  shared.setThreads(threads);
  alone.setThreads(threads);
  for (int step = 1; step <= steps; ++step) {
    if (shared.step() != StepStatus::Ok || alone.step() != StepStatus::Ok) {
      ADD_FAILURE() << "step " << step;
      result.same = false;
      return result;
    }
    result.same = result.same && sameState(shared, alone) && shared.stats().contactPoints == alone.stats().contactPoints;
    result.points += alone.stats().contactPoints;
    result.read += shared.stats().contactPointsRead;
    if (shared.stats().contactPointsRead < shared.stats().contactPoints) ++result.dividedSteps;
    // (a step with pairs of high mass ratio, the jelly's particles on a crate, is solved whole by every process)
    if (alone.stats().heavyIslands == 0 && alone.stats().contactPoints > 0) ++result.divisibleSteps;
  }
  return result;
}

TEST(WorldRanks, EachProcessMakesTheContactPointsItSolves) {
  for (const int threads : {1, 2}) {
    MpiProcessGroup exchange(MPI_COMM_WORLD);
    const Stepped s = stepBoth(exchange, threads, 360);
    const int ranks = exchange.size();
    EXPECT_TRUE(everywhere(s.same)) << ranks << " processes, " << threads << " threads";
    EXPECT_GT(s.points, 40000u);  // (what the comparison saw: the heap in contact)
    if (ranks == 1) {
      EXPECT_EQ(s.read, s.points);
    } else {
      // each process made a part of the points in nearly every step whose solve is divided (in a step where
      // few bodies touch, one process's share may hold them all), and together at least as many as there were
      EXPECT_TRUE(everywhere(s.read < s.points));
      EXPECT_GE(sumOver(s.read), s.points);
      EXPECT_TRUE(everywhere(10 * s.dividedSteps >= 9 * s.divisibleSteps)) << s.dividedSteps << " of " << s.divisibleSteps;
      EXPECT_GT(s.divisibleSteps, 60u);  // (the comparison saw divided solves)
    }
  }
}

}  // namespace
}  // namespace volpar
