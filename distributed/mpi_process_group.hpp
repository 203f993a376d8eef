#pragma once
// Processes stepping one world together, over MPI: each process's share of a stage's results gathered into
// every process (MPI_Allgatherv).

#include <mpi.h>

#include <vector>

#include "volpar/engine/core/process_group.hpp"

namespace volpar {

class MpiProcessGroup final : public ProcessGroup {
 public:
  /// Over the processes of `comm` (which stays the caller's).
  explicit MpiProcessGroup(MPI_Comm comm);

  [[nodiscard]] int rank() const override { return rank_; }
  [[nodiscard]] int size() const override { return size_; }
  void share(std::span<std::byte> data, std::span<const std::size_t> offset, std::span<const std::size_t> count) override;
  void gather(std::span<const std::byte> mine, ExchangeBytes& all) override;

  /// Bytes this process has received through share() and gather() so far (what the others' shares cost it).
  [[nodiscard]] std::size_t bytesReceived() const { return received_; }
  /// share() and gather() calls so far.
  [[nodiscard]] std::size_t calls() const { return calls_; }
  [[nodiscard]] double exchangeSeconds() const override { return seconds_; }

 private:
  MPI_Comm comm_;
  int rank_ = 0;
  int size_ = 1;
  std::vector<int> counts_, displacements_;
  std::vector<unsigned long long> sizes_;
  std::size_t received_ = 0;
  std::size_t calls_ = 0;
  double seconds_ = 0.0;
};

}  // namespace volpar
