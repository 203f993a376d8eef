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

}  // namespace volpar::test
