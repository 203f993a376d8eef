#pragma once
// The pattern of a symmetric matrix of 6 x 6 blocks in compressed rows (a frame's stiffness and its coarse
// levels, frame_stiffness.hpp and frame_multigrid.hpp): each row's columns sorted, every row holding its
// diagonal.

#include <cstdint>
#include <vector>

namespace volpar {

struct BlockPattern {
  std::vector<std::uint32_t> start{0};  // row i's entries: [start[i], start[i + 1])
  std::vector<std::uint32_t> column;
  std::vector<std::uint32_t> diagonal;  // per row, the index of its diagonal entry

  [[nodiscard]] std::size_t rows() const { return start.size() - 1; }
  /// The index of entry (i, j); it must be in the pattern.
  [[nodiscard]] std::uint32_t find(std::uint32_t i, std::uint32_t j) const;
  /// The rows whose off-diagonal columns are `neighbours` (CSR: neighbourStart, sorted, no duplicates, no
  /// diagonal), each with its diagonal in its place. O(the entries).
  void setRows(const std::vector<std::uint32_t>& neighbourStart, const std::vector<std::uint32_t>& neighbours);
};

}  // namespace volpar
