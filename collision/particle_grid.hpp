#pragma once
// A uniform hash grid over points, for finding every pair of points closer than a cut-off without
// testing all pairs. Used when bodies are built (connectors within reach) and to check a scene for
// bodies that overlap at start. Cells are keyed by a hash of their integer coordinates; pairs are
// reported in a deterministic order (ascending i, then ascending j).

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

class ParticleGrid {
 public:
  /// Builds the grid over `points` with cubic cells of edge `cellSize` [m] (> 0).
  void build(std::span<const Vec3> points, double cellSize);

  /// All index pairs (i < j) with |p_i - p_j| < cutoff (cutoff <= cellSize), sorted.
  [[nodiscard]] std::vector<std::pair<std::uint32_t, std::uint32_t>> pairsWithin(double cutoff) const;

  /// Indices of points within `radius` (<= cellSize) of `q`, ascending.
  void queryRadius(const Vec3& q, double radius, std::vector<std::uint32_t>& out) const;

 private:
  struct Entry {
    std::uint64_t key;
    std::uint32_t index;
  };
  [[nodiscard]] std::uint64_t keyOf(std::int64_t x, std::int64_t y, std::int64_t z) const;
  [[nodiscard]] Eigen::Matrix<std::int64_t, 3, 1> cellOf(const Vec3& p) const;
  template <class F>
  void forEachInCell(std::uint64_t key, F&& f) const;

  std::span<const Vec3> points_;
  double cellSize_ = 1.0;
  LargeVector<Entry> entries_;  // sorted by (key, index)
};

}  // namespace volpar
