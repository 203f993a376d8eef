#include "volpar/engine/core/thread_pool.hpp"

#include <algorithm>

namespace volpar {

namespace {

/// A short wait inside a spin loop (lets the other hardware thread of a core run).
inline void relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

}  // namespace

void SpinBarrier::wait() {
  if (count_ <= 1) return;
  const unsigned generation = generation_.load(std::memory_order_acquire);
  if (waiting_.fetch_add(1, std::memory_order_acq_rel) + 1 == count_) {
    waiting_.store(0, std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_acq_rel);
    return;
  }
  for (int spins = 0; generation_.load(std::memory_order_acquire) == generation; ++spins) {
    if (spins < ThreadPool::kSpins) relax();
    else std::this_thread::yield();
  }
}

ThreadPool::ThreadPool(int workers) : workers_(std::max(1, workers)) {
  for (int w = 1; w < workers_; ++w) threads_.emplace_back([this, w] { loop(w); });
}

ThreadPool::~ThreadPool() {
  {
    const std::lock_guard lock(mutex_);
    stop_.store(true, std::memory_order_release);
    generation_.fetch_add(1, std::memory_order_acq_rel);
  }
  start_.notify_all();
  for (std::thread& t : threads_) t.join();
}

void ThreadPool::split(std::size_t n, const std::vector<std::size_t>* weights, std::vector<std::size_t>& bounds) const {
  const auto parts = static_cast<std::size_t>(workers_);
  bounds.assign(parts + 1, n);
  bounds[0] = 0;
  if (!weights || weights->size() != n) {
    for (std::size_t w = 1; w < parts; ++w) bounds[w] = n * w / parts;
    return;
  }
  std::size_t total = 0;
  for (const std::size_t x : *weights) total += x;
  // worker w starts at the first item whose preceding weight reaches w / parts of the total
  std::size_t acc = 0, i = 0;
  for (std::size_t w = 1; w < parts; ++w) {
    const std::size_t target = total * w / parts;
    while (i < n && acc < target) acc += (*weights)[i++];
    bounds[w] = i;
  }
}

void ThreadPool::run(std::size_t n, FunctionRef<void(int, std::size_t, std::size_t)> f,
                     const std::vector<std::size_t>* weights) {
  if (n == 0) return;
  if (workers_ == 1) {
    f(0, 0, n);
    return;
  }
  split(n, weights, bounds_);
  job_ = &f;
  pending_.store(workers_ - 1, std::memory_order_relaxed);
  {
    // (under the lock: a worker about to sleep checks the generation under it too, so none misses a job)
    const std::lock_guard lock(mutex_);
    generation_.fetch_add(1, std::memory_order_release);
  }
  if (sleepers_.load(std::memory_order_acquire) > 0) start_.notify_all();
  if (bounds_[0] < bounds_[1]) f(0, bounds_[0], bounds_[1]);
  // the others' ranges are about as long as this one: spin, then give the processor away
  for (int spins = 0; pending_.load(std::memory_order_acquire) != 0; ++spins) {
    if (spins < kSpins) relax();
    else std::this_thread::yield();
  }
  job_ = nullptr;
}

void ThreadPool::runItems(std::size_t n, FunctionRef<void(int, std::size_t)> f) {
  if (n == 0) return;
  if (workers_ == 1 || n == 1) {
    for (std::size_t i = 0; i < n; ++i) f(0, i);
    return;
  }
  std::atomic<std::size_t> next{0};
  run(static_cast<std::size_t>(workers_), [&](int worker, std::size_t, std::size_t) {
    for (std::size_t i = next.fetch_add(1, std::memory_order_relaxed); i < n; i = next.fetch_add(1, std::memory_order_relaxed))
      f(worker, i);
  });
}

void ThreadPool::runChunks(std::size_t n, FunctionRef<void(int, std::size_t, std::size_t)> f) {
  if (n == 0) return;
  const std::size_t chunks = std::min(n, kChunksPerWorker * static_cast<std::size_t>(workers_));
  runItems(chunks, [&](int worker, std::size_t c) { f(worker, n * c / chunks, n * (c + 1) / chunks); });
}

void ThreadPool::loop(int worker) {
  std::size_t seen = 0;
  for (;;) {
    // the step hands out work many times in quick succession: spin a while before sleeping, since waking
    // a sleeping thread costs more than most of the ranges it would run
    std::size_t now = generation_.load(std::memory_order_acquire);
    for (int spins = 0; now == seen && spins < kSpins; ++spins) {
      relax();
      now = generation_.load(std::memory_order_acquire);
    }
    if (now == seen) {
      std::unique_lock lock(mutex_);
      sleepers_.fetch_add(1, std::memory_order_acq_rel);
      start_.wait(lock, [&] { return generation_.load(std::memory_order_acquire) != seen; });
      sleepers_.fetch_sub(1, std::memory_order_acq_rel);
      now = generation_.load(std::memory_order_acquire);
    }
    seen = now;
    if (stop_.load(std::memory_order_acquire)) return;
    const std::size_t begin = bounds_[static_cast<std::size_t>(worker)];
    const std::size_t end = bounds_[static_cast<std::size_t>(worker) + 1];
    if (begin < end) (*job_)(worker, begin, end);
    pending_.fetch_sub(1, std::memory_order_acq_rel);
  }
}

}  // namespace volpar
