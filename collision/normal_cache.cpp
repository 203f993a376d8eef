#include "collision/normal_cache.hpp"

#include "collision/particle_contacts.hpp"

namespace volpar {

namespace {

/// The estimation rule for one particle: offset from the neighbours' mean, surface when it is large.
void estimateOne(const Vec3& x, const Vec3& sum, double distSum, int count, std::uint8_t& surface, Vec3& normal) {
  normal = Vec3::Zero();
  surface = 0;
  if (count == 0) {
    surface = 1;  // a lone particle: surface, no preferred direction
    return;
  }
  const Vec3 offset = x - sum / count;  // from the neighbours' mean towards the particle
  const double meanDist = distSum / count;
  if (count < 4 || offset.norm() > 0.15 * meanDist) {
    surface = 1;
    if (offset.norm() > 1e-9 * meanDist) normal = offset.normalized();
  }
}

}  // namespace

std::size_t recomputeNormals(std::span<const ParticleId> ids, ParticleStore& p, const BodyStore& bodies,
                             const ContactFinder& adjacency, NormalCache& cache) {
  for (const ParticleId id : ids) {
    const std::size_t i = id.index();
    // deformable bodies: from the current shape, turned into the body frame of their cached normals
    const bool world = bodies.info[p.body[i].index()].kind == BodyKind::Deformable;
    const std::vector<Vec3>& x = world ? p.position : p.local;
    Vec3 sum = Vec3::Zero();
    double dist = 0.0;
    int count = 0;
    for (const ParticleId n : adjacency.neighbours(id)) {
      sum += x[n.index()];
      dist += (x[n.index()] - x[i]).norm();
      ++count;
    }
    std::uint8_t surface = 0;
    Vec3 normal;
    estimateOne(x[i], sum, dist, count, surface, normal);
    if (world) normal = bodies.state[p.body[i].index()].orientation.conjugate() * normal;
    if (surface) {
      p.flags[i] |= kParticleSurface;
      if (p.normalIndex[i] < 0) p.normalIndex[i] = cache.add(normal);
      else cache.set(p.normalIndex[i], normal);
    } else {
      p.flags[i] &= static_cast<std::uint8_t>(~(kParticleSurface | kParticleEdge | kParticleCorner));
      p.normalIndex[i] = -1;
    }
  }
  return ids.size();
}

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
  // sum holds the offsets to the neighbours: the neighbours' mean is x + sum / count
  for (std::size_t i = 0; i < n; ++i)
    estimateOne(positions[i], positions[i] * count[i] + sum[i], dist[i], count[i], out.surface[i], out.normal[i]);
  return out;
}

}  // namespace volpar
