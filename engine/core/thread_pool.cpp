#include "engine/core/thread_pool.hpp"

#include <algorithm>

namespace volpar {

void SpinBarrier::wait() {
  if (count_ <= 1) return;
  const unsigned generation = generation_.load(std::memory_order_acquire);
  if (waiting_.fetch_add(1, std::memory_order_acq_rel) + 1 == count_) {
    waiting_.store(0, std::memory_order_relaxed);
    generation_.fetch_add(1, std::memory_order_acq_rel);
    return;
  }
  for (int spins = 0; generation_.load(std::memory_order_acquire) == generation; ++spins) {
    if (spins < 2000) {
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#endif
    } else {
      std::this_thread::yield();
    }
  }
}

ThreadPool::ThreadPool(int workers) : workers_(std::max(1, workers)) {
  for (int w = 1; w < workers_; ++w) threads_.emplace_back([this, w] { loop(w); });
}

ThreadPool::~ThreadPool() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
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

void ThreadPool::run(std::size_t n, const std::function<void(int, std::size_t, std::size_t)>& f,
                     const std::vector<std::size_t>* weights) {
  if (n == 0) return;
  if (workers_ == 1) {
    f(0, 0, n);
    return;
  }
  {
    const std::lock_guard lock(mutex_);
    split(n, weights, bounds_);
    job_ = &f;
    pending_ = workers_ - 1;
    ++generation_;
  }
  start_.notify_all();
  if (bounds_[0] < bounds_[1]) f(0, bounds_[0], bounds_[1]);
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return pending_ == 0; });
  job_ = nullptr;
}

void ThreadPool::loop(int worker) {
  std::size_t seen = 0;
  for (;;) {
    const std::function<void(int, std::size_t, std::size_t)>* job;
    std::size_t begin, end;
    {
      std::unique_lock lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      job = job_;
      begin = bounds_[static_cast<std::size_t>(worker)];
      end = bounds_[static_cast<std::size_t>(worker) + 1];
    }
    if (begin < end) (*job)(worker, begin, end);
    {
      const std::lock_guard lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
}

}  // namespace volpar
