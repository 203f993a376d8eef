// The narrow phase shared by MPI processes (run under mpirun with 1, 2 and 3 processes): each computes a run
// of the contact groups and keeps the entries for reuse of its own groups, handing an entry over when its
// group passes to another process; every process then holds the patches one process alone makes, bit for
// bit, step after step, with one or two threads each. The entries are divided (each kept by one process)
// and saved in a checkpoint as one process saves them; restored from one (every process then keeps every
// entry), or given the processes only after some runs alone, the processes go on alike. Which process keeps
// which entry every process knows from the last run, so a run in which no entry passes between processes
// exchanges only its results.

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

bool same(const PatchSet& x, const PatchSet& y) {
  if (x.patches.size() != y.patches.size() || x.contacts != y.contacts || x.depthAlongNormal != y.depthAlongNormal ||
      x.patchOfContact != y.patchOfContact || x.flipped != y.flipped)
    return false;
  for (std::size_t i = 0; i < x.patches.size(); ++i) {
    const ContactPatch &p = x.patches[i], &q = y.patches[i];
    if (p.a != q.a || p.b != q.b || p.plane != q.plane || p.normal != q.normal || p.point != q.point ||
        p.depth != q.depth || p.margin != q.margin || p.planeCase != q.planeCase || p.source != q.source ||
        p.validated != q.validated || p.lookAhead != q.lookAhead || p.lookAheadCase != q.lookAheadCase ||
        p.curvedSide != q.curvedSide || p.core != q.core || p.first != q.first || p.count != q.count)
      return false;
  }
  return x.stats.patches == y.stats.patches && x.stats.reused == y.stats.reused &&
         x.stats.candidates == y.stats.candidates && x.stats.byCase == y.stats.byCase;
}

bool same(const StateArchive& x, const StateArchive& y) {
  if (x.arrays().size() != y.arrays().size()) return false;
  for (std::size_t i = 0; i < x.arrays().size(); ++i) {
    const StateArchive::Array &a = x.arrays()[i], &b = y.arrays()[i];
    if (a.name != b.name || a.type != b.type || a.width != b.width || a.bytes != b.bytes) return false;
  }
  return true;
}

struct Compared {
  bool allSame = true, divided = true, savedSame = true, restored = true;
  std::size_t patches = 0, reused = 0, received = 0, mostKept = 0, keptAlone = 0;
  /// runs in which no entry passed between processes, and the most exchanges any of them made
  std::size_t runsWithoutMoves = 0, mostExchangesWithoutMoves = 0;
};

/// Steps the scene alone and, after every step, makes its patches again with a narrow phase shared by the
/// processes through `exchange` (and with one of its own), comparing them with the world's.
Compared compare(MpiProcessGroup& exchange, int threads, int steps) {
  Compared result;
  World w = test::worldFromString(test::kHeapScene, "heap.yaml");
  NarrowPhase shared, alone;
  shared.setSettings(w.settings().planes);
  alone.setSettings(w.settings().planes);
  ThreadPool pool(threads);
  ThreadPool* const p = threads > 1 ? &pool : nullptr;
  PatchSet fromShared, fromAlone;
  // (the world's contacts and patches of its first state were made as it was built: step 0 compares those)
  for (int step = 0; step <= steps; ++step) {
    if (step > 0 && w.step() != StepStatus::Ok) {
      ADD_FAILURE() << "step " << step;
      result.allSame = false;
      return result;
    }
    // (the first runs made by each process alone, as a world's first contacts are found before it is given
    // its processes: every process keeps every entry of those)
    if (step == 10) shared.setProcesses(&exchange);
    if (step == 200) {
      // a checkpoint of one process restored into the shared narrow phase: every process then keeps every
      // entry until its next run
      StateArchive one;
      alone.saveCache(one);
      StateReader reader(one);
      result.restored = shared.restoreCache(reader);
    }
    const std::size_t callsBefore = exchange.calls();
    shared.run(w.narrowPhaseInput(), w.contacts(), fromShared, p);
    const std::size_t calls = exchange.calls() - callsBefore;
    if (step >= 10 && sumOver(shared.entriesReceived()) == 0) {
      ++result.runsWithoutMoves;
      result.mostExchangesWithoutMoves = std::max(result.mostExchangesWithoutMoves, calls);
    }
    alone.run(w.narrowPhaseInput(), w.contacts(), fromAlone, p);
    result.allSame = result.allSame && same(fromShared, w.patches()) && same(fromAlone, w.patches());
    // every entry kept by exactly one process
    if (step >= 10) result.divided = result.divided && sumOver(shared.cachedGroups()) == alone.cachedGroups();
    result.patches += w.patches().patches.size();
    result.reused += w.patches().stats.reused;
    result.received += shared.entriesReceived();
    result.mostKept = std::max(result.mostKept, shared.cachedGroups());
    result.keptAlone = std::max(result.keptAlone, alone.cachedGroups());
    if (step % 100 == 50) {
      StateArchive mine, one;
      shared.saveCache(mine);
      alone.saveCache(one);
      result.savedSame = result.savedSame && same(mine, one);
    }
  }
  return result;
}

TEST(NarrowPhaseRanks, EveryProcessMakesThePatchesOfOne) {
  for (const int threads : {1, 2}) {
    MpiProcessGroup exchange(MPI_COMM_WORLD);
    const Compared c = compare(exchange, threads, 360);
    const int ranks = exchange.size();
    EXPECT_TRUE(everywhere(c.allSame)) << ranks << " processes, " << threads << " threads";
    EXPECT_TRUE(everywhere(c.divided));
    EXPECT_TRUE(everywhere(c.savedSame));
    EXPECT_TRUE(everywhere(c.restored));
    // (what the comparison saw: many patches, most taken over from the step before)
    EXPECT_GT(c.patches, 20000u);
    EXPECT_GT(c.reused, c.patches / 2);
    if (ranks > 1) {
      // the processes kept a part each, and entries did pass from one to another
      EXPECT_TRUE(everywhere(c.mostKept < c.keptAlone));
      EXPECT_GT(sumOver(c.received), 0u);
      // a run in which no entry passed exchanged the patches, and the contacts' depths and flips, alone:
      // nothing waits for the others' tests of their entries before the groups are divided
      EXPECT_GT(c.runsWithoutMoves, 20u);
      EXPECT_EQ(c.mostExchangesWithoutMoves, 3u);
    }
  }
}

}  // namespace
}  // namespace volpar
