#pragma once
// One contiguous range per worker, sized by the workers' measured paces.
//
// Work whose items cost unevenly, and whose result does not depend on which worker handles which items
// (each range's output is merged in range order afterwards), can be cut into one contiguous range per
// worker instead of many small chunks taken as they come: each worker then reads one contiguous part of
// the inputs (in its own cache), and there is one output per worker to merge. What makes the ranges even is
// the last call's times: each worker times its range, and the next call's boundaries move towards the
// division in which every worker's share is in proportion to its pace (items a second). Items that cost
// alike from call to call (a step's body pairs, the next step's) balance within a few calls.
//
// The boundaries are fractions of the items, so they carry over when the number of items changes. Since
// they follow timings, a result must never depend on them.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace volpar {

class PacedSplit {
 public:
  /// Fraction of the way each boundary moves towards the pace-even one per call: all of it would follow
  /// one call's noise (a worker interrupted once), a tenth would take dozens of calls to settle.
  static constexpr double kFollow = 0.5;

  /// [begin, end) of `worker`'s range of n items among `workers` (the first call: equal counts).
  [[nodiscard]] std::pair<std::size_t, std::size_t> range(std::size_t n, int workers, int worker) {
    prepare(workers);
    const auto at = [&](std::size_t w) {
      return w >= static_cast<std::size_t>(workers) ? n
                                                     : std::min(n, static_cast<std::size_t>(std::llround(edges_[w] * static_cast<double>(n))));
    };
    const auto w = static_cast<std::size_t>(worker);
    return {at(w), std::max(at(w), at(w + 1))};
  }

  /// Sizes the per-worker records for `workers` (called by range(); call it before record() from the
  /// workers, which must not resize anything).
  void prepare(int workers) {
    const auto count = static_cast<std::size_t>(std::max(1, workers));
    if (edges_.size() == count) return;
    edges_.resize(count);
    seconds_.assign(count, 0.0);
    for (std::size_t w = 0; w < count; ++w) edges_[w] = static_cast<double>(w) / static_cast<double>(count);
  }

  /// Worker `worker`'s time for its range in this call (each worker writes its own entry).
  void record(int worker, double seconds) { seconds_[static_cast<std::size_t>(worker)] = seconds; }

  /// Moves the boundaries for the next call from this call's times (after all workers have recorded).
  void adapt() {
    const std::size_t count = edges_.size();
    if (count < 2) return;
    paces_.resize(count);
    double total = 0.0;
    for (std::size_t w = 0; w < count; ++w) {
      const double share = (w + 1 < count ? edges_[w + 1] : 1.0) - edges_[w];
      // (a worker that took no measurable time, or had nothing: no evidence, keep the division)
      if (!(seconds_[w] > 0.0) || !std::isfinite(seconds_[w]) || !(share > 0.0)) return;
      paces_[w] = share / seconds_[w];
      total += paces_[w];
    }
    double edge = 0.0;
    for (std::size_t w = 1; w < count; ++w) {
      edge += paces_[w - 1] / total;
      // (kept in order: each range starts where the one before it ends)
      edges_[w] = std::clamp(edges_[w] + kFollow * (edge - edges_[w]), edges_[w - 1], 1.0);
    }
  }

  /// The boundaries as fractions of the items (worker w starts at fraction w).
  [[nodiscard]] const std::vector<double>& edges() const { return edges_; }

 private:
  std::vector<double> edges_;    // start of each worker's range, as a fraction of the items
  std::vector<double> seconds_;  // each worker's time in the last call
  std::vector<double> paces_;
};

/// Seconds since `start` (for PacedSplit::record).
inline double secondsSinceStart(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace volpar
