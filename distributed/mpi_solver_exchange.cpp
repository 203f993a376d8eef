#include "volpar/distributed/mpi_solver_exchange.hpp"

#include <limits>
#include <stdexcept>

namespace volpar {

MpiSolverExchange::MpiSolverExchange(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  counts_.resize(static_cast<std::size_t>(size_));
  displacements_.resize(static_cast<std::size_t>(size_));
}

void MpiSolverExchange::share(std::span<std::byte> data, std::span<const std::size_t> offset,
                              std::span<const std::size_t> count) {
  // (MPI counts bytes in int: a share past 2 GiB would need a derived datatype)
  constexpr auto kMax = static_cast<std::size_t>(std::numeric_limits<int>::max());
  for (std::size_t r = 0; r < counts_.size(); ++r) {
    if (offset[r] > kMax || count[r] > kMax - offset[r] || offset[r] + count[r] > data.size())
      throw std::length_error("a solver share of " + std::to_string(count[r]) + " bytes at " + std::to_string(offset[r]) +
                              " lies outside the " + std::to_string(data.size()) + " bytes shared (or past 2 GiB)");
    counts_[r] = static_cast<int>(count[r]);
    displacements_[r] = static_cast<int>(offset[r]);
    if (static_cast<int>(r) != rank_) received_ += count[r];
  }
  ++calls_;
  MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, data.data(), counts_.data(), displacements_.data(), MPI_BYTE, comm_);
}

}  // namespace volpar
