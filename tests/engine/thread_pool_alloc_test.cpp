// Handing work to the thread pool allocates nothing. A program of its own: it replaces the global
// operators new and delete to count every allocation, which must not meet libraries that allocate
// through another allocator (the sanitizer build's, in the scene loader's).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "volpar/engine/core/thread_pool.hpp"

// Every allocation of this test program is counted (the replaceable global operators new and delete, on
// top of malloc and free), so that a test can check that a piece of code allocates nothing.
namespace {
std::atomic<long> gAllocations{0};
void* allocate(std::size_t size, std::size_t alignment) {
  gAllocations.fetch_add(1, std::memory_order_relaxed);
  if (size == 0) size = 1;
  void* p = alignment <= alignof(std::max_align_t)
                ? std::malloc(size)
                : std::aligned_alloc(alignment, (size + alignment - 1) / alignment * alignment);
  if (!p) throw std::bad_alloc();
  return p;
}
}  // namespace

void* operator new(std::size_t size) { return allocate(size, 0); }
void* operator new[](std::size_t size) { return allocate(size, 0); }
void* operator new(std::size_t size, std::align_val_t a) { return allocate(size, static_cast<std::size_t>(a)); }
void* operator new[](std::size_t size, std::align_val_t a) { return allocate(size, static_cast<std::size_t>(a)); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace volpar {
namespace {

TEST(ThreadPool, HandsOutWorkWithoutAllocating) {
  // the step hands out work many times per step and must not allocate: neither the pool nor the
  // references to the work it passes around may (work capturing several references would not fit in
  // std::function's small buffer)
  ThreadPool pool(2);
  std::vector<double> out(1000, 0.0);
  double scale = 2.0, offset = 1.0;
  const auto ranges = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) out[i] = scale * static_cast<double>(i) + offset;
  };
  const auto items = [&](int, std::size_t i) { out[i] += scale * offset; };
  const auto round = [&] {
    pool.run(out.size(), ranges);
    pool.runItems(out.size(), items);
    pool.runChunks(out.size(), ranges);
  };
  round();  // (anything made on first use is made here)
  const long before = gAllocations.load();
  for (int r = 0; r < 100; ++r) round();
  EXPECT_EQ(gAllocations.load() - before, 0);
  for (std::size_t i = 0; i < out.size(); ++i) ASSERT_EQ(out[i], 2.0 * static_cast<double>(i) + 1.0);
}

}  // namespace
}  // namespace volpar
