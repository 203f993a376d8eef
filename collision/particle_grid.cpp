#include "volpar/collision/particle_grid.hpp"

#include <algorithm>
#include <cmath>

namespace volpar {

namespace {

std::uint64_t mix(std::uint64_t h) {
  // splitmix64 finaliser
  h ^= h >> 30;
  h *= 0xbf58476d1ce4e5b9ULL;
  h ^= h >> 27;
  h *= 0x94d049bb133111ebULL;
  h ^= h >> 31;
  return h;
}

}  // namespace

std::uint64_t ParticleGrid::keyOf(std::int64_t x, std::int64_t y, std::int64_t z) const {
  std::uint64_t h = mix(static_cast<std::uint64_t>(x));
  h = mix(h ^ static_cast<std::uint64_t>(y));
  return mix(h ^ static_cast<std::uint64_t>(z));
}

Eigen::Matrix<std::int64_t, 3, 1> ParticleGrid::cellOf(const Vec3& p) const {
  Eigen::Matrix<std::int64_t, 3, 1> c;
  for (int k = 0; k < 3; ++k) c[k] = static_cast<std::int64_t>(std::floor(p[k] / cellSize_));
  return c;
}

void ParticleGrid::build(std::span<const Vec3> points, double cellSize) {
  points_ = points;
  cellSize_ = cellSize;
  entries_.clear();
  entries_.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto c = cellOf(points[i]);
    entries_.push_back({keyOf(c.x(), c.y(), c.z()), static_cast<std::uint32_t>(i)});
  }
  std::sort(entries_.begin(), entries_.end(),
            [](const Entry& a, const Entry& b) { return a.key != b.key ? a.key < b.key : a.index < b.index; });
}

template <class F>
void ParticleGrid::forEachInCell(std::uint64_t key, F&& f) const {
  auto it = std::lower_bound(entries_.begin(), entries_.end(), key,
                             [](const Entry& e, std::uint64_t k) { return e.key < k; });
  for (; it != entries_.end() && it->key == key; ++it) f(it->index);
}

std::vector<std::pair<std::uint32_t, std::uint32_t>> ParticleGrid::pairsWithin(double cutoff) const {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  const double cutoff2 = cutoff * cutoff;
  std::vector<std::uint64_t> visited;
  for (std::size_t i = 0; i < points_.size(); ++i) {
    const auto c = cellOf(points_[i]);
    // distinct neighbour cells only (hash collisions could repeat a key)
    visited.clear();
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) visited.push_back(keyOf(c.x() + dx, c.y() + dy, c.z() + dz));
    std::sort(visited.begin(), visited.end());
    visited.erase(std::unique(visited.begin(), visited.end()), visited.end());
    for (const std::uint64_t key : visited) {
      forEachInCell(key, [&](std::uint32_t j) {
        if (j <= i) return;
        if ((points_[j] - points_[i]).squaredNorm() < cutoff2) pairs.emplace_back(static_cast<std::uint32_t>(i), j);
      });
    }
  }
  std::sort(pairs.begin(), pairs.end());
  return pairs;
}

void ParticleGrid::queryRadius(const Vec3& q, double radius, std::vector<std::uint32_t>& out) const {
  out.clear();
  const auto c = cellOf(q);
  const double r2 = radius * radius;
  std::uint64_t keys[27];
  int n = 0;
  for (int dx = -1; dx <= 1; ++dx)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dz = -1; dz <= 1; ++dz) keys[n++] = keyOf(c.x() + dx, c.y() + dy, c.z() + dz);
  std::sort(keys, keys + n);
  n = static_cast<int>(std::unique(keys, keys + n) - keys);
  for (int k = 0; k < n; ++k)
    forEachInCell(keys[k], [&](std::uint32_t j) {
      if ((points_[j] - q).squaredNorm() < r2) out.push_back(j);
    });
  std::sort(out.begin(), out.end());
}

}  // namespace volpar
