// The contact solver's order is a tree of bisections of the bodies whose nodes the threads share: a deep
// tree solved on one, two, three and four threads gives the same velocities and impulses bit for bit (and
// on six, where some threads take over others' nodes), and
// deep or shallow, it solves the contacts (no contact left approaching).

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "volpar/dynamics/contact_solver.hpp"
#include "volpar/engine/core/thread_pool.hpp"
#include "tests/support/contact_lattice.hpp"

namespace volpar {
namespace {

using test::expectSameSolve;
using test::Lattice;
using test::kNx;
using test::kNy;
using test::kNz;
using test::makeLattice;
using test::Solved;
using test::solveLattice;


TEST(ContactSolverTree, DeepTreeGivesTheSameResultOnAnyNumberOfThreads) {
  // 288 bodies in leaves of at least 4: 64 leaves, seven levels
  ASSERT_EQ(ContactSolver::depthFor(kNx * kNy * kNz, 4), 6);
  const Solved one = solveLattice(1, 4, 10);
  for (const int threads : {2, 3, 4}) {
    const Solved many = solveLattice(threads, 4, 10);
    expectSameSolve(many, one, std::to_string(threads) + " threads");
    if (::testing::Test::HasFatalFailure()) return;
  }
}

TEST(ContactSolverTree, NodesTakenOverFromAnotherThreadGiveTheSameResult) {
  // A thread that is done with its share of a level's nodes takes those of a slower thread it has not
  // started. Six threads on fewer cores: the system pauses some of them mid-sweep, and the others take
  // their nodes over. Whoever solves a node, the result is the same bit for bit; solved again until a
  // node has been taken over (the first solve nearly always does)
  const Solved one = solveLattice(1, 4, 10);
  EXPECT_EQ(one.nodesTakenOver, 0u);
  std::size_t takenOver = 0;
  for (int round = 0; round < 200 && takenOver == 0; ++round) {
    const Solved many = solveLattice(6, 4, 10);
    expectSameSolve(many, one, "six threads, round " + std::to_string(round));
    if (::testing::Test::HasFatalFailure()) return;
    takenOver += many.nodesTakenOver;
  }
  EXPECT_GT(takenOver, 0u);
}

TEST(ContactSolverTree, DeepAndShallowTreesBothStopEveryApproach) {
  // the tree orders the iterations; converged, no touching contact may still approach
  for (const int perLeaf : {4, 1000}) {
    Lattice l = makeLattice();
    ContactSolver solver;
    SolverSettings s;
    s.bodiesPerLeaf = perLeaf;
    s.iterations = 1000;
    s.warmStart = false;
    solver.setSettings(s);
    solver.solve(l.bodies, l.points, 1.0 / 240.0);
    double worst = 0.0;
    for (const ContactPointInput& p : l.points) {
      if (p.depth < 0.0) continue;  // (a gap may close, not more)
      const SolverBody* a = p.a == ContactPointInput::kFixed ? nullptr : &l.bodies[p.a];
      const SolverBody& b = l.bodies[p.b];
      double vn = p.normal.dot(b.v) + p.rB.cross(p.normal).dot(b.w);
      if (a) vn -= p.normal.dot(a->v) + p.rA.cross(p.normal).dot(a->w);
      worst = std::min(worst, vn);
    }
    EXPECT_GT(worst, -1e-3) << "leaves of " << perLeaf << " bodies: a contact still approaches at " << -worst << " m/s";
  }
}

}  // namespace
}  // namespace volpar
