#pragma once
// MPI for a program that may or may not have been started by an MPI launcher: under mpirun (which sets
// OMPI_COMM_WORLD_SIZE, PMIX_RANK or PMI_SIZE) the session initializes MPI and finalizes it when it ends;
// started plainly it is a session of one process that never touches MPI.

#include <mpi.h>

namespace volpar {

class MpiSession {
 public:
  MpiSession();
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  /// Whether the program was started by an MPI launcher (then MPI is initialized).
  [[nodiscard]] bool active() const { return active_; }
  [[nodiscard]] int rank() const { return rank_; }
  [[nodiscard]] int size() const { return size_; }
  /// Processes of this session on this machine.
  [[nodiscard]] int localSize() const { return localSize_; }
  /// Whether any process says yes (every process calls it, and every one gets the same answer).
  [[nodiscard]] bool any(bool mine) const;
  /// Ends every process of the session with `status` (after this process has said why).
  [[noreturn]] void abort(int status) const;

 private:
  bool active_ = false;
  int rank_ = 0;
  int size_ = 1;
  int localSize_ = 1;
};

}  // namespace volpar
