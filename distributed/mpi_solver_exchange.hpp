#pragma once
// The contact solver's exchange between processes over MPI: each process's share of a level's results
// gathered into every process (MPI_Allgatherv in place).

#include <mpi.h>

#include <vector>

#include "volpar/dynamics/contact_solver.hpp"

namespace volpar {

class MpiSolverExchange final : public SolverExchange {
 public:
  /// Over the processes of `comm` (which stays the caller's).
  explicit MpiSolverExchange(MPI_Comm comm);

  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  void share(std::span<std::byte> data, std::span<const std::size_t> offset, std::span<const std::size_t> count) override;

  /// Bytes this process has received through share() so far (what the others' shares cost it).
  [[nodiscard]] std::size_t bytesReceived() const { return received_; }
  /// share() calls so far.
  [[nodiscard]] std::size_t calls() const { return calls_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
  std::vector<int> counts_, displacements_;
  std::size_t received_ = 0;
  std::size_t calls_ = 0;
};

}  // namespace volpar
