#include "volpar/engine/core/large_pages.hpp"

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <map>
#include <mutex>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__SANITIZE_ADDRESS__)
#define VOLPAR_LARGE_PAGE_POOL 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define VOLPAR_LARGE_PAGE_POOL 0
#endif
#endif
#if !defined(VOLPAR_LARGE_PAGE_POOL) && defined(__linux__) && defined(MADV_HUGEPAGE)
#define VOLPAR_LARGE_PAGE_POOL 1
#endif
#if !defined(VOLPAR_LARGE_PAGE_POOL)
#define VOLPAR_LARGE_PAGE_POOL 0
#endif

namespace volpar {
namespace {

constexpr std::size_t kAlign = 64;

void* allocateSmall(std::size_t bytes) { return ::operator new(bytes, std::align_val_t{kAlign}); }
void freeSmall(void* block) noexcept { ::operator delete(block, std::align_val_t{kAlign}); }

#if VOLPAR_LARGE_PAGE_POOL

// blocks below this come from operator new: a vector of a few elements gains nothing from the pool
constexpr std::size_t kSmallest = 16 * 1024;
constexpr std::size_t kLargePage = std::size_t{2} << 20;
constexpr std::size_t kGranule = 256;                      // blocks are whole granules
constexpr std::size_t kRegionBytes = std::size_t{64} << 20;  // address space reserved at a time

std::size_t roundUp(std::size_t n, std::size_t to) { return (n + to - 1) / to * to; }

class Pool {
 public:
  void* allocate(std::size_t bytes) {
    const std::size_t size = roundUp(bytes, kGranule);
    const std::lock_guard<std::mutex> lock(mutex_);
    auto it = firstFit(size);
    if (it == free_.end()) {
      addRegion(size);  // (which adds a free block at least this large)
      it = firstFit(size);
    }
    return take(it, size);
  }

  void free(void* block, std::size_t bytes) noexcept {
    const std::size_t size = roundUp(bytes, kGranule);
    auto at = reinterpret_cast<std::uintptr_t>(block);
    const std::lock_guard<std::mutex> lock(mutex_);
    auto region = std::prev(regions_.upper_bound(at));
    --region->second.blocks;
    used_ -= size;
    --blocks_;
    std::size_t length = size;
    // merge with the free blocks on either side within the same region
    auto next = free_.lower_bound(at);
    if (next != free_.end() && next->first == at + length && next->first < region->first + region->second.size) {
      length += next->second;
      next = free_.erase(next);
    }
    if (next != free_.begin()) {
      auto before = std::prev(next);
      if (before->first + before->second == at && before->first >= region->first) {
        at = before->first;
        length += before->second;
        free_.erase(before);
      }
    }
    if (region->second.blocks == 0) {  // the whole region is free (the merged block is all of it): back to the system
      munmap(reinterpret_cast<void*>(region->first), region->second.size);
      reserved_ -= region->second.size;
      regions_.erase(region);
      return;
    }
    free_.emplace(at, length);
  }

  LargePageStats stats() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return {regions_.size(), reserved_, used_, blocks_, handedOut_};
  }

 private:
  struct Region {
    std::size_t size = 0;
    std::size_t blocks = 0;  // handed out and not given back
  };

  using FreeBlock = std::map<std::uintptr_t, std::size_t>::iterator;

  // first fit, lowest address first, so that the blocks in use stay packed at the front of the regions
  FreeBlock firstFit(std::size_t size) {
    return std::find_if(free_.begin(), free_.end(), [&](const auto& f) { return f.second >= size; });
  }

  void* take(FreeBlock it, std::size_t size) {
    const std::uintptr_t at = it->first;
    const std::size_t left = it->second - size;
    free_.erase(it);
    if (left > 0) free_.emplace(at + size, left);
    ++std::prev(regions_.upper_bound(at))->second.blocks;
    used_ += size;
    ++blocks_;
    ++handedOut_;
    return reinterpret_cast<void*>(at);
  }

  // reserves a region of at least `size` bytes, aligned to a large page, and asks for large pages in it
  void addRegion(std::size_t size) {
    const std::size_t length = roundUp(std::max(size, kRegionBytes), kLargePage);
    void* raw = mmap(nullptr, length + kLargePage, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE,
                     -1, 0);
    if (raw == MAP_FAILED) throw std::bad_alloc();
    const auto start = reinterpret_cast<std::uintptr_t>(raw);
    const std::uintptr_t aligned = roundUp(start, kLargePage);
    // (the unaligned head and tail go back at once)
    if (aligned > start) munmap(raw, aligned - start);
    const std::uintptr_t tail = aligned + length;
    if (start + length + kLargePage > tail) munmap(reinterpret_cast<void*>(tail), start + length + kLargePage - tail);
    // (a system that refuses large pages leaves the region ordinary memory)
    madvise(reinterpret_cast<void*>(aligned), length, MADV_HUGEPAGE);
    regions_.emplace(aligned, Region{length, 0});
    free_.emplace(aligned, length);
    reserved_ += length;
  }

  std::mutex mutex_;
  std::map<std::uintptr_t, Region> regions_;   // by start address
  std::map<std::uintptr_t, std::size_t> free_;  // free blocks by start address: their lengths
  std::size_t reserved_ = 0, used_ = 0, blocks_ = 0, handedOut_ = 0;
};

Pool& pool() {
  // (in static storage, never destroyed: vectors in static objects may give their blocks back after main
  // returns; and making it allocates nothing)
  alignas(Pool) static unsigned char storage[sizeof(Pool)];
  static Pool* const p = ::new (static_cast<void*>(storage)) Pool;
  return *p;
}

#endif

}  // namespace

void* allocateLargePages(std::size_t bytes) {
#if VOLPAR_LARGE_PAGE_POOL
  if (bytes >= kSmallest) return pool().allocate(bytes);
#endif
  return allocateSmall(bytes);
}

void freeLargePages(void* block, std::size_t bytes) noexcept {
  if (!block) return;
#if VOLPAR_LARGE_PAGE_POOL
  if (bytes >= kSmallest) {
    pool().free(block, bytes);
    return;
  }
#else
  (void)bytes;
#endif
  freeSmall(block);
}

LargePageStats largePageStats() {
#if VOLPAR_LARGE_PAGE_POOL
  return pool().stats();
#else
  return {};
#endif
}

bool largePagePoolUsed() { return VOLPAR_LARGE_PAGE_POOL != 0; }

}  // namespace volpar
