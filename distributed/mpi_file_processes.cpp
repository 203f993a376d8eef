#include "volpar/distributed/mpi_file_processes.hpp"

#include <hdf5.h>

#include <type_traits>

namespace volpar {

static_assert(std::is_same_v<hid_t, std::int64_t>, "FileProcesses passes HDF5 identifiers as std::int64_t");

MpiFileProcesses::MpiFileProcesses(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
}

bool MpiFileProcesses::useMpiIo(std::int64_t fapl) const {
#ifdef H5_HAVE_PARALLEL
  return H5Pset_fapl_mpio(fapl, comm_, MPI_INFO_NULL) >= 0;
#else
  static_cast<void>(fapl);
  return false;
#endif
}

bool MpiFileProcesses::any(bool mine) const {
  int in = mine ? 1 : 0, out = 0;
  MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_LOR, comm_);
  return out != 0;
}

}  // namespace volpar
