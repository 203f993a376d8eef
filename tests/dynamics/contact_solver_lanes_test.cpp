// The contact solver's velocity iterations take two batches of four rows at once in eight AVX lanes where
// the processor has AVX, and one batch at a time in four lanes otherwise (SolverSettings::wideLanes). Each
// lane's arithmetic is the same, so both give the same velocities and impulses bit for bit: on a lattice of
// spheres whose contacts slide (the friction cone bounds them) and bounce, on one thread and on three, and
// with an island of high mass ratio.

#include <gtest/gtest.h>

#include "volpar/dynamics/contact_solver.hpp"
#include "tests/support/contact_lattice.hpp"

namespace volpar {
namespace {

using test::expectSameSolve;
using test::Solved;
using test::solveLattice;

TEST(ContactSolverLanes, EightLanesGiveTheSameResultAsFour) {
  if (!ContactSolver::wideLanesAvailable()) GTEST_SKIP() << "this processor has no AVX: only four lanes run";
  for (const int threads : {1, 3}) {
    for (const bool heavy : {false, true}) {
      const Solved narrow = solveLattice(threads, 4, 10, nullptr, heavy, false);
      const Solved wide = solveLattice(threads, 4, 10, nullptr, heavy, true);
      // (some contacts slide: their friction is at the cone's bound, which the lanes compute with a square
      // root, a division and a minimum)
      const test::Lattice lattice = test::makeLattice(heavy);
      std::size_t sliding = 0;
      for (std::size_t k = 0; k < narrow.impulses.size(); ++k) {
        const Vec3& p = narrow.impulses[k];
        const Vec3& n = lattice.points[k % lattice.points.size()].normal;
        const double normal = p.dot(n), friction = (p - normal * n).norm();
        if (normal > 0.0 && friction > 0.999 * 0.5 * normal) ++sliding;
      }
      EXPECT_GT(sliding, 0u);
      expectSameSolve(wide, narrow, heavy ? "with the heavy island" : "lattice");
    }
  }
}

}  // namespace
}  // namespace volpar
