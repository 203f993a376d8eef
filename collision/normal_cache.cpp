#include "volpar/collision/normal_cache.hpp"

#include <cstring>

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
  else p.normalIndex[i] = cache.rewrite(p.normalIndex[i], normal, f);
}

/// A hash of a normal and its faces, bit for bit.
std::uint64_t contentHash(const Vec3& normal, std::span<const Vec3> faces) {
  std::uint64_t h = 0xcbf29ce484222325ull ^ faces.size();
  const auto mix = [&](double x) {
    std::uint64_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    h = (h ^ bits) * 0x100000001b3ull;
    h ^= h >> 29;
  };
  for (std::size_t c = 0; c < 3; ++c) mix(normal[static_cast<Eigen::Index>(c)]);
  for (const Vec3& f : faces)
    for (std::size_t c = 0; c < 3; ++c) mix(f[static_cast<Eigen::Index>(c)]);
  return h;
}

bool sameBits(const Vec3& x, const Vec3& y) { return std::memcmp(x.data(), y.data(), 3 * sizeof(double)) == 0; }

}  // namespace

bool NormalCache::holds(std::int32_t index, const Vec3& normal, std::span<const Vec3> faces) const {
  const auto i = static_cast<std::size_t>(index);
  if (index < 0 || i >= normals_.size() || users_[i] == 0) return false;
  const Faces& f = faces_[i];
  if (f.count != std::min<std::size_t>(faces.size(), 3) || !sameBits(normals_[i], normal)) return false;
  for (std::size_t k = 0; k < f.count; ++k)
    if (!sameBits(f.normal[k], faces[k])) return false;
  return true;
}

std::int32_t NormalCache::addShared(const Vec3& normal, std::span<const Vec3> faces) {
  faces = faces.first(std::min<std::size_t>(faces.size(), 3));
  const std::uint64_t h = contentHash(normal, faces);
  if (const auto it = shared_.find(h); it != shared_.end() && holds(it->second, normal, faces)) {
    ++users_[static_cast<std::size_t>(it->second)];
    return it->second;
  }
  const std::int32_t index = add(normal, faces);
  shared_[h] = index;
  return index;
}

std::int32_t NormalCache::rewrite(std::int32_t index, const Vec3& normal, std::span<const Vec3> faces) {
  if (holds(index, normal, faces)) return index;
  if (users_[static_cast<std::size_t>(index)] == 1) {
    write(index, normal, faces);
    return index;
  }
  release(index);
  return addShared(normal, faces);
}

bool NormalCache::countUsers(std::span<const std::int32_t> normalIndex) {
  users_.assign(normals_.size(), 0);
  for (const std::int32_t k : normalIndex) {
    if (k < 0) continue;
    if (static_cast<std::size_t>(k) >= users_.size()) return false;
    ++users_[static_cast<std::size_t>(k)];
  }
  for (const std::int32_t k : free_)
    if (users_[static_cast<std::size_t>(k)] != 0) return false;
  // (the entries in use are shared again by content, each hash taking its first entry)
  shared_.clear();
  for (std::size_t i = 0; i < normals_.size(); ++i) {
    if (users_[i] == 0) continue;
    const Faces& f = faces_[i];
    shared_.try_emplace(contentHash(normals_[i], std::span<const Vec3>(f.normal.data(), f.count)), static_cast<std::int32_t>(i));
  }
  return true;
}

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
