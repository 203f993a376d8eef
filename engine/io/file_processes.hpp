#pragma once
// Processes that write one trajectory together (docs/distributed.md): every process opens the file with
// parallel HDF5 over MPI-IO and writes its share of every dataset's rows in collective calls. The engine sees
// the processes only through this; the MPI implementation is volpar/distributed/mpi_file_processes.hpp.

#include <cstdint>

namespace volpar {

class FileProcesses {
 public:
  virtual ~FileProcesses() = default;
  [[nodiscard]] virtual int rank() const = 0;
  [[nodiscard]] virtual int size() const = 0;
  /// Sets `fapl`, an HDF5 file access property list (hid_t), to open files with MPI-IO among these processes;
  /// false where it cannot (an HDF5 built without parallel support).
  [[nodiscard]] virtual bool useMpiIo(std::int64_t fapl) const = 0;
  /// Whether any process says yes: every process calls it and gets the same answer.
  [[nodiscard]] virtual bool any(bool mine) const = 0;
};

}  // namespace volpar
