#pragma once
// A contact problem for the solver's tests: a lattice of spheres, every one touching its neighbours.

#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "volpar/dynamics/contact_solver.hpp"
#include "volpar/engine/core/thread_pool.hpp"

namespace volpar::test {

constexpr int kNx = 6, kNy = 6, kNz = 8;

/// A lattice of unit spheres (1 kg, spacing 1) with jittered centres and random velocities, every sphere
/// touching its lattice neighbours and the bottom layer a fixed floor; some contacts overlap, some have
/// small gaps. With `heavyStack`, also a stack of two spheres beside it, apart from it: a 1 kg sphere on
/// the floor under a 1000 kg one (an island the solver solves exactly: SolverSettings::heavyIslandRatio).
struct Lattice {
  std::vector<SolverBody> bodies;
  std::vector<ContactPointInput> points;
};

inline Lattice makeLattice(bool heavyStack = false) {
  Lattice l;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02), speed(-1.0, 1.0), depth(-0.01, 0.02);
  const auto index = [](int x, int y, int z) { return static_cast<std::uint32_t>((z * kNy + y) * kNx + x); };
  for (int z = 0; z < kNz; ++z)
    for (int y = 0; y < kNy; ++y)
      for (int x = 0; x < kNx; ++x) {
        SolverBody b;
        b.position = Vec3(x, y, z + 0.5) + Vec3(jitter(rng), jitter(rng), jitter(rng));
        b.v = Vec3(speed(rng), speed(rng), speed(rng) - 2.0);
        b.w = Vec3(speed(rng), speed(rng), speed(rng));
        b.invMass = 1.0;
        b.invInertia = Mat3::Identity() / (0.4 * 0.25);  // a solid sphere of radius 0.5
        l.bodies.push_back(b);
      }
  std::uint64_t key = 1;
  const auto contact = [&](std::uint32_t a, std::uint32_t b, const Vec3& n) {
    ContactPointInput p;
    p.a = a;
    p.b = b;
    p.normal = n;
    p.rA = a == ContactPointInput::kFixed ? Vec3::Zero() : Vec3(0.5 * n);
    p.rB = -0.5 * n;
    p.depth = depth(rng);
    p.slop = 0.001;
    p.friction = 0.5;
    p.restitution = 0.2;
    p.key = key++;
    l.points.push_back(p);
  };
  for (int z = 0; z < kNz; ++z)
    for (int y = 0; y < kNy; ++y)
      for (int x = 0; x < kNx; ++x) {
        const std::uint32_t i = index(x, y, z);
        if (z == 0) contact(ContactPointInput::kFixed, i, Vec3::UnitZ());
        if (x + 1 < kNx) contact(i, index(x + 1, y, z), Vec3::UnitX());
        if (y + 1 < kNy) contact(i, index(x, y + 1, z), Vec3::UnitY());
        if (z + 1 < kNz) contact(i, index(x, y, z + 1), Vec3::UnitZ());
      }
  if (heavyStack) {
    const auto light = static_cast<std::uint32_t>(l.bodies.size()), heavy = light + 1;
    for (const double mass : {1.0, 1000.0}) {
      SolverBody b;
      b.position = Vec3(-3.0, 2.5, 0.5 + static_cast<double>(l.bodies.size() - light));
      b.v = Vec3(0.0, 0.0, -1.0);
      b.invMass = 1.0 / mass;
      b.invInertia = Mat3::Identity() / (0.4 * 0.25 * mass);
      l.bodies.push_back(b);
    }
    contact(ContactPointInput::kFixed, light, Vec3::UnitZ());
    contact(light, heavy, Vec3::UnitZ());
  }
  return l;
}


/// Five solves (the warm start carried from each to the next) with `threads` threads (and the processes of
/// `exchange`): every body's velocities and every point's impulses.
struct Solved {
  std::vector<SolverBody> bodies;
  std::vector<Vec3> impulses;
  std::size_t heavyIslands = 0;  // islands solved exactly, over the five solves
  std::size_t nodesTakenOver = 0;  // sweeps over a node one thread took over from another, over the five
};

/// Expects two solves' velocities, pseudo velocities and impulses to be the same bit for bit.
inline void expectSameSolve(const Solved& got, const Solved& want, const std::string& what) {
  ASSERT_EQ(got.bodies.size(), want.bodies.size()) << what;
  for (std::size_t i = 0; i < want.bodies.size(); ++i) {
    ASSERT_TRUE(got.bodies[i].v == want.bodies[i].v) << what << ", body " << i;
    ASSERT_TRUE(got.bodies[i].w == want.bodies[i].w) << what << ", body " << i;
    ASSERT_TRUE(got.bodies[i].pv == want.bodies[i].pv) << what << ", body " << i;
    ASSERT_TRUE(got.bodies[i].pw == want.bodies[i].pw) << what << ", body " << i;
  }
  ASSERT_TRUE(got.impulses == want.impulses) << what;
}

inline Solved solveLattice(int threads, int bodiesPerLeaf, int iterations, ProcessGroup* exchange = nullptr,
                           bool heavyStack = false, bool wideLanes = true) {
  Lattice l = makeLattice(heavyStack);
  ContactSolver solver;
  SolverSettings s;
  s.bodiesPerLeaf = bodiesPerLeaf;
  s.iterations = iterations;
  s.wideLanes = wideLanes;
  solver.setSettings(s);
  solver.setProcesses(exchange);
  ThreadPool pool(threads);
  pool.setShareAll(true);  // every stage shared, however small
  Solved r;
  for (int step = 0; step < 5; ++step) {
    solver.solve(l.bodies, l.points, 1.0 / 240.0, threads > 1 ? &pool : nullptr);
    r.impulses.insert(r.impulses.end(), solver.impulses().begin(), solver.impulses().end());
    r.heavyIslands += solver.heavyIslandsSolved();
    r.nodesTakenOver += solver.nodesTakenOver();
  }
  r.bodies = l.bodies;
  return r;
}

}  // namespace volpar::test
