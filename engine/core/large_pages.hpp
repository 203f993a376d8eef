#pragma once
// Memory for the engine's large arrays on large pages. The step walks arrays of particles, contacts, planes
// and solver rows, mostly by index, over tens of megabytes: with 4 KiB pages most of those reads miss the
// processor's TLB, and under a hypervisor each miss walks two page tables. Linux backs memory with 2 MiB
// pages (transparent huge pages) where a program asks for them (`madvise(MADV_HUGEPAGE)`, the default
// setting of `/sys/kernel/mm/transparent_hugepage/enabled`) or everywhere (`always`); glibc's malloc asks
// only when told to (`GLIBC_TUNABLES=glibc.malloc.hugetlb=1`). So the arrays that the step walks take
// their memory from a pool of regions that ask: a region is reserved 2 MiB-aligned, a block is carved from
// it at 64-byte alignment, and a region whose blocks are all given back is returned to the system.
//
// Small blocks, builds without Linux's madvise, and builds with AddressSanitizer (which must see every
// block on its own) use the ordinary allocator instead; nothing else differs. Where the system refuses
// large pages the regions are ordinary memory. Only speed depends on it, never a result.

#include <cstddef>
#include <limits>
#include <new>
#include <vector>

namespace volpar {

/// `bytes` of storage aligned to 64 bytes, from the large-page pool (from `operator new` where blocks this
/// small or this build do not use the pool). Throws std::bad_alloc where there is no memory.
[[nodiscard]] void* allocateLargePages(std::size_t bytes);
/// Gives back a block from allocateLargePages(), with the size it was asked for.
void freeLargePages(void* block, std::size_t bytes) noexcept;

/// What the pool holds now, for tests and reports.
struct LargePageStats {
  std::size_t regions = 0;        ///< regions reserved from the system
  std::size_t reservedBytes = 0;  ///< their address space (resident only where touched)
  std::size_t usedBytes = 0;      ///< in blocks handed out (rounded to the pool's granule)
  std::size_t blocks = 0;         ///< blocks handed out from the pool and not given back
  std::size_t handedOut = 0;      ///< blocks handed out from the pool since the program started
};
[[nodiscard]] LargePageStats largePageStats();
/// Whether this build's blocks come from the pool (false off Linux and under AddressSanitizer).
[[nodiscard]] bool largePagePoolUsed();

/// A standard allocator over allocateLargePages(), for the step's large arrays.
template <class T>
struct LargePageAllocator {
  using value_type = T;
  LargePageAllocator() noexcept = default;
  template <class U>
  LargePageAllocator(const LargePageAllocator<U>&) noexcept {}  // NOLINT(google-explicit-constructor)
  [[nodiscard]] T* allocate(std::size_t n) {
    if (n > std::numeric_limits<std::size_t>::max() / sizeof(T)) throw std::bad_array_new_length();
    return static_cast<T*>(allocateLargePages(n * sizeof(T)));
  }
  void deallocate(T* p, std::size_t n) noexcept { freeLargePages(p, n * sizeof(T)); }
  template <class U>
  bool operator==(const LargePageAllocator<U>&) const noexcept {
    return true;
  }
};

/// A vector whose storage comes from the large-page pool.
template <class T>
using LargeVector = std::vector<T, LargePageAllocator<T>>;

}  // namespace volpar
