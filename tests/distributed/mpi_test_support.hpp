#pragma once
// What the tests run under mpirun share.

#include <mpi.h>

namespace volpar::test {

/// True on every process when it holds on every process.
inline bool everywhere(bool ok) {
  int mine = ok ? 1 : 0, all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return all == 1;
}

}  // namespace volpar::test
