#pragma once
// Processes that step one world together (docs/distributed.md): each holds the whole world and does its
// share of a stage's work, and these calls hand every process the others' results. The layers below the
// engine see processes only through this; the MPI implementation is volpar/distributed/mpi_process_group.hpp.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

namespace volpar {

/// An allocator whose vectors leave the elements that resize() adds as they are (default-initialised: for
/// bytes, not written), where std::allocator's are zeroed first. The buffers of the exchanges are resized
/// to what arrives and then written whole: zeroing them first cost each of two processes about 0.7 ms a step
/// of pile-8000, most of it in the gather of the narrow phase's patches (its buffer serves smaller exchanges
/// in between, so it grows each time).
template <class T>
struct UninitializedAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() noexcept = default;
  template <class U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// The bytes of an exchange among processes.
using ExchangeBytes = std::vector<std::byte, UninitializedAllocator<std::byte>>;

class ProcessGroup {
 public:
  virtual ~ProcessGroup() = default;
  [[nodiscard]] virtual int rank() const = 0;
  [[nodiscard]] virtual int size() const = 0;
  /// Makes `data` the same on every process: the bytes [offset[r], offset[r] + count[r]) from process r
  /// (per process, in bytes; the ranges do not overlap). Called by every process with the same ranges.
  virtual void share(std::span<std::byte> data, std::span<const std::size_t> offset, std::span<const std::size_t> count) = 0;
  /// Every process's `mine`, one after another in process order, into `all`.
  virtual void gather(std::span<const std::byte> mine, ExchangeBytes& all) = 0;
  /// Seconds this process has spent in share() and gather() so far, the waits for the other processes
  /// included: what a stage loses to its exchanges and to the processes' uneven shares.
  [[nodiscard]] virtual double exchangeSeconds() const { return 0.0; }
};

// A stage's results as bytes for gather(): vectors (their length, then their elements) and single values,
// read back in the order written (each process's bytes then tell where they end). (Plain data only: the processes are copies of one program on one kind of
// machine, so the bytes mean the same on every one.)
template <class T, class A, class B>
void appendBytes(std::vector<std::byte, B>& to, const std::vector<T, A>& v) {
  const std::uint64_t n = v.size();
  const auto* size = reinterpret_cast<const std::byte*>(&n);
  to.insert(to.end(), size, size + sizeof n);
  const auto* data = reinterpret_cast<const std::byte*>(v.data());
  to.insert(to.end(), data, data + n * sizeof(T));
}
template <class T, class B>
void appendBytes(std::vector<std::byte, B>& to, const T& value) {
  const auto* data = reinterpret_cast<const std::byte*>(&value);
  to.insert(to.end(), data, data + sizeof(T));
}
template <class T, class A>
void readBytes(const std::byte*& from, std::vector<T, A>& v) {
  std::uint64_t n = 0;
  std::memcpy(&n, from, sizeof n);
  from += sizeof n;
  v.resize(n);
  if (n > 0) std::memcpy(static_cast<void*>(v.data()), from, n * sizeof(T));  // (an empty vector's data() may be null)
  from += n * sizeof(T);
}
template <class T>
void readBytes(const std::byte*& from, T& value) {
  std::memcpy(static_cast<void*>(&value), from, sizeof(T));
  from += sizeof(T);
}

/// share() of runs of equal elements: process r's part of `data` is elements [start(r), start(r + 1)) of `bytes`
/// bytes each, for r from 0 to the group's size (`offset` and `count`: the caller's scratch, kept between calls)
template <class Start>
void shareRuns(ProcessGroup& group, std::span<std::byte> data, std::size_t bytes, const Start& start,
               std::vector<std::size_t>& offset, std::vector<std::size_t>& count) {
  const auto n = static_cast<std::size_t>(group.size());
  offset.resize(n);
  count.resize(n);
  for (std::size_t r = 0; r < n; ++r) {
    offset[r] = start(r) * bytes;
    count[r] = (start(r + 1) - start(r)) * bytes;
  }
  group.share(data, offset, count);
}
/// The first of n items that process (or worker) `rank` of `size` takes: each takes a contiguous run, up to
/// the next one's first.
[[nodiscard]] inline std::size_t firstShare(int rank, int size, std::size_t n) {
  return (static_cast<std::size_t>(rank) * n + static_cast<std::size_t>(size) - 1) / static_cast<std::size_t>(size);
}

}  // namespace volpar
