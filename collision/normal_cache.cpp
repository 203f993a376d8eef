#include "volpar/collision/normal_cache.hpp"

#include "volpar/collision/particle_contacts.hpp"

namespace volpar {

namespace {

/// Writes one estimate into the particle's flags and cache entry; `toCache` turns the estimate's frame into
/// the cache's.
void store(ParticleStore& p, std::size_t i, const SurfaceEstimate& e, const Quat& toCache, NormalCache& cache) {
  p.flags[i] = e.flags;
  if (!(e.flags & kParticleSurface)) {
    if (p.normalIndex[i] >= 0) cache.release(p.normalIndex[i]);
    p.normalIndex[i] = -1;
    return;
  }
  std::array<Vec3, 3> faces{};
  for (std::size_t k = 0; k < e.faceCount; ++k) faces[k] = toCache * e.faces[k];
  const Vec3 normal = toCache * e.normal;
  const std::span<const Vec3> f(faces.data(), e.faceCount);
  if (p.normalIndex[i] < 0) p.normalIndex[i] = cache.add(normal, f);
  else cache.set(p.normalIndex[i], normal, f);
}

}  // namespace

std::size_t NormalUpdater::recompute(std::span<const ParticleId> ids, ParticleStore& p, const BodyStore& bodies,
                                     const ContactFinder& adjacency, std::span<const std::uint8_t> opened,
                                     NormalCache& cache) {
  if (ids.empty()) return 0;
  // neighbours never leave their body, so each frame is estimated on its own: the body frame of rigid and
  // static bodies, the world for deformable ones
  rigid_.clear();
  deformable_.clear();
  for (const ParticleId id : ids)
    (bodies.info[p.body[id.index()].index()].kind == BodyKind::Deformable ? deformable_ : rigid_).push_back(id);
  const auto run = [&](const std::vector<ParticleId>& targets, std::span<const Vec3> positions, bool world) {
    if (targets.empty()) return;
    // a deformable body's sheets and chains stay sheets and chains as they bend
    kinds_.clear();
    if (world)
      for (const ParticleId id : targets) kinds_.push_back(p.flags[id.index()]);
    estimator_.estimate({positions, adjacency.adjacencyStart(), adjacency.adjacencyList(), opened}, targets, out_, kinds_,
                        world ? kDeformingSurfaceReach : kSurfaceReach);
    for (std::size_t t = 0; t < targets.size(); ++t) {
      const std::size_t i = targets[t].index();
      const Quat toCache = world ? bodies.state[p.body[i].index()].orientation.conjugate() : Quat::Identity();
      store(p, i, out_[t], toCache, cache);
    }
  };
  run(rigid_, p.local, false);
  run(deformable_, p.position, true);
  return ids.size();
}

}  // namespace volpar
