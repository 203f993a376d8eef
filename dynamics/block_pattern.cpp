#include "volpar/dynamics/block_pattern.hpp"

#include <algorithm>

namespace volpar {

std::uint32_t BlockPattern::find(std::uint32_t i, std::uint32_t j) const {
  const auto first = column.begin() + start[i], last = column.begin() + start[i + 1];
  return static_cast<std::uint32_t>(std::lower_bound(first, last, j) - column.begin());
}

void BlockPattern::setRows(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours) {
  const std::size_t n = neighbourStart.size() - 1;
  start.assign(n + 1, 0);
  column.clear();
  column.reserve(neighbours.size() + n);
  diagonal.assign(n, 0);
  for (std::uint32_t i = 0; i < n; ++i) {
    bool placed = false;
    for (std::uint32_t k = neighbourStart[i]; k < neighbourStart[i + 1]; ++k) {
      if (!placed && neighbours[k] > i) {
        diagonal[i] = static_cast<std::uint32_t>(column.size());
        column.push_back(i);
        placed = true;
      }
      column.push_back(neighbours[k]);
    }
    if (!placed) {
      diagonal[i] = static_cast<std::uint32_t>(column.size());
      column.push_back(i);
    }
    start[i + 1] = static_cast<std::uint32_t>(column.size());
  }
}

}  // namespace volpar
