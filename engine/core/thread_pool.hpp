#pragma once
// A small pool of worker threads for the step's independent work (body pairs, contact groups, bodies).
//
// `run(n, f)` calls f(worker, begin, end) on fixed ranges that split [0, n) into one contiguous range per
// worker, in order: the split depends only on n and the number of workers, never on timing, and each range
// is handled by one thread in index order. Work that writes only to its own items (or to per-worker
// buffers merged afterwards in worker order) therefore gives the same result with any number of threads.
// With one worker everything runs on the calling thread.

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

namespace volpar {

template <class Signature>
class FunctionRef;

/// A non-owning reference to a callable, for work handed to the pool: unlike std::function it never
/// allocates (the step hands out work many times and must not allocate), and it is only valid while the
/// callable lives, which for the pool's calls is until they return.
template <class R, class... Args>
class FunctionRef<R(Args...)> {
 public:
  template <class F>
    requires(!std::is_same_v<std::remove_cvref_t<F>, FunctionRef>)
  FunctionRef(F&& f) noexcept  // NOLINT(google-explicit-constructor): a lambda converts implicitly
      : object_(const_cast<void*>(static_cast<const void*>(std::addressof(f)))),
        call_([](void* o, Args... args) -> R {
          return (*static_cast<std::remove_reference_t<F>*>(o))(std::forward<Args>(args)...);
        }) {}
  R operator()(Args... args) const { return call_(object_, std::forward<Args>(args)...); }

 private:
  void* object_;
  R (*call_)(void*, Args...);
};

/// A barrier for the workers of one ThreadPool::run that meet many times in quick succession (the contact
/// solver's phases): it spins briefly, then yields.
class SpinBarrier {
 public:
  SpinBarrier() = default;
  // (its state only lives during one run: moving an owner carries nothing over)
  SpinBarrier(SpinBarrier&& other) noexcept : count_(other.count_) {}
  SpinBarrier& operator=(SpinBarrier&& other) noexcept {
    count_ = other.count_;
    return *this;
  }
  /// Prepares for `count` participants (before they start).
  void reset(int count) {
    count_ = count;
    waiting_.store(0, std::memory_order_relaxed);
  }
  /// Returns once all participants have called it; what each wrote before is visible to all after.
  void wait();

 private:
  int count_ = 1;
  std::atomic<int> waiting_{0};
  std::atomic<unsigned> generation_{0};
};

class ThreadPool {
 public:
  /// `workers` threads in all, the calling thread included (so workers - 1 are started).
  explicit ThreadPool(int workers = 1);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  [[nodiscard]] int workers() const { return workers_; }
  /// Pause instructions a waiting thread spins through before it sleeps (workers) or yields (callers,
  /// barriers): half a millisecond to a millisecond, by processor (a pause is longer on some than on
  /// others), longer than the gaps between the runs of one step, short beside a frame.
  static constexpr int kSpins = 20000;
  /// Items per worker to cut uneven work into for runItems: enough for the uneven ones to balance out.
  static constexpr std::size_t kChunksPerWorker = 8;
  /// Whether n items are worth handing out: at least `perWorker` for every worker (waking the workers
  /// costs more than a few small items). Sharing or not never changes a result.
  [[nodiscard]] bool worthSharing(std::size_t n, std::size_t perWorker) const {
    return workers_ > 1 && (shareAll_ || n >= perWorker * static_cast<std::size_t>(workers_));
  }
  /// Hands out work of any size (tests use it to run the threaded paths on small scenes).
  void setShareAll(bool on) { shareAll_ = on; }
  /// Calls f(worker, begin, end) for the ranges of [0, n), worker 0 on the calling thread; returns when
  /// all are done. `weights`, if given (size n), balances the ranges by cumulative weight instead of count.
  void run(std::size_t n, FunctionRef<void(int, std::size_t, std::size_t)> f,
           const std::vector<std::size_t>* weights = nullptr);
  /// Calls f(worker, item) once for every item of [0, n), the workers taking the next item as they
  /// finish one (uneven items balance themselves). Which worker runs an item depends on timing: f must
  /// write only to the item's own output (merged in item order afterwards) and to the worker's scratch.
  void runItems(std::size_t n, FunctionRef<void(int, std::size_t)> f);
  /// Calls f(worker, begin, end) for kChunksPerWorker consecutive ranges of [0, n) per worker, handed out
  /// as with runItems: for items of uneven cost that write only to their own places.
  void runChunks(std::size_t n, FunctionRef<void(int, std::size_t, std::size_t)> f);
  /// The range boundaries run() uses: bounds[w] .. bounds[w + 1] for worker w (workers + 1 entries).
  void split(std::size_t n, const std::vector<std::size_t>* weights, std::vector<std::size_t>& bounds) const;

 private:
  void loop(int worker);

  int workers_ = 1;
  bool shareAll_ = false;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::atomic<std::size_t> generation_{0};  // one more for every run (and for stopping)
  std::atomic<int> pending_{0};             // workers still on the current run
  std::atomic<int> sleepers_{0};            // workers waiting on start_
  std::atomic<bool> stop_{false};
  const FunctionRef<void(int, std::size_t, std::size_t)>* job_ = nullptr;
  std::vector<std::size_t> bounds_;
};

}  // namespace volpar
