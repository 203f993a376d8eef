#include "collision/normal_cache.hpp"

namespace volpar {

EstimatedNormals estimateNormals(std::span<const Vec3> positions,
                                 std::span<const std::array<std::uint32_t, 2>> connectors) {
  const std::size_t n = positions.size();
  std::vector<Vec3> sum(n, Vec3::Zero());
  std::vector<double> dist(n, 0.0);
  std::vector<int> count(n, 0);
  for (const auto& c : connectors) {
    const Vec3 d = positions[c[1]] - positions[c[0]];
    sum[c[0]] += d;
    sum[c[1]] -= d;
    dist[c[0]] += d.norm();
    dist[c[1]] += d.norm();
    ++count[c[0]];
    ++count[c[1]];
  }
  EstimatedNormals out;
  out.normal.assign(n, Vec3::Zero());
  out.surface.assign(n, 0);
  for (std::size_t i = 0; i < n; ++i) {
    if (count[i] == 0) {
      out.surface[i] = 1;  // a lone particle: surface, no preferred direction
      continue;
    }
    const Vec3 offset = -sum[i] / count[i];  // from the neighbours' mean towards i
    const double meanDist = dist[i] / count[i];
    if (count[i] < 4 || offset.norm() > 0.15 * meanDist) {
      out.surface[i] = 1;
      if (offset.norm() > 1e-9 * meanDist) out.normal[i] = offset.normalized();
    }
  }
  return out;
}

}  // namespace volpar
