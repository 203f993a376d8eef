#pragma once
// The processes of an MPI communicator writing one trajectory together with parallel HDF5 (MPI-IO).

#include <mpi.h>

#include "volpar/engine/io/file_processes.hpp"

namespace volpar {

class MpiFileProcesses final : public FileProcesses {
 public:
  /// Over the processes of `comm` (which stays the caller's).
  explicit MpiFileProcesses(MPI_Comm comm);

  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  [[nodiscard]] bool useMpiIo(std::int64_t fapl) const override;
  [[nodiscard]] bool any(bool mine) const override;

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
};

}  // namespace volpar
