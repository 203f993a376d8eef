#pragma once
// One contiguous range of work per worker, sized by the measured cost of the items, with a tail that
// workers who finish early take over.
//
// Work whose items cost unevenly, and whose result does not depend on which worker handles which items
// (each piece's output is merged in piece order afterwards), can be cut into one contiguous range per
// worker instead of many small chunks taken as they come: each worker then reads one contiguous part of
// the inputs, in its own cache. The ranges are sized by the last call's times: every piece is timed, each
// range's cost is the sum of its pieces' times, and the next call's boundaries move towards the division
// in which every range costs the same (items that cost alike from call to call, such as a step's body pairs
// and the next step's, balance within a few calls). What the timing cannot foresee (a step whose fresh
// work lies elsewhere than the last one's, a worker interrupted) the tail absorbs: each range is cut into
// a lead piece and kPieces - 1 smaller ones; a worker takes its own pieces from the front and then any
// other range's pieces that are left, from the back.
//
// The boundaries are fractions of the items, so they carry over when the number of items changes. Since
// they follow timings, and pieces go to whichever worker claims them, a result must never depend on
// either.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "volpar/engine/core/thread_pool.hpp"

namespace volpar {

class PacedSplit {
 public:
  /// Pieces per worker's range: a lead piece of kLead of the range, then equal pieces of the rest.
  static constexpr std::size_t kPieces = 4;
  static constexpr double kLead = 0.7;
  /// Fraction of the way each boundary moves towards the cost-even one per call: all of it would follow
  /// one call's noise, a tenth would take dozens of calls to settle.
  static constexpr double kFollow = 0.5;

  /// Pieces in all for `workers` workers (the outputs to merge, in this order).
  [[nodiscard]] static std::size_t pieces(int workers) { return kPieces * static_cast<std::size_t>(std::max(1, workers)); }

  /// [begin, end) of piece `piece` of n items among `workers` (the first call: equal counts per worker).
  [[nodiscard]] std::pair<std::size_t, std::size_t> piece(std::size_t n, int workers, std::size_t piece) {
    prepare(workers);
    return range(n, piece);
  }

  /// Calls f(worker, piece, begin, end) once for every piece of n items, on `workers` workers of `pool`
  /// (workers <= pool.workers(); one worker: in order on the calling thread), and then moves the
  /// boundaries for the next call.
  template <class F>
  void run(ThreadPool& pool, int workers, std::size_t n, const F& f) {
    prepare(workers);
    const std::size_t count = edges_.size();
    const auto timed = [&](int worker, std::size_t p) {
      const auto started = std::chrono::steady_clock::now();
      const auto [begin, end] = range(n, p);
      f(worker, p, begin, end);
      seconds_[p] = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    };
    if (count == 1) {
      for (std::size_t p = 0; p < kPieces; ++p) timed(0, p);
      return;
    }
    // (every range's pieces offered before any worker starts: one that finds nothing left has nothing left)
    ++round_;
    for (std::size_t w = 0; w < count; ++w) claims_[w].word.store(pack(0, kPieces), std::memory_order_relaxed);
    pool.run(count, [&](int worker, std::size_t first, std::size_t last) {
      for (std::size_t w = first; w < last; ++w)
        for (std::size_t k; (k = take(claims_[w], true)) != kNone;) timed(worker, w * kPieces + k);
      for (std::size_t o = 1; o < count; ++o) {
        const std::size_t w = (first + o) % count;
        for (std::size_t k; (k = take(claims_[w], false)) != kNone;) timed(worker, w * kPieces + k);
      }
    });
    adapt();
  }

  /// Sizes everything for `workers` (the first call for a number of workers: equal counts).
  void prepare(int workers) {
    const auto count = static_cast<std::size_t>(std::max(1, workers));
    if (edges_.size() == count) return;
    edges_.resize(count);
    for (std::size_t w = 0; w < count; ++w) edges_[w] = static_cast<double>(w) / static_cast<double>(count);
    seconds_.assign(count * kPieces, 0.0);
    costs_.assign(count, 0.0);
    next_.assign(count, 0.0);
    claims_ = std::make_unique<Claim[]>(count);
  }

  /// Records piece `piece`'s time (for callers that run the pieces themselves).
  void record(std::size_t piece, double seconds) { seconds_[piece] = seconds; }

  /// Moves the boundaries for the next call from the pieces' times of this one.
  void adapt() {
    const std::size_t count = edges_.size();
    if (count < 2) return;
    double total = 0.0;
    for (std::size_t w = 0; w < count; ++w) {
      double cost = 0.0;
      for (std::size_t p = 0; p < kPieces; ++p) cost += seconds_[w * kPieces + p];
      const double share = (w + 1 < count ? edges_[w + 1] : 1.0) - edges_[w];
      // (a range that took no measurable time, or had nothing: no evidence, keep the division)
      if (!(cost > 0.0) || !std::isfinite(cost) || !(share > 0.0)) return;
      costs_[w] = cost;
      total += cost;
    }
    // the cost density is taken as even within each range: the boundary goes where the cumulative cost
    // reaches w / count of the total
    std::size_t r = 0;
    double before = 0.0;  // cost of the ranges before r
    double previous = 0.0;
    for (std::size_t w = 1; w < count; ++w) {
      const double target = total * static_cast<double>(w) / static_cast<double>(count);
      while (r + 1 < count && before + costs_[r] < target) before += costs_[r++];
      const double lo = edges_[r], hi = r + 1 < count ? edges_[r + 1] : 1.0;
      const double even = lo + (hi - lo) * std::clamp((target - before) / costs_[r], 0.0, 1.0);
      // (kept in order: each range starts where the one before it ends)
      const double moved = std::clamp(edges_[w] + kFollow * (even - edges_[w]), previous, 1.0);
      previous = moved;
      next_[w] = moved;
    }
    for (std::size_t w = 1; w < count; ++w) edges_[w] = next_[w];
  }

  /// The boundaries as fractions of the items (worker w's range starts at fraction w).
  [[nodiscard]] const std::vector<double>& edges() const { return edges_; }

 private:
  static constexpr std::size_t kNone = ~std::size_t{0};
  /// A range's pieces still to take: [front, back) of the current round, in one word.
  struct alignas(64) Claim {
    std::atomic<std::uint64_t> word{0};
  };
  [[nodiscard]] std::uint64_t pack(std::size_t front, std::size_t back) const {
    return (round_ << 16) | (static_cast<std::uint64_t>(front) << 8) | static_cast<std::uint64_t>(back);
  }
  /// A piece of claim c from its front (its owner) or back (another worker); kNone once none is left.
  std::size_t take(Claim& c, bool front) const {
    std::uint64_t w = c.word.load(std::memory_order_acquire);
    for (;;) {
      const std::size_t f = (w >> 8) & 0xffu, b = w & 0xffu;
      if ((w >> 16) != round_ || f >= b) return kNone;
      if (c.word.compare_exchange_weak(w, front ? pack(f + 1, b) : pack(f, b - 1), std::memory_order_acq_rel,
                                       std::memory_order_acquire))
        return front ? f : b - 1;
    }
  }
  /// [begin, end) of piece p of n items.
  [[nodiscard]] std::pair<std::size_t, std::size_t> range(std::size_t n, std::size_t p) const {
    return {at(n, p), std::max(at(n, p), at(n, p + 1))};
  }
  /// Start of piece p of n items (p = pieces(): n).
  [[nodiscard]] std::size_t at(std::size_t n, std::size_t p) const {
    const std::size_t count = edges_.size(), w = p / kPieces, k = p % kPieces;
    if (w >= count) return n;
    const double lo = edges_[w], hi = w + 1 < count ? edges_[w + 1] : 1.0;
    const double from = k == 0 ? 0.0 : kLead + (1.0 - kLead) * static_cast<double>(k - 1) / static_cast<double>(kPieces - 1);
    return std::min(n, static_cast<std::size_t>(std::llround((lo + (hi - lo) * from) * static_cast<double>(n))));
  }

  std::vector<double> edges_;    // start of each worker's range, as a fraction of the items
  std::vector<double> seconds_;  // each piece's time in the last call
  std::vector<double> costs_;    // each range's cost in the last call
  std::vector<double> next_;     // the boundaries being moved
  std::unique_ptr<Claim[]> claims_;
  std::uint64_t round_ = 0;
};

}  // namespace volpar
