#include "volpar/collision/polytope_cores.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace volpar {

namespace {

constexpr double kSameFace = 1.0 - 1e-9;  // two face normals equal to rounding
constexpr double kOnPlane = 1e-3;         // x radius: a centre on a face's plane, a vertex at a centre
constexpr double kEscapes = 1e-9;         // a direction no plane faces (n . u at most this for every n)

}  // namespace

bool PolytopeCores::find(std::span<const ParticleId> ids, const ParticleStore& p, const NormalCache& normals,
                         std::vector<Vec3>& out) {
  out.clear();
  std::array<Vec3, kMaxFaces> faces;
  std::array<double, kMaxFaces> height;
  std::size_t nf = 0;
  double radius = 0.0;
  // 1. the distinct face normals of the surface particles
  const auto facesOf = [&](ParticleId q, std::array<Vec3, 3>& list) -> int {
    const std::uint8_t flags = p.flags[q.index()];
    const std::int32_t k = p.normalIndex[q.index()];
    if (k < 0) return -1;
    if (flags & (kParticleSheet | kParticleLine)) return -1;
    if (flags & (kParticleEdge | kParticleCorner)) {
      const std::span<const Vec3> f = normals.faces(k);
      if (f.size() < 2) return -1;
      for (std::size_t j = 0; j < f.size(); ++j) list[j] = f[j];
      return static_cast<int>(f.size());
    }
    if (normals[k].isZero()) return -1;
    list[0] = normals[k];
    return 1;
  };
  std::array<Vec3, 3> list;
  for (const ParticleId q : ids) {
    radius = std::max(radius, p.radius[q.index()]);
    if (!(p.flags[q.index()] & kParticleSurface)) continue;
    const int count = facesOf(q, list);
    if (count < 0) return false;
    for (int j = 0; j < count; ++j) {
      const double len = list[static_cast<std::size_t>(j)].norm();
      if (!(len > 0.5)) return false;
      const Vec3 f = list[static_cast<std::size_t>(j)] / len;
      bool known = false;
      for (std::size_t g = 0; g < nf && !known; ++g) known = faces[g].dot(f) > kSameFace;
      if (known) continue;
      if (nf == kMaxFaces) return false;
      faces[nf++] = f;
    }
  }
  if (nf < 4 || !(radius > 0.0)) return false;
  const double eps = kOnPlane * radius;
  // 2. each face's plane through the outermost centre along it, and every particle carrying it on that plane
  for (std::size_t g = 0; g < nf; ++g) {
    height[g] = -std::numeric_limits<double>::infinity();
    for (const ParticleId q : ids) height[g] = std::max(height[g], faces[g].dot(p.local[q.index()]));
  }
  for (const ParticleId q : ids) {
    if (!(p.flags[q.index()] & kParticleSurface)) continue;
    const int count = facesOf(q, list);
    for (int j = 0; j < count; ++j) {
      const Vec3 f = list[static_cast<std::size_t>(j)].normalized();
      std::size_t g = 0;
      while (faces[g].dot(f) <= kSameFace) ++g;
      if (f.dot(p.local[q.index()]) < height[g] - eps) return false;
    }
  }
  // 3. the planes bound a polytope: no direction along which every face normal turns away (such a direction,
  // where there is one, lies on two of the planes' normals' cross product)
  for (std::size_t i = 0; i < nf; ++i)
    for (std::size_t j = i + 1; j < nf; ++j) {
      const Vec3 c = faces[i].cross(faces[j]);
      const double len = c.norm();
      if (!(len > 1e-6)) continue;
      for (const double sign : {1.0, -1.0}) {
        const Vec3 u = sign * c / len;
        bool escapes = true;
        for (std::size_t g = 0; g < nf && escapes; ++g) escapes = faces[g].dot(u) <= kEscapes;
        if (escapes) return false;
      }
    }
  // its vertices, where three planes meet inside every other, each at a particle centre
  for (std::size_t i = 0; i < nf; ++i)
    for (std::size_t j = i + 1; j < nf; ++j)
      for (std::size_t k = j + 1; k < nf; ++k) {
        const Vec3 jk = faces[j].cross(faces[k]);
        const double det = faces[i].dot(jk);
        if (!(std::abs(det) > 1e-9)) continue;
        const Vec3 x = (height[i] * jk + height[j] * faces[k].cross(faces[i]) + height[k] * faces[i].cross(faces[j])) / det;
        bool inside = true;
        for (std::size_t g = 0; g < nf && inside; ++g) inside = faces[g].dot(x) <= height[g] + eps;
        if (!inside) continue;
        bool known = false;
        for (const Vec3& v : out) known = known || (v - x).squaredNorm() <= eps * eps;
        if (known) continue;
        const ParticleId* at = nullptr;
        for (const ParticleId& q : ids)
          if ((p.local[q.index()] - x).squaredNorm() <= eps * eps) {
            at = &q;
            break;
          }
        if (!at || out.size() == kMaxVertices) {
          out.clear();
          return false;
        }
        out.push_back(p.local[at->index()]);
      }
  if (out.size() < 4) {
    out.clear();
    return false;
  }
  return true;
}

void PolytopeCores::update(BodyId id, const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals) {
  const std::size_t i = id.index();
  if (count_.size() <= i) {
    first_.resize(bodies.size(), 0);
    count_.resize(bodies.size(), 0);
    capacity_.resize(bodies.size(), 0);
  }
  const BodyInfo& info = bodies.info[i];
  count_[i] = 0;
  if (!info.alive || info.kind == BodyKind::Deformable || info.particles.empty()) return;
  if (!find(info.particles, particles, normals, scratch_)) return;
  if (scratch_.size() > capacity_[i]) {
    first_[i] = static_cast<std::uint32_t>(vertices_.size());
    capacity_[i] = static_cast<std::uint32_t>(scratch_.size());
    vertices_.resize(vertices_.size() + scratch_.size());
  }
  std::copy(scratch_.begin(), scratch_.end(), vertices_.begin() + first_[i]);
  count_[i] = static_cast<std::uint32_t>(scratch_.size());
}

void PolytopeCores::updateAll(const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals) {
  first_.assign(bodies.size(), 0);
  count_.assign(bodies.size(), 0);
  capacity_.assign(bodies.size(), 0);
  vertices_.clear();
  for (std::size_t i = 0; i < bodies.size(); ++i) update(BodyId(i), particles, bodies, normals);
}

std::size_t PolytopeCores::bodiesWithCore() const {
  return static_cast<std::size_t>(std::count_if(count_.begin(), count_.end(), [](std::uint32_t c) { return c > 0; }));
}

}  // namespace volpar
