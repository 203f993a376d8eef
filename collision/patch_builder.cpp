#include "volpar/collision/patch_builder.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace volpar {

namespace {

constexpr double kCentreLines = 0.2;  // cos 78 degrees: neighbouring contacts' centre lines

/// A particle's surface normal facing `towards` in the world, and whether it has one a contact can use
/// (not interior, not on an edge, corner, chain or a sheet's rim).
bool facingWorldNormal(const NarrowPhaseInput& in, ParticleId p, const Vec3& towards, Vec3& n) {
  const ParticleStore& ps = *in.particles;
  const std::uint8_t flags = ps.flags[p.index()];
  const std::int32_t k = ps.normalIndex[p.index()];
  if (k < 0 || !(flags & kParticleSurface) || (flags & kParticleSharp)) return false;
  if ((flags & kParticleSheet) && (flags & kParticleEdge)) return false;
  const Quat& r = in.bodies->state[ps.body[p.index()].index()].orientation;
  const Vec3 local = r.conjugate() * towards;
  // a sheet shows a face only to what is across it, not to particles beside it in its own layer
  if ((flags & kParticleSheet) && !in.normals->faces(k).empty() && std::abs(in.normals->faces(k)[0].dot(local)) < 0.3) return false;
  const Vec3 f = facingNormal(flags, (*in.normals)[k], in.normals->faces(k), local);
  if (f.isZero()) return false;
  n = r * f;
  return true;
}

}  // namespace

bool PatchBuilder::direction(const NarrowPhaseInput& in, const ParticleContact& c, Vec3& out) {
  out = c.normal;
  if (c.plane.valid()) return true;
  Vec3 na, nb;
  const bool a = facingWorldNormal(in, c.a, c.normal, na);
  const bool b = facingWorldNormal(in, c.b, -c.normal, nb);
  if (a && b && (na - nb).norm() > 1e-9) out = (na - nb).normalized();
  else if (a) out = na;
  else if (b) out = -nb;
  return a || b;
}

void PatchBuilder::build(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                         std::span<std::uint8_t> flipped, std::vector<std::uint32_t>& order,
                         std::vector<std::uint32_t>& sizes) {
  order.clear();
  sizes.clear();
  const std::uint32_t m = g.count;
  const ParticleContact* c = set.contacts.data() + g.first;
  const bool plane = g.plane.valid();
  const bool self = !plane && g.a == g.b;
  constexpr std::uint32_t kFree = ~0u;
  patchOf_.assign(m, kFree);
  directions_.resize(m);
  surface_.resize(m);
  for (std::uint32_t i = 0; i < m; ++i) {
    surface_[i] = direction(in, c[i], directions_[i]) ? 1 : 0;
    flipped[g.first + i] = 0;
  }
  // seeds: the deepest contacts first (ties: the contacts' order)
  seeds_.resize(m);
  std::iota(seeds_.begin(), seeds_.end(), 0u);
  // (ties in the contacts' order: a sort that keeps equal elements in place would borrow a buffer from the
  // heap every time, and the step allocates nothing)
  std::sort(seeds_.begin(), seeds_.end(), [&](std::uint32_t x, std::uint32_t y) {
    return c[x].depth > c[y].depth || (!(c[y].depth > c[x].depth) && x < y);
  });
  if (self) {
    byParticle_.clear();
    for (std::uint32_t i = 0; i < m; ++i) {
      byParticle_.emplace_back(c[i].a, i);
      byParticle_.emplace_back(c[i].b, i);
    }
    std::sort(byParticle_.begin(), byParticle_.end());
  }
  if (side_.size() < in.particles->size()) side_.resize(in.particles->size(), 0);
  const auto deformable = [&](BodyId b) { return b.valid() && in.kindOf(b) == BodyKind::Deformable; };
  const double minCos = std::cos(deformable(g.a) || deformable(g.b) ? deformableSpread : spread);
  const auto near = [&](ParticleId x, ParticleId y) { return x == y || in.finder->connected(x, y); };
  for (const std::uint32_t seed : seeds_) {
    if (patchOf_[seed] != kFree) continue;
    if (++stamp_ >= 0x7fffffffu) {  // wrapped: clear the marks
      std::fill(side_.begin(), side_.end(), 0u);
      stamp_ = 1;
    }
    const auto sideOf = [&](ParticleId p) -> int {
      const std::uint32_t v = side_[p.index()];
      return (v >> 1) == stamp_ ? static_cast<int>(v & 1u) : -1;
    };
    const auto mark = [&](ParticleId p, int s) { side_[p.index()] = (stamp_ << 1) | static_cast<std::uint32_t>(s); };
    const std::uint32_t patch = static_cast<std::uint32_t>(sizes.size());
    const std::size_t start = order.size();
    // the patch's direction: its first contact's that has one
    Vec3 patchDirection = directions_[seed];
    bool directed = surface_[seed] != 0;
    const auto take = [&](std::uint32_t j, bool flip) {
      if (!directed && surface_[j]) {
        patchDirection = flip ? Vec3(-directions_[j]) : directions_[j];
        directed = true;
      }
      patchOf_[j] = patch;
      flipped[g.first + j] = flip ? 1 : 0;
      order.push_back(g.first + j);
      queue_.push_back(j);
      if (self) {
        mark(flip ? c[j].b : c[j].a, 0);
        mark(flip ? c[j].a : c[j].b, 1);
      }
    };
    queue_.clear();
    take(seed, false);
    for (std::size_t head = 0; head < queue_.size(); ++head) {
      const std::uint32_t i = queue_[head];
      const bool fi = flipped[g.first + i] != 0;
      const ParticleId ai = fi ? c[i].b : c[i].a, bi = fi ? c[i].a : c[i].b;
      const Vec3 ni = fi ? Vec3(-c[i].normal) : c[i].normal;
      const auto consider = [&](std::uint32_t j) {
        if (patchOf_[j] != kFree) return;
        // the side each of its particles is on (self-contact: as the patch has them, or by its direction)
        bool fj = false;
        if (self) {
          const int sa = sideOf(c[j].a), sb = sideOf(c[j].b);
          if (sa == 0 || sb == 1) fj = false;
          else if (sa == 1 || sb == 0) fj = true;
          else fj = c[j].normal.dot(patchDirection) < 0.0;
          if ((fj ? sb : sa) == 1 || (fj ? sa : sb) == 0) return;  // a particle would be on both sides
        }
        const ParticleId aj = fj ? c[j].b : c[j].a, bj = fj ? c[j].a : c[j].b;
        if (!near(ai, aj)) return;
        if (!plane && !near(bi, bj)) return;
        const Vec3 nj = fj ? Vec3(-c[j].normal) : c[j].normal;
        if (!(ni.dot(nj) > kCentreLines)) return;
        const Vec3 dj = fj ? Vec3(-directions_[j]) : directions_[j];
        if (directed && surface_[j] && !(dj.dot(patchDirection) >= minCos)) return;
        take(j, fj);
      };
      // candidates: the contacts of A's particle and of its connector neighbours
      const auto visit = [&](ParticleId x) {
        if (self) {
          const auto [lo, hi] = std::equal_range(byParticle_.begin(), byParticle_.end(), std::make_pair(x, 0u),
                                                 [](const auto& l, const auto& r) { return l.first < r.first; });
          for (auto it = lo; it != hi; ++it) consider(it->second);
          return;
        }
        const auto [lo, hi] = std::equal_range(c, c + m, x, [](const auto& l, const auto& r) {
          if constexpr (std::is_same_v<std::decay_t<decltype(l)>, ParticleContact>) return l.a < r;
          else return l < r.a;
        });
        for (const ParticleContact* cj = lo; cj != hi; ++cj) consider(static_cast<std::uint32_t>(cj - c));
      };
      visit(ai);
      for (const ParticleId n : in.finder->neighbours(ai)) visit(n);
    }
    // (canonical order: the patch's contacts ascending, which the next step's reuse keeps)
    std::sort(order.begin() + static_cast<std::ptrdiff_t>(start), order.end());
    sizes.push_back(static_cast<std::uint32_t>(order.size() - start));
  }
  // patches in the order of their first contacts
  std::uint32_t first = 0;
  scratch_.clear();
  for (std::uint32_t k = 0; k < sizes.size(); ++k) {
    scratch_.push_back(k);
    patchOf_[k] = first;  // (reused as each patch's start)
    first += sizes[k];
  }
  std::sort(scratch_.begin(), scratch_.end(), [&](std::uint32_t x, std::uint32_t y) { return order[patchOf_[x]] < order[patchOf_[y]]; });
  queue_.clear();
  seeds_.clear();
  for (const std::uint32_t k : scratch_) {
    queue_.insert(queue_.end(), order.begin() + patchOf_[k], order.begin() + patchOf_[k] + sizes[k]);
    seeds_.push_back(sizes[k]);
  }
  order.swap(queue_);
  sizes.assign(seeds_.begin(), seeds_.end());
}

std::size_t PatchBuilder::split(const NarrowPhaseInput& in, const ContactSet& set, std::span<std::uint32_t> idx,
                                std::span<const std::uint8_t> flipped) {
  const std::size_t n = idx.size();
  // the contacts' directions: split across their widest spread when they spread more than a few degrees,
  // otherwise across the widest spread of their points
  directions_.resize(n);
  Vec3 mean = Vec3::Zero(), centre = Vec3::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const ParticleContact& c = set.contacts[idx[k]];
    direction(in, c, directions_[k]);
    if (!flipped.empty() && flipped[idx[k]]) directions_[k] = -directions_[k];
    mean += directions_[k];
    centre += c.point;
  }
  mean /= static_cast<double>(n);
  centre /= static_cast<double>(n);
  Mat3 spreadDirections = Mat3::Zero(), spreadPoints = Mat3::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 d = directions_[k] - mean, p = set.contacts[idx[k]].point - centre;
    spreadDirections += d * d.transpose();
    spreadPoints += p * p.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> byDirection(spreadDirections / static_cast<double>(n));
  const bool turning = byDirection.eigenvalues()[2] > std::pow(std::sin(0.1), 2);
  const Eigen::SelfAdjointEigenSolver<Mat3> byPoint(spreadPoints);
  const Vec3 axis = turning ? Vec3(byDirection.eigenvectors().col(2)) : Vec3(byPoint.eigenvectors().col(2));
  keys_.resize(n);
  scratch_.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    keys_[k] = turning ? (directions_[k] - mean).dot(axis) : (set.contacts[idx[k]].point - centre).dot(axis);
    scratch_[k] = static_cast<std::uint32_t>(k);
  }
  std::sort(scratch_.begin(), scratch_.end(), [&](std::uint32_t x, std::uint32_t y) {
    return keys_[x] < keys_[y] || (!(keys_[y] < keys_[x]) && x < y);  // (ties in order, without a heap buffer)
  });
  std::vector<std::uint32_t>& sorted = seeds_;  // (scratch)
  sorted.resize(n);
  for (std::size_t k = 0; k < n; ++k) sorted[k] = idx[scratch_[k]];
  std::copy(sorted.begin(), sorted.end(), idx.begin());
  return n / 2;
}

}  // namespace volpar
