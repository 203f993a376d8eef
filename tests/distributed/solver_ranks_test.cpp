// The contact solver shared by MPI processes (run under mpirun with 1, 2 and 3 processes): every process
// gets the velocities and impulses of one process alone, bit for bit, with one or two threads each, for a
// deep tree (64 leaves) and a shallow one (2 leaves, fewer than the processes at 3), with and without an
// island of very unequal masses (solved exactly); and without the exchange the divided solve does differ,
// so the processes really did divide it.

#include <gtest/gtest.h>
#include <mpi.h>

#include <cstdio>

#include "tests/distributed/mpi_test_support.hpp"
#include "tests/support/contact_lattice.hpp"
#include "volpar/distributed/mpi_process_group.hpp"

namespace volpar {
namespace {

using test::everywhere;
using test::Solved;
using test::solveLattice;

bool same(const Solved& a, const Solved& b) {
  if (a.bodies.size() != b.bodies.size() || a.impulses != b.impulses) return false;
  for (std::size_t i = 0; i < a.bodies.size(); ++i) {
    const SolverBody &x = a.bodies[i], &y = b.bodies[i];
    if (x.v != y.v || x.w != y.w || x.pv != y.pv || x.pw != y.pw) return false;
  }
  return true;
}

/// An exchange that divides the work as MPI's does but hands no values over: its shares in place do
/// nothing (its gathers, which carry how the others laid their rows out, go through).
class Silent final : public ProcessGroup {
 public:
  explicit Silent(ProcessGroup& real) : real_(real) {}
  [[nodiscard]] int rank() const override { return real_.rank(); }
  [[nodiscard]] int size() const override { return real_.size(); }
  void share(std::span<std::byte>, std::span<const std::size_t>, std::span<const std::size_t>) override {}
  void gather(std::span<const std::byte> mine, ExchangeBytes& all) override { real_.gather(mine, all); }

 private:
  ProcessGroup& real_;
};

class SolverRanks : public ::testing::TestWithParam<int> {};  // bodies per leaf

TEST_P(SolverRanks, EveryProcessGetsTheResultOfOne) {
  const int perLeaf = GetParam();
  const Solved alone = solveLattice(1, perLeaf, 10);
  for (const int threads : {1, 2}) {
    MpiProcessGroup exchange(MPI_COMM_WORLD);
    const Solved shared = solveLattice(threads, perLeaf, 10, &exchange);
    EXPECT_TRUE(everywhere(same(shared, alone))) << exchange.size() << " processes, " << threads << " threads";
    if (exchange.size() > 1) {
      EXPECT_GT(exchange.calls(), 0u);
      if (exchange.rank() == 0 && threads == 1)
        std::printf("%d processes, leaves of %d bodies: %zu exchanges and %zu bytes received by process 0 per solve\n",
                    exchange.size(), perLeaf, exchange.calls() / 5, exchange.bytesReceived() / 5);
      // (the bytes that reached a process: 0 for one that owns every node, as the last may with 2 leaves)
      std::size_t bytes = exchange.bytesReceived(), total = 0;
      MPI_Allreduce(&bytes, &total, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
      EXPECT_GT(total, 0u);
    }
  }
}

TEST_P(SolverRanks, AHeavyIslandIsSolvedExactlyAsByOneProcess) {
  // (an island of very unequal masses is solved from every part's rows: the processes then each prepare
  // every part, and still divide the iterations)
  const int perLeaf = GetParam();
  const Solved alone = solveLattice(1, perLeaf, 10, nullptr, true);
  ASSERT_GT(alone.heavyIslands, 0u);
  for (const int threads : {1, 2}) {
    MpiProcessGroup exchange(MPI_COMM_WORLD);
    const Solved shared = solveLattice(threads, perLeaf, 10, &exchange, true);
    EXPECT_EQ(shared.heavyIslands, alone.heavyIslands);
    EXPECT_TRUE(everywhere(same(shared, alone))) << exchange.size() << " processes, " << threads << " threads";
  }
}

TEST_P(SolverRanks, WithoutTheExchangeTheDividedSolveDiffers) {
  MpiProcessGroup exchange(MPI_COMM_WORLD);
  if (exchange.size() == 1) GTEST_SKIP() << "one process divides nothing";
  const int perLeaf = GetParam();
  const Solved alone = solveLattice(1, perLeaf, 10);
  Silent silent(exchange);
  const Solved divided = solveLattice(1, perLeaf, 10, &silent);
  EXPECT_FALSE(everywhere(same(divided, alone)));
}

INSTANTIATE_TEST_SUITE_P(Leaves, SolverRanks, ::testing::Values(4, 128),
                         [](const ::testing::TestParamInfo<int>& p) { return "bodiesPerLeaf" + std::to_string(p.param); });

}  // namespace
}  // namespace volpar
