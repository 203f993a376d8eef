#include "volpar/distributed/mpi_process_group.hpp"

#include <chrono>
#include <limits>
#include <stdexcept>

namespace volpar {

namespace {
using Clock = std::chrono::steady_clock;
double secondsSince(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }
}  // namespace

MpiProcessGroup::MpiProcessGroup(MPI_Comm comm) : comm_(comm) {
  MPI_Comm_rank(comm_, &rank_);
  MPI_Comm_size(comm_, &size_);
  counts_.resize(static_cast<std::size_t>(size_));
  displacements_.resize(static_cast<std::size_t>(size_));
  sizes_.resize(static_cast<std::size_t>(size_));
}

void MpiProcessGroup::share(std::span<std::byte> data, std::span<const std::size_t> offset,
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
  const auto t = Clock::now();
  MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, data.data(), counts_.data(), displacements_.data(), MPI_BYTE, comm_);
  seconds_ += secondsSince(t);
}

void MpiProcessGroup::gather(std::span<const std::byte> mine, ExchangeBytes& all) {
  // every process's size first, then the bytes
  unsigned long long size = mine.size();
  const auto t = Clock::now();
  MPI_Allgather(&size, 1, MPI_UNSIGNED_LONG_LONG, sizes_.data(), 1, MPI_UNSIGNED_LONG_LONG, comm_);
  constexpr auto kMax = static_cast<unsigned long long>(std::numeric_limits<int>::max());
  unsigned long long total = 0;
  for (std::size_t r = 0; r < counts_.size(); ++r) {
    if (sizes_[r] > kMax || total > kMax - sizes_[r])
      throw std::length_error("a gather of " + std::to_string(total + sizes_[r]) + " bytes is past 2 GiB");
    counts_[r] = static_cast<int>(sizes_[r]);
    displacements_[r] = static_cast<int>(total);
    total += sizes_[r];
    if (static_cast<int>(r) != rank_) received_ += sizes_[r];
  }
  ++calls_;
  all.resize(static_cast<std::size_t>(total));
  MPI_Allgatherv(mine.data(), counts_[static_cast<std::size_t>(rank_)], MPI_BYTE, all.data(), counts_.data(),
                 displacements_.data(), MPI_BYTE, comm_);
  seconds_ += secondsSince(t);
}

}  // namespace volpar
