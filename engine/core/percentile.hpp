#pragma once
// The q-quantile of a sample, interpolated between order statistics (for reports and tests).

#include <algorithm>
#include <cstddef>
#include <vector>

namespace volpar {

/// The q-quantile (0 <= q <= 1) of `v`, linearly interpolated between the two nearest order statistics
/// (numpy's default); 0 for an empty sample.
[[nodiscard]] inline double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

}  // namespace volpar
