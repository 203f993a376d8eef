#include "volpar/collision/particle_contacts.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

namespace volpar {

namespace {

/// The skin of a rigid pair's candidate list, as a fraction of the sum of the two bodies' largest radii: a
/// wider skin lists more pairs to test each step but searches the grids again less often (a collapsing pile
/// moves its neighbours by a centimetre in a few steps).
constexpr double kListSkin = 0.25;

/// The contact of particles a and b (world positions, radii) at centre distance squared `dist2`, whose radii
/// sum to `rsum` (what touch() and the processes' merge both compute it from, with the same arithmetic).
[[gnu::always_inline]] inline void pairContact(const ParticleStore& p, ParticleId a, ParticleId b, const Vec3& d,
                                               double rsum, double dist2, ParticleContact& c) {
  const double dist = std::sqrt(dist2);
  c.a = a;
  c.b = b;
  c.plane = PlaneId{};
  // coincident centres have no centre line: fall back to +z
  c.normal = dist > 1e-12 * rsum ? Vec3(d / dist) : Vec3::UnitZ();
  c.depth = rsum - dist;
  c.point = p.position[a.index()] + c.normal * (p.radius[a.index()] - 0.5 * c.depth);
}

/// The same contact from the two ids alone (particles a and b, found touching by the search).
[[gnu::always_inline]] inline void pairContact(const ParticleStore& p, ParticleId a, ParticleId b, ParticleContact& c) {
  const Vec3 d = p.position[b.index()] - p.position[a.index()];
  pairContact(p, a, b, d, p.radius[a.index()] + p.radius[b.index()], d.squaredNorm(), c);
}

/// Whether particles a and b (world positions, radii) touch, or come within `margin` x (r_a + r_b) plus
/// `sweep` [m] of touching: touch()'s test alone.
[[gnu::always_inline]] inline bool withinReach(const ParticleStore& p, ParticleId a, ParticleId b, double margin,
                                               double sweep) {
  const double rsum = p.radius[a.index()] + p.radius[b.index()];
  const double dist2 = (p.position[b.index()] - p.position[a.index()]).squaredNorm();
  const double reach = rsum * (1.0 + margin) + sweep;
  return dist2 < reach * reach;
}

/// Contact between particles a and b if they are withinReach() (a speculative contact, negative depth, where
/// they do not touch).
[[gnu::always_inline]] inline bool touch(const ParticleStore& p, ParticleId a, ParticleId b, double margin, double sweep,
                                        ParticleContact& c) {
  if (!withinReach(p, a, b, margin, sweep)) return false;
  pairContact(p, a, b, c);
  return true;
}

/// Height of particle pi's centre above plane pl [m].
double heightAbove(const ParticleStore& p, ParticleId pi, const Plane& pl) {
  return pl.normal.dot(p.position[pi.index()]) - pl.offset;
}

/// The contact of particle pi with plane `plane` (pl), its centre `height` above it.
void planeContact(const ParticleStore& p, ParticleId pi, PlaneId plane, const Plane& pl, double height,
                  ParticleContact& c) {
  const double r = p.radius[pi.index()];
  c.a = pi;
  c.b = ParticleId{};
  c.plane = plane;
  c.normal = -pl.normal;
  c.depth = r - height;
  // midpoint between the particle's lowest point and its foot on the plane
  c.point = p.position[pi.index()] - pl.normal * (0.5 * (r + height));
}

/// Cell index of coordinate v (grid origin o, cell width w), clamped to [-1, n] before the integer
/// conversion so that far-away or huge coordinates cannot overflow.
int cellIndex(double v, double o, double w, int n) {
  const double c = std::floor((v - o) / w);
  return static_cast<int>(std::clamp(c, -1.0, static_cast<double>(n)));
}

void sortGroup(ContactSet& out, std::uint32_t first) {
  std::sort(out.contacts.begin() + first, out.contacts.end(), [](const ParticleContact& x, const ParticleContact& y) {
    return x.a != y.a ? x.a < y.a : x.b < y.b;
  });
}

}  // namespace

void ContactFinder::buildGrid(BodyGrid& g, std::span<const ParticleId> ids, std::span<const Vec3> coords,
                              const ParticleStore& particles) {
  Aabb box;
  g.maxRadius = 0.0;
  for (const ParticleId id : ids) {
    box.extend({coords[id.index()], coords[id.index()]});
    g.maxRadius = std::max(g.maxRadius, particles.radius[id.index()]);
  }
  // cells one diameter wide; grown if a sparse body would need too many
  g.cell = std::max(2.0 * g.maxRadius, 1e-9);
  const Vec3 extent = box.hi - box.lo;
  const double maxCells = 8.0 * static_cast<double>(ids.size()) + 64.0;
  while ((extent / g.cell + Vec3::Ones()).prod() > maxCells) g.cell *= 2.0;
  g.origin = box.lo;
  for (int k = 0; k < 3; ++k) g.dims[k] = static_cast<int>(std::floor(extent[k] / g.cell)) + 1;
  const std::size_t cells = static_cast<std::size_t>(g.dims.x()) * static_cast<std::size_t>(g.dims.y()) * static_cast<std::size_t>(g.dims.z());
  auto cellOf = [&](const Vec3& x) {
    Eigen::Vector3i c;
    for (int k = 0; k < 3; ++k) c[k] = std::clamp(cellIndex(x[k], g.origin[k], g.cell, g.dims[k]), 0, g.dims[k] - 1);
    return (static_cast<std::size_t>(c.z()) * static_cast<std::size_t>(g.dims.y()) + static_cast<std::size_t>(c.y())) *
               static_cast<std::size_t>(g.dims.x()) + static_cast<std::size_t>(c.x());
  };
  // counting sort of the particles by cell (stable: ascending ids within a cell)
  g.cellStart.assign(cells + 1, 0);
  for (const ParticleId id : ids) ++g.cellStart[cellOf(coords[id.index()]) + 1];
  for (std::size_t c = 0; c < cells; ++c) g.cellStart[c + 1] += g.cellStart[c];
  g.items.resize(ids.size());
  fill_.assign(g.cellStart.begin(), g.cellStart.end() - 1);
  for (const ParticleId id : ids) g.items[fill_[cellOf(coords[id.index()])]++] = id;
}

void ContactFinder::addBody(BodyId id, const ParticleStore& particles, const BodyStore& bodies) {
  if (grids_.size() <= id.index()) grids_.resize(id.index() + 1);
  BodyGrid& g = grids_[id.index()];
  const BodyInfo& info = bodies.info[id.index()];
  if (info.kind == BodyKind::Deformable) {
    g.worldFrame = true;
    deformables_.push_back(id);
    buildGrid(g, info.particles, particles.position, particles);
  } else {
    g.worldFrame = false;
    buildGrid(g, info.particles, particles.local, particles);
  }
  if (runs_.size() <= id.index()) runs_.resize(id.index() + 1);
  runs_[id.index()] = runOf(info.particles);
  if (extent_.size() <= id.index()) extent_.resize(id.index() + 1, 0.0);
  double extent = 0.0;
  for (const ParticleId p : info.particles) extent = std::max(extent, particles.local[p.index()].norm());
  extent_[id.index()] = extent;
  adjacencyDirty_ = true;
}

void ContactFinder::rebuildAdjacency(const ParticleStore& particles, const ConnectorStore& connectors) {
  const std::size_t n = particles.size();
  adjacencyStart_.assign(n + 1, 0);
  for (std::size_t c = 0; c < connectors.size(); ++c) {
    if (connectors.broken[c]) continue;
    ++adjacencyStart_[connectors.a[c].index() + 1];
    ++adjacencyStart_[connectors.b[c].index() + 1];
  }
  for (std::size_t i = 0; i < n; ++i) adjacencyStart_[i + 1] += adjacencyStart_[i];
  adjacency_.resize(adjacencyStart_[n]);
  fill_.assign(adjacencyStart_.begin(), adjacencyStart_.end() - 1);
  for (std::size_t c = 0; c < connectors.size(); ++c) {
    if (connectors.broken[c]) continue;
    adjacency_[fill_[connectors.a[c].index()]++] = connectors.b[c];
    adjacency_[fill_[connectors.b[c].index()]++] = connectors.a[c];
  }
  for (std::size_t i = 0; i < n; ++i)
    std::sort(adjacency_.begin() + adjacencyStart_[i], adjacency_.begin() + adjacencyStart_[i + 1]);
  adjacencyDirty_ = false;
}

bool ContactFinder::connected(ParticleId a, ParticleId b) const {
  if (a.index() + 1 >= adjacencyStart_.size()) return false;
  const auto first = adjacency_.begin() + adjacencyStart_[a.index()];
  const auto last = adjacency_.begin() + adjacencyStart_[a.index() + 1];
  return std::binary_search(first, last, b);
}

template <class F>
void ContactFinder::forCells(const BodyGrid& g, const BodyState& s, const Aabb& box, F&& f) const {
  // the world box in the grid's frame (a rotated box's bounds)
  Vec3 centre = box.centre(), half = 0.5 * (box.hi - box.lo);
  if (!g.worldFrame) {
    const Mat3 rt = s.orientation.toRotationMatrix().transpose();
    centre = rt * (centre - s.position);
    half = rt.cwiseAbs() * half;
  }
  Eigen::Vector3i lo, hi;
  for (int k = 0; k < 3; ++k) {
    lo[k] = std::max(0, cellIndex(centre[k] - half[k], g.origin[k], g.cell, g.dims[k]));
    hi[k] = std::min(g.dims[k] - 1, cellIndex(centre[k] + half[k], g.origin[k], g.cell, g.dims[k]));
    if (lo[k] > hi[k]) return;
  }
  for (int z = lo.z(); z <= hi.z(); ++z)
    for (int y = lo.y(); y <= hi.y(); ++y) {
      const std::size_t row = (static_cast<std::size_t>(z) * static_cast<std::size_t>(g.dims.y()) + static_cast<std::size_t>(y)) *
                              static_cast<std::size_t>(g.dims.x());
      for (std::size_t c = row + static_cast<std::size_t>(lo.x()); c <= row + static_cast<std::size_t>(hi.x()); ++c)
        for (std::uint32_t i = g.cellStart[c]; i < g.cellStart[c + 1]; ++i) f(g.items[i]);
    }
}

void ContactFinder::gatherMotion(const BodyStore& bodies, ThreadPool* pool) {
  motion_.resize(grids_.size());
  const auto gather = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i < end; ++i) {
      const BodyState& s = bodies.state[i];
      BodyMotion& m = motion_[i];
      m.velocity = s.linearVelocity;
      m.spin = s.angularVelocity.norm() * extent_[i];
      m.margin = margin_ * grids_[i].maxRadius;
      m.worldFrame = grids_[i].worldFrame;
    }
  };
  if (pool && pool->worthSharing(grids_.size(), 256)) pool->run(grids_.size(), gather);
  else gather(0, 0, grids_.size());
}

double ContactFinder::sweepReach(BodyId a, BodyId b, const Vec3& n) const {
  if (sweepTime_ <= 0.0) return 0.0;
  const BodyMotion& ma = motion_[a.index()];
  double closing = ma.spin;
  double reach = ma.margin;
  if (b.valid()) {
    const BodyMotion& mb = motion_[b.index()];
    closing += (mb.velocity - ma.velocity).norm() + mb.spin;
    reach += mb.margin;
  } else {
    closing += std::max(0.0, -n.dot(ma.velocity));
  }
  // (a reach the pair's motion cannot make infinite; the search stays inside the other body's grid however far
  // it reaches)
  const double sweep = std::max(0.0, closing * sweepTime_ - reach);
  return std::isfinite(sweep) ? sweep : 0.0;
}

void ContactFinder::searchPair(const ParticleStore& p, const BodyStore& bodies, BodyId a, BodyId b,
                               std::span<const Aabb> boxes, double sweep, double skin, ContactSet& out,
                               std::vector<std::pair<ParticleId, ParticleId>>* listed,
                               std::array<std::vector<ParticleId>, 2>& near) const {
  // the boxes grown by the speculative reach (and the sweep and the skin)
  const double grow = margin_ * (grids_[a.index()].maxRadius + grids_[b.index()].maxRadius) + sweep + skin;
  const Aabb boxA = boxes[a.index()].expanded(grow);
  const Aabb boxB = boxes[b.index()].expanded(grow);
  const Aabb overlap{boxA.lo.cwiseMax(boxB.lo), boxA.hi.cwiseMin(boxB.hi)};
  if (!overlap.valid()) return;
  // a particle pair found by either search: listed within the skin, a contact within the reach
  ParticleContact c;
  const auto consider = [&](ParticleId pa, ParticleId pb) {
    if (listed) {
      const double rs = (p.radius[pa.index()] + p.radius[pb.index()]) * (1.0 + margin_) + sweep + skin;
      if ((p.position[pb.index()] - p.position[pa.index()]).squaredNorm() < rs * rs) listed->emplace_back(pa, pb);
    }
    if (touch(p, pa, pb, margin_, sweep, c)) out.contacts.push_back(c);
  };
  const std::size_t count0 = runs_[a.index()].count, count1 = runs_[b.index()].count;
  if (count0 <= kFewParticles && count1 <= kFewParticles) {
    // small bodies: every pair of the particles whose reach overlaps the other's grown box (a pair within
    // reach has both; the set of pairs found, which the caller sorts, is the grids')
    const auto gather = [&](BodyId body, const Aabb& other, std::vector<ParticleId>& into) {
      into.clear();
      forParticles(bodies, body, [&](ParticleId q) {
        if (Aabb::sphere(p.position[q.index()], p.radius[q.index()] + sweep + skin).overlaps(other)) into.push_back(q);
      });
    };
    gather(a, boxB, near[0]);
    if (near[0].empty()) return;
    gather(b, boxA, near[1]);
    for (const ParticleId pa : near[0])
      for (const ParticleId pb : near[1]) consider(pa, pb);
    return;
  }
  // iterate the body with fewer particles, look up the other's grid
  const bool iterateA = count0 <= count1;
  const BodyId it = iterateA ? a : b;
  const BodyId other = iterateA ? b : a;
  const BodyGrid& gi = grids_[it.index()];
  const BodyGrid& go = grids_[other.index()];
  const BodyState& so = bodies.state[other.index()];
  const Mat3 rtOther = so.orientation.toRotationMatrix().transpose();
  forCells(gi, bodies.state[it.index()], overlap.expanded(gi.maxRadius), [&](ParticleId pi) {
    const Vec3& x = p.position[pi.index()];
    // (a hair wider than the largest sum of radii, so rounding in the frame change cannot drop a pair)
    const double reach = (p.radius[pi.index()] + go.maxRadius) * (1.0 + margin_ + 1e-9) + sweep + skin;
    if (!Aabb::sphere(x, p.radius[pi.index()] + sweep + skin).overlaps(iterateA ? boxB : boxA)) return;
    // the particle's reach in the other grid's frame
    const Vec3 y = go.worldFrame ? x : Vec3(rtOther * (x - so.position));
    Eigen::Vector3i lo, hi;
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::max(0, cellIndex(y[k] - reach, go.origin[k], go.cell, go.dims[k]));
      hi[k] = std::min(go.dims[k] - 1, cellIndex(y[k] + reach, go.origin[k], go.cell, go.dims[k]));
      if (lo[k] > hi[k]) return;
    }
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int yy = lo.y(); yy <= hi.y(); ++yy) {
        const std::size_t row = (static_cast<std::size_t>(z) * static_cast<std::size_t>(go.dims.y()) + static_cast<std::size_t>(yy)) *
                                static_cast<std::size_t>(go.dims.x());
        for (std::size_t cell = row + static_cast<std::size_t>(lo.x()); cell <= row + static_cast<std::size_t>(hi.x()); ++cell)
          for (std::uint32_t k = go.cellStart[cell]; k < go.cellStart[cell + 1]; ++k) {
            const ParticleId q = go.items[k];
            consider(iterateA ? pi : q, iterateA ? q : pi);
          }
      }
  });
}

void ContactFinder::bodyPair(const ParticleStore& p, const BodyStore& bodies, BodyId a, BodyId b,
                             std::span<const Aabb> boxes, Chunk& w) const {
  ContactSet& out = w.out;
  const std::uint32_t first = static_cast<std::uint32_t>(out.contacts.size());
  const bool rigid = !motion_[a.index()].worldFrame && !motion_[b.index()].worldFrame;
  const double swept = sweepReach(a, b);
  // (boxes farther apart than the reach: no contact, and no list to keep; a list is made afresh once they
  // come within reach, and finds what a kept one would)
  const double reach = (motion_[a.index()].margin + motion_[b.index()].margin + swept) * (1.0 + 1e-6);
  if (!boxes[a.index()].expanded(reach).overlaps(boxes[b.index()].expanded(reach))) return;
  if (!reuse_ || !rigid) {
    searchPair(p, bodies, a, b, boxes, swept, 0.0, out, nullptr, w.near);
    sortGroup(out, first);
  } else {
    // B's pose in A's frame
    const BodyState& sa = bodies.state[a.index()];
    const BodyState& sb = bodies.state[b.index()];
    const Quat relRotation = sa.orientation.conjugate() * sb.orientation;
    const Vec3 relPosition = sa.orientation.conjugate() * (sb.position - sa.position);
    // (the body pairs come sorted, like the lists: a worker's cursor only moves forward)
    const auto key = std::make_pair(a.value, b.value);
    while (w.cursor < cache_.lists.size() && std::make_pair(cache_.lists[w.cursor].a, cache_.lists[w.cursor].b) < key)
      ++w.cursor;
    const auto it = cache_.lists.begin() + static_cast<std::ptrdiff_t>(w.cursor);
    bool reuse = it != cache_.lists.end() && it->a == a.value && it->b == b.value;
    if (reuse) {
      // how far any particle pair's distance can have changed since the list was made
      const double turned = 2.0 * (it->relRotation.conjugate() * relRotation).vec().norm();
      reuse = turned * extent_[b.index()] + (relPosition - it->relPosition).norm() < it->skin && swept <= it->sweep;
    }
    PairList list;
    list.a = a.value;
    list.b = b.value;
    list.first = static_cast<std::uint32_t>(w.cache.pairs.size());
    if (reuse) {
      ++w.reused;
      list.relRotation = it->relRotation;
      list.relPosition = it->relPosition;
      list.skin = it->skin;
      list.sweep = it->sweep;
      const auto* listed = cache_.pairs.data() + it->first;
      w.cache.pairs.insert(w.cache.pairs.end(), listed, listed + it->count);
      // touch() in two passes: the pairs withinReach(), marked without a branch (in pile-1000 about four
      // listed pairs in ten are, in no pattern a branch predictor could follow), then their contacts
      if (w.hits.size() < it->count) w.hits.resize(it->count);
      std::uint32_t hits = 0;
      for (std::uint32_t k = 0; k < it->count; ++k) {
        w.hits[hits] = k;
        hits += withinReach(p, listed[k].first, listed[k].second, margin_, swept) ? 1u : 0u;
      }
      ParticleContact c;
      for (std::uint32_t h = 0; h < hits; ++h) {
        const auto& [pa, pb] = listed[w.hits[h]];
        pairContact(p, pa, pb, c);
        out.contacts.push_back(c);
      }
    } else {
      list.relRotation = relRotation;
      list.relPosition = relPosition;
      list.skin = kListSkin * (grids_[a.index()].maxRadius + grids_[b.index()].maxRadius);
      // (a pair speeding up lists a little farther than it needs, so that it is not searched every step)
      list.sweep = 1.5 * swept;
      w.found.clear();
      searchPair(p, bodies, a, b, boxes, swept, list.skin + (list.sweep - swept), out, &w.found, w.near);
      sortGroup(out, first);
      std::sort(w.found.begin(), w.found.end());
      w.cache.pairs.insert(w.cache.pairs.end(), w.found.begin(), w.found.end());
    }
    list.count = static_cast<std::uint32_t>(w.cache.pairs.size()) - list.first;
    w.cache.lists.push_back(list);  // an empty list too: nothing comes within reach until B moves by the skin
  }
  const auto count = static_cast<std::uint32_t>(out.contacts.size()) - first;
  if (count == 0) return;
  out.groups.push_back({a, b, PlaneId{}, first, count});
}

void ContactFinder::selfContacts(const ParticleStore& p, BodyId id, ContactSet& out) const {
  const BodyGrid& g = grids_[id.index()];
  const std::uint32_t first = static_cast<std::uint32_t>(out.contacts.size());
  ParticleContact c;
  for (const ParticleId pi : g.items) {
    const Vec3& x = p.position[pi.index()];
    forCells(g, BodyState{}, Aabb::sphere(x, (p.radius[pi.index()] + g.maxRadius) * (1.0 + margin_)), [&](ParticleId q) {
      if (!(pi < q) || connected(pi, q)) return;
      if (touch(p, pi, q, margin_, 0.0, c)) out.contacts.push_back(c);
    });
  }
  const auto count = static_cast<std::uint32_t>(out.contacts.size()) - first;
  if (count == 0) return;
  sortGroup(out, first);
  out.groups.push_back({id, id, PlaneId{}, first, count});
}

void ContactFinder::planeContacts(const ParticleStore& p, const BodyStore& bodies, BodyId id, PlaneId plane,
                                  const Plane& pl, ContactSet& out) const {
  const std::uint32_t first = static_cast<std::uint32_t>(out.contacts.size());
  const double swept = sweepReach(id, BodyId{}, pl.normal);
  forParticles(bodies, id, [&](ParticleId pi) {
    const double r = p.radius[pi.index()];
    const double height = heightAbove(p, pi, pl);
    if (!(height < r * (1.0 + margin_) + swept)) return;
    ParticleContact c;
    planeContact(p, pi, plane, pl, height, c);
    out.contacts.push_back(c);
  });
  const auto count = static_cast<std::uint32_t>(out.contacts.size()) - first;
  if (count > 0) out.groups.push_back({id, BodyId{}, plane, first, count});
}

void ContactFinder::find(const ParticleStore& particles, const BodyStore& bodies, const ConnectorStore& connectors,
                         std::span<const BodyPair> pairs, std::span<const BodyPlanePair> planePairs,
                         std::span<const Plane> planes, std::span<const Aabb> boxes, ContactSet& out,
                         ThreadPool* pool) {
  if (adjacencyDirty_) rebuildAdjacency(particles, connectors);
  for (const BodyId id : deformables_) buildGrid(grids_[id.index()], bodies.info[id.index()].particles, particles.position, particles);
  gatherMotion(bodies, pool);
  const int ranks = processes_ ? processes_->size() : 1;
  if (ranks == 1) {
    search(particles, bodies, pairs, planePairs, planes, deformables_, boxes, out, pool);
    return;
  }
  // this process's contiguous share of each kind of pair: of the body pairs, the share that the processes'
  // search times of the last step make even (every process divides alike from the same times; the
  // contacts found do not depend on the division), of the planes' pairs and self-contacts an equal share
  const int me = processes_->rank();
  const auto count = static_cast<std::size_t>(ranks);
  if (boundary_.size() != count + 1) {
    boundary_.resize(count + 1);
    for (std::size_t r = 0; r <= count; ++r) boundary_[r] = static_cast<double>(r) / static_cast<double>(count);
  }
  const auto share = [&](auto all) {
    const std::size_t first = firstShare(me, ranks, all.size()), last = firstShare(me + 1, ranks, all.size());
    return all.subspan(first, last - first);
  };
  const auto at = [&](std::size_t r) {
    const auto n = static_cast<double>(pairs.size());
    return r == count ? pairs.size() : std::min(pairs.size(), static_cast<std::size_t>(boundary_[r] * n));
  };
  // (the boundaries never decrease: moveBoundaries() keeps them in order)
  const std::size_t pairFirst = at(static_cast<std::size_t>(me)), pairLast = at(static_cast<std::size_t>(me) + 1);
  const auto started = std::chrono::steady_clock::now();
  const auto [bodyGroups, planeGroups] =
      search(particles, bodies, pairs.subspan(pairFirst, pairLast - pairFirst), share(planePairs), planes,
             share(std::span<const BodyId>(deformables_)), boxes, mine_, pool);
  searchSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  gatherShares(particles, planes, mine_, bodyGroups, planeGroups, out, pool);
}

std::pair<std::size_t, std::size_t> ContactFinder::search(const ParticleStore& particles, const BodyStore& bodies,
                                                          std::span<const BodyPair> pairs,
                                                          std::span<const BodyPlanePair> planePairs,
                                                          std::span<const Plane> planes, std::span<const BodyId> deformables,
                                                          std::span<const Aabb> boxes, ContactSet& out, ThreadPool* pool) {
  // (out keeps its size until the merge below resizes it: only entries beyond the last step's are
  // initialised before they are overwritten)
  // body pairs, then bodies on planes, in one contiguous range per worker, sized by the ranges' costs in
  // the last search and cut into pieces (chunks) that workers done with their own take over (PacedSplit:
  // each worker then reads one part of the particles, in its own cache, where many small chunks taken as
  // they come made every worker read all of them); the chunks' outputs are merged in order, all body
  // pairs' contacts first, then all planes'
  const bool shared = pool && pool->worthSharing(pairs.size(), 512);
  const int workers = shared ? pool->workers() : 1;
  const std::size_t chunks = shared ? PacedSplit::pieces(workers) : 1;
  if (chunks_.size() < chunks) chunks_.resize(chunks);
  for (std::size_t k = 0; k < chunks; ++k) {
    chunks_[k].out.clear();
    chunks_[k].planes.clear();
    chunks_[k].cache.clear();
    chunks_[k].reused = 0;
  }
  std::size_t onlyChunkBodyGroups = 0;
  const auto work = [&](int, std::size_t k, std::size_t begin, std::size_t end) {
    Chunk& w = chunks_[k];
    // (whether this range's pairs come in key order, after the range before: the lists follow the pairs, so
    // they are in key order, which lookups need, where every range's pairs are)
    w.inOrder = std::is_sorted(pairs.begin() + static_cast<std::ptrdiff_t>(begin), pairs.begin() + static_cast<std::ptrdiff_t>(end)) &&
                (begin == 0 || begin >= end || !(pairs[begin] < pairs[begin - 1]));
    // where this range's pairs start among the last step's lists
    w.cursor = 0;
    if (begin < end) {
      const auto first = std::make_pair(pairs[begin].a.value, pairs[begin].b.value);
      w.cursor = static_cast<std::size_t>(
          std::lower_bound(cache_.lists.begin(), cache_.lists.end(), first,
                           [](const PairList& l, const std::pair<std::uint32_t, std::uint32_t>& key) {
                             return std::make_pair(l.a, l.b) < key;
                           }) -
          cache_.lists.begin());
    }
    for (std::size_t i = begin; i < end; ++i) bodyPair(particles, bodies, pairs[i].a, pairs[i].b, boxes, w);
    // (one chunk: the planes' contacts follow the body pairs' in its own output, already in their order)
    if (chunks == 1) onlyChunkBodyGroups = w.out.groups.size();
    ContactSet& planesOut = chunks == 1 ? w.out : w.planes;
    for (std::size_t i = planePairs.size() * k / chunks; i < planePairs.size() * (k + 1) / chunks; ++i)
      planeContacts(particles, bodies, planePairs[i].body, planePairs[i].plane, planes[planePairs[i].plane.index()], planesOut);
  };
  if (shared) pairSplit_.run(*pool, workers, pairs.size(), work);
  else work(0, 0, 0, pairs.size());
  // lookups need the lists in key order (body pairs come sorted; if a caller's do not, nothing is reused,
  // which finds the same contacts)
  const auto checkOrder = [&] {
    if (!std::all_of(chunks_.begin(), chunks_.begin() + static_cast<std::ptrdiff_t>(chunks), [](const Chunk& w) { return w.inOrder; }))
      cache_.clear();
  };
  if (chunks == 1) {
    // the one chunk's output and lists are the result as they stand: exchanged, not copied (the chunk
    // takes the last step's buffers, which it clears and refills in the next)
    Chunk& w = chunks_[0];
    reusedPairs_ = w.reused;
    std::swap(out.contacts, w.out.contacts);
    std::swap(out.groups, w.out.groups);
    std::swap(cache_.lists, w.cache.lists);
    std::swap(cache_.pairs, w.cache.pairs);
    checkOrder();
    const std::size_t groupsOfPlanes = out.groups.size() - onlyChunkBodyGroups;
    for (const BodyId id : deformables) selfContacts(particles, id, out);
    return {onlyChunkBodyGroups, groupsOfPlanes};
  }
  // the chunks' outputs at their places, copied by the workers
  reusedPairs_ = 0;
  std::size_t contacts = 0, groups = 0, lists = 0, listed = 0;
  for (std::size_t k = 0; k < chunks; ++k) {
    Chunk& w = chunks_[k];
    w.contactBase = contacts;
    w.groupBase = groups;
    w.listBase = lists;
    w.pairBase = listed;
    contacts += w.out.contacts.size();
    groups += w.out.groups.size();
    lists += w.cache.lists.size();
    listed += w.cache.pairs.size();
    reusedPairs_ += w.reused;
  }
  const std::size_t bodyGroups = groups;
  for (std::size_t k = 0; k < chunks; ++k) {
    Chunk& w = chunks_[k];
    w.planeContactBase = contacts;
    w.planeGroupBase = groups;
    contacts += w.planes.contacts.size();
    groups += w.planes.groups.size();
  }
  out.contacts.resize(contacts);
  out.groups.resize(groups);
  cache_.lists.resize(lists);
  cache_.pairs.resize(listed);
  const auto place = [&](const ContactSet& from, std::size_t contactBase, std::size_t groupBase) {
    std::copy(from.contacts.begin(), from.contacts.end(), out.contacts.begin() + static_cast<std::ptrdiff_t>(contactBase));
    for (std::size_t i = 0; i < from.groups.size(); ++i) {
      ContactGroup g = from.groups[i];
      g.first += static_cast<std::uint32_t>(contactBase);
      out.groups[groupBase + i] = g;
    }
  };
  const auto copy = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const Chunk& w = chunks_[k];
      place(w.out, w.contactBase, w.groupBase);
      place(w.planes, w.planeContactBase, w.planeGroupBase);
      for (std::size_t i = 0; i < w.cache.lists.size(); ++i) {
        PairList l = w.cache.lists[i];
        l.first += static_cast<std::uint32_t>(w.pairBase);
        cache_.lists[w.listBase + i] = l;
      }
      std::copy(w.cache.pairs.begin(), w.cache.pairs.end(), cache_.pairs.begin() + static_cast<std::ptrdiff_t>(w.pairBase));
    }
  };
  if (shared) pool->run(chunks, copy);
  else copy(0, 0, chunks);
  checkOrder();
  for (const BodyId id : deformables) selfContacts(particles, id, out);
  return {bodyGroups, groups - bodyGroups};
}

void ContactFinder::gatherShares(const ParticleStore& particles, std::span<const Plane> planes, const ContactSet& mine,
                                 std::size_t bodyGroups, std::size_t planeGroups, ContactSet& out, ThreadPool* pool) {
  // what travels: how many groups of body pairs and of planes lead, the groups, and each contact's two
  // particle ids (the rest of a contact follows from them)
  ids_.resize(mine.contacts.size());
  for (std::size_t i = 0; i < mine.contacts.size(); ++i) ids_[i] = {mine.contacts[i].a, mine.contacts[i].b};
  const ShareHeader header{bodyGroups, planeGroups, searchSeconds_};
  bytes_.resize(sizeof header);
  std::memcpy(bytes_.data(), &header, sizeof header);
  appendBytes(bytes_, mine.groups);
  appendBytes(bytes_, ids_);
  processes_->gather(bytes_, gathered_);
  const auto ranks = static_cast<std::size_t>(processes_->size());
  const auto me = static_cast<std::uint32_t>(processes_->rank());
  if (shares_.size() < ranks) shares_.resize(ranks);
  const std::byte* at = gathered_.data();
  std::size_t groups = 0, contacts = 0;
  for (std::size_t r = 0; r < ranks; ++r) {
    Share& s = shares_[r];
    readBytes(at, s.header);
    readBytes(at, s.groups);
    readBytes(at, s.ids);
    groups += s.groups.size();
    contacts += s.ids.size();
  }
  // the groups in one process's order: every process's body pairs (the processes' shares follow each other
  // in the pairs' order), then every process's planes, then every process's self-contacts
  out.groups.resize(groups);
  out.contacts.resize(contacts);
  fromShare_.resize(groups);
  fromFirst_.resize(groups);
  std::size_t gi = 0;
  std::uint32_t first = 0;
  for (int kind = 0; kind < 3; ++kind)
    for (std::size_t r = 0; r < ranks; ++r) {
      const Share& s = shares_[r];
      const std::size_t planesFirst = s.header.bodyGroups, selfFirst = planesFirst + s.header.planeGroups;
      const std::size_t begin = kind == 0 ? 0 : kind == 1 ? planesFirst : selfFirst;
      const std::size_t end = kind == 0 ? planesFirst : kind == 1 ? selfFirst : s.groups.size();
      for (std::size_t k = begin; k < end; ++k, ++gi) {
        ContactGroup g = s.groups[k];
        fromShare_[gi] = static_cast<std::uint32_t>(r);
        fromFirst_[gi] = g.first;
        g.first = first;
        first += g.count;
        out.groups[gi] = g;
      }
    }
  // each contact made from its two ids as the search made it
  const auto make = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t g = begin; g < end; ++g) {
      const ContactGroup& group = out.groups[g];
      const std::pair<ParticleId, ParticleId>* ids = shares_[fromShare_[g]].ids.data() + fromFirst_[g];
      ParticleContact* c = out.contacts.data() + group.first;
      if (fromShare_[g] == me) {
        std::copy_n(mine.contacts.data() + fromFirst_[g], group.count, c);
      } else if (group.plane.valid()) {
        const Plane& pl = planes[group.plane.index()];
        for (std::uint32_t k = 0; k < group.count; ++k)
          planeContact(particles, ids[k].first, group.plane, pl, heightAbove(particles, ids[k].first, pl), c[k]);
      } else {
        for (std::uint32_t k = 0; k < group.count; ++k) pairContact(particles, ids[k].first, ids[k].second, c[k]);
      }
    }
  };
  if (pool && pool->worthSharing(groups, 256)) pool->run(groups, make);
  else make(0, 0, groups);
  moveBoundaries();
}

void ContactFinder::moveBoundaries() {
  // each process's share moved a tenth of the way towards one in proportion to its pace (pairs a second) in
  // the last step, when the slowest took a fifth longer than the fastest (a pair that changes process is
  // searched afresh by its new one: moving the division by much at once would slow the process that takes
  // the pairs over, and throw the division back)
  const std::size_t ranks = boundary_.size() - 1;
  pace_.resize(ranks);
  double paces = 0.0, slowest = 0.0, fastest = std::numeric_limits<double>::infinity();
  for (std::size_t r = 0; r < ranks; ++r) {
    const double seconds = shares_[r].header.seconds;
    pace_[r] = seconds > 0.0 ? (boundary_[r + 1] - boundary_[r]) / seconds : 0.0;
    paces += pace_[r];
    slowest = std::max(slowest, seconds);
    fastest = std::min(fastest, seconds);
  }
  if (!(paces > 0.0) || !std::isfinite(paces) || !(slowest > 1.2 * fastest)) return;
  double edge = 0.0;
  for (std::size_t r = 0; r + 1 < ranks; ++r) {
    edge += pace_[r] / paces;
    // (kept in order against rounding: each share must start where the one before it ends)
    boundary_[r + 1] = std::max(boundary_[r], boundary_[r + 1] + 0.1 * (edge - boundary_[r + 1]));
  }
}

}  // namespace volpar
