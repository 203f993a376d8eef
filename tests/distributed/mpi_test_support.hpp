#pragma once
// What the tests run under mpirun share.

#include <mpi.h>

#include <cstddef>

namespace volpar::test {

/// True on every process when it holds on every process.
inline bool everywhere(bool ok) {
  int mine = ok ? 1 : 0, all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return all == 1;
}

/// The sum of every process's `mine`.
inline std::size_t sumOver(std::size_t mine) {
  unsigned long long value = mine, sum = 0;
  MPI_Allreduce(&value, &sum, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, MPI_COMM_WORLD);
  return static_cast<std::size_t>(sum);
}

// 64 crates falling into a pen in a heap (the groups' runs move between the processes as pairs meet and
// part), and a soft cube among them (groups that are never kept for reuse).
inline constexpr const char* kHeapScene = R"(name: heap
dt: 0.004166667
duration: 2.0
gravity: [0, 0, -9.81]
solver: {iterations: 10, substeps: 4}
materials:
  m: {density: 1000, restitution: 0.1, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: 0, material: m}
  - {normal: [1, 0, 0], offset: -1.0, material: m}
  - {normal: [-1, 0, 0], offset: -1.0, material: m}
  - {normal: [0, 1, 0], offset: -1.0, material: m}
  - {normal: [0, -1, 0], offset: -1.0, material: m}
bodies:
  - name: crate
    shape: {box: {size: [0.3, 0.3, 0.3]}}
    fill: {lattice: cubic, radius: 0.05, spacing: 0.1}
    material: m
    position: [-0.675, -0.675, 0.3]
    repeat:
      count: [4, 4, 4]
      spacing: [0.45, 0.45, 0.45]
      rotation_step: [{axis: [0, 0, 1], angle: 0.37}, {axis: [1, 0, 0], angle: 0.11}]
  - {name: jelly, kind: deformable, shape: {box: {size: [0.3, 0.3, 0.3]}}, fill: {radius: 0.05},
     connectors: {springs: {stiffness: 20000, damping: 5}}, material: m, position: [0.0, 0.0, 2.2]}
)";

}  // namespace volpar::test
