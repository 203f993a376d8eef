#include "collision/narrow_phase.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace volpar {

namespace {

std::uint32_t findRoot(std::vector<std::uint32_t>& parent, std::uint32_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

void unite(std::vector<std::uint32_t>& parent, std::uint32_t i, std::uint32_t j) {
  i = findRoot(parent, i);
  j = findRoot(parent, j);
  if (i == j) return;
  // the smaller index is the root: a patch is named by its first contact
  if (j < i) std::swap(i, j);
  parent[j] = i;
}

Vec3 particleVelocity(const ParticleStore& p, const BodyStore& bodies, ParticleId id) {
  const BodyId b = p.body[id.index()];
  const BodyInfo& info = bodies.info[b.index()];
  if (info.kind == BodyKind::Static) return Vec3::Zero();
  if (info.kind == BodyKind::Deformable) return p.velocity[id.index()];
  const BodyState& s = bodies.state[b.index()];
  return s.linearVelocity + s.angularVelocity.cross(p.position[id.index()] - s.position);
}

}  // namespace

const char* planeCaseName(PlaneCase c) {
  switch (c) {
    case PlaneCase::VertexFace11: return "vertex_face_1_1";
    case PlaneCase::VertexFace12: return "vertex_face_1_2";
    case PlaneCase::VertexFace13: return "vertex_face_1_3";
    case PlaneCase::EdgeEdge12: return "edge_edge_1_2";
    case PlaneCase::EdgeEdge22: return "edge_edge_2_2";
    case PlaneCase::EdgeEdge23: return "edge_edge_2_3_collinear";
    case PlaneCase::EdgeFace23: return "edge_face_2_3";
    case PlaneCase::EdgeFace33: return "edge_face_3_collinear_3";
    case PlaneCase::FaceFace: return "face_face";
    case PlaneCase::ParticlePlane: return "particle_plane";
  }
  return "unknown";
}

const char* normalSourceName(NormalSource s) {
  switch (s) {
    case NormalSource::FaceA: return "face_a";
    case NormalSource::FaceB: return "face_b";
    case NormalSource::LineLine: return "line_line";
    case NormalSource::LinePerpendicular: return "line_perpendicular";
    case NormalSource::LineContactPoints: return "line_contact_points";
    case NormalSource::NeighbourLine: return "neighbour_line";
    case NormalSource::CachedA: return "cached_a";
    case NormalSource::CachedB: return "cached_b";
    case NormalSource::CentreLine: return "centre_line";
    case NormalSource::Plane: return "plane";
    case NormalSource::Separation: return "separation";
    case NormalSource::Surface: return "surface";
    case NormalSource::ContactLines: return "contact_lines";
  }
  return "unknown";
}

Vec3 cachedWorldNormal(const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals, ParticleId p) {
  const std::int32_t k = particles.normalIndex[p.index()];
  if (k < 0) return Vec3::Zero();
  return bodies.state[particles.body[p.index()].index()].orientation * normals[k];
}

Vec3 NarrowPhase::worldNormal(const NarrowPhaseInput& in, ParticleId p) {
  return cachedWorldNormal(*in.particles, *in.bodies, *in.normals, p);
}

void NarrowPhase::clearCache() { cache_.clear(); }

bool NarrowPhase::cacheable(const NarrowPhaseInput& in, const ContactGroup& g) {
  if (g.a == g.b) return false;  // self-contact of a deformable body
  if (in.bodies->info[g.a.index()].kind == BodyKind::Deformable) return false;
  return g.plane.valid() || in.bodies->info[g.b.index()].kind != BodyKind::Deformable;
}

NarrowPhase::GroupKey NarrowPhase::keyOf(const ContactGroup& g) {
  return g.plane.valid() ? GroupKey{1, g.a.value, g.plane.value} : GroupKey{0, g.a.value, g.b.value};
}

void NarrowPhase::relativePose(const NarrowPhaseInput& in, const ContactGroup& g, Quat& rotation, Vec3& position) {
  const BodyState& a = in.bodies->state[g.a.index()];
  if (g.plane.valid()) {
    rotation = a.orientation;
    position = a.position;
    return;
  }
  const BodyState& b = in.bodies->state[g.b.index()];
  rotation = a.orientation.conjugate() * b.orientation;
  position = a.orientation.conjugate() * (b.position - a.position);
}

bool NarrowPhase::reusable(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                           const CachedGroup& c) const {
  if (c.pairCount != g.count) return false;
  const ParticleContact* contacts = set.contacts.data() + g.first;
  const auto* pairs = cache_.pairs.data() + c.pairFirst;
  for (std::uint32_t i = 0; i < g.count; ++i)
    if (contacts[i].a != pairs[i].first || contacts[i].b != pairs[i].second) return false;
  // a plane's patches depend on the contacts alone (the normal is the plane's)
  if (g.plane.valid()) return true;
  Quat rotation;
  Vec3 position;
  relativePose(in, g, rotation, position);
  const double turned = 2.0 * (c.relRotation.conjugate() * rotation).vec().norm();
  const ParticleStore& p = *in.particles;
  const double rsum = p.radius[contacts[0].a.index()] + p.radius[contacts[0].b.index()];
  return turned < settings_.reuseAngle && (position - c.relPosition).norm() < settings_.reuseShift * rsum;
}

void NarrowPhase::reuse(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, const CachedGroup& c,
                        Worker& w, PatchSet& out) const {
  const ParticleStore& p = *in.particles;
  const Quat& qa = in.bodies->state[g.a.index()].orientation;
  const bool plane = g.plane.valid();
  const std::size_t patchBegin = w.o->patches.size();
  std::uint32_t k = c.pairFirst;  // position in cache order (parallel to pairs)
  for (std::uint32_t j = 0; j < c.patchCount; ++j) {
    const CachedPatch& cp = cache_.patches[c.patchFirst + j];
    ContactPatch patch;
    patch.a = g.a;
    patch.b = g.b;
    patch.plane = g.plane;
    patch.normal = plane ? cp.normal : Vec3(qa * cp.normal);
    patch.margin = cp.margin;
    patch.planeCase = cp.planeCase;
    patch.source = cp.source;
    patch.validated = cp.validated;
    patch.lookAhead = cp.lookAhead;
    patch.first = static_cast<std::uint32_t>(w.o->contacts.size());
    patch.count = cp.count;
    // depths along the normal and the deepest point, from the current positions
    std::uint32_t deepest = g.first + cache_.order[k];
    patch.depth = 0.0;
    for (std::uint32_t i = 0; i < cp.count; ++i, ++k) {
      const std::uint32_t ci = g.first + cache_.order[k];
      w.o->contacts.push_back(ci);
      const ParticleContact& ct = set.contacts[ci];
      if (ct.depth > set.contacts[deepest].depth) deepest = ci;
      const double d = plane ? ct.depth
                             : p.radius[ct.a.index()] + p.radius[ct.b.index()] -
                                   patch.normal.dot(p.position[ct.b.index()] - p.position[ct.a.index()]);
      out.depthAlongNormal[ci] = d;
      patch.depth = std::max(patch.depth, d);
    }
    patch.point = set.contacts[deepest].point;
    ++w.o->stats.patches;
    ++w.o->stats.reused;
    ++w.o->stats.byCase[static_cast<std::size_t>(patch.planeCase)];
    if (!patch.validated) ++w.o->stats.unvalidated;
    w.o->patches.push_back(patch);
  }
  remember(in, set, g, patchBegin, w);
  // keep the pose of the computation, not this step's: the tolerance bounds the total drift
  w.o->cache.groups.back().relRotation = c.relRotation;
  w.o->cache.groups.back().relPosition = c.relPosition;
}

void NarrowPhase::remember(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                           std::size_t patchBegin, Worker& w) const {
  CachedGroup c;
  c.key = keyOf(g);
  relativePose(in, g, c.relRotation, c.relPosition);
  c.pairFirst = static_cast<std::uint32_t>(w.o->cache.pairs.size());
  c.pairCount = g.count;
  c.patchFirst = static_cast<std::uint32_t>(w.o->cache.patches.size());
  c.patchCount = static_cast<std::uint32_t>(w.o->patches.size() - patchBegin);
  for (std::uint32_t i = 0; i < g.count; ++i) {
    const ParticleContact& ct = set.contacts[g.first + i];
    w.o->cache.pairs.emplace_back(ct.a, ct.b);
  }
  const Quat toA = in.bodies->state[g.a.index()].orientation.conjugate();
  for (std::size_t j = patchBegin; j < w.o->patches.size(); ++j) {
    const ContactPatch& patch = w.o->patches[j];
    CachedPatch cp;
    cp.normal = g.plane.valid() ? patch.normal : Vec3(toA * patch.normal);
    cp.margin = patch.margin;
    cp.count = patch.count;
    cp.planeCase = patch.planeCase;
    cp.source = patch.source;
    cp.validated = patch.validated;
    cp.lookAhead = patch.lookAhead;
    w.o->cache.patches.push_back(cp);
    for (std::uint32_t i = patch.first; i < patch.first + patch.count; ++i) w.o->cache.order.push_back(w.o->contacts[i] - g.first);
  }
  w.o->cache.groups.push_back(c);
}

void NarrowPhase::run(const NarrowPhaseInput& in, const ContactSet& contacts, PatchSet& out, ThreadPool* pool) {
  out.stats = NarrowPhaseStats{};
  // (every contact of a group lands in one patch, whose workers write its depth and patch: no clearing)
  out.depthAlongNormal.resize(contacts.contacts.size());
  out.patchOfContact.resize(contacts.contacts.size());
  const std::size_t groups = contacts.groups.size();
  const bool shared = pool && pool->worthSharing(groups, 512);
  const std::size_t workers = shared ? static_cast<std::size_t>(pool->workers()) : 1;
  const std::size_t chunks = shared ? ThreadPool::kChunksPerWorker * workers : 1;
  if (workers_.size() < workers) workers_.resize(workers);
  for (std::size_t k = 0; k < workers; ++k)
    if (workers_[k].mark.size() < in.particles->size()) workers_[k].mark.resize(in.particles->size(), 0);
  if (chunks_.size() < chunks) chunks_.resize(chunks);
  for (std::size_t k = 0; k < chunks; ++k) {
    Output& o = chunks_[k];
    o.patches.clear();
    o.contacts.clear();
    o.stats = NarrowPhaseStats{};
    o.cache.clear();
  }
  // the groups in chunks of contiguous ranges that the workers take as they go (a group whose patches
  // are taken over costs a small part of one whose patches are computed); outputs merged in chunk order
  const auto byKey = [](const CachedGroup& c, const GroupKey& k) { return c.key < k; };
  const auto work = [&](int worker, std::size_t k) {
    Worker& w = workers_[static_cast<std::size_t>(worker)];
    w.o = &chunks_[k];
    const std::size_t begin = groups * k / chunks, end = groups * (k + 1) / chunks;
    // each group's patches of the last run, if it may take them over (groups mostly come in key order,
    // like the cache: a cursor walks forward, a binary search when not)
    auto cursor = cache_.groups.begin();
    if (begin < end) cursor = std::lower_bound(cache_.groups.begin(), cache_.groups.end(), keyOf(contacts.groups[begin]), byKey);
    for (std::size_t gi = begin; gi < end; ++gi) {
      const ContactGroup& g = contacts.groups[gi];
      const bool cacheableGroup = settings_.reuse && cacheable(in, g);
      if (cacheableGroup) {
        const GroupKey key = keyOf(g);
        if (cursor != cache_.groups.begin() && !(std::prev(cursor)->key < key))
          cursor = std::lower_bound(cache_.groups.begin(), cache_.groups.end(), key, byKey);
        while (cursor != cache_.groups.end() && cursor->key < key) ++cursor;
        if (cursor != cache_.groups.end() && cursor->key == key && reusable(in, contacts, g, *cursor)) {
          reuse(in, contacts, g, *cursor, w, out);
          continue;
        }
      }
      const std::size_t patchBegin = w.o->patches.size();
      makePatches(in, contacts, g, w, out);
      if (cacheableGroup) remember(in, contacts, g, patchBegin, w);
    }
  };
  if (shared) pool->runItems(chunks, work);
  else work(0, 0);
  // the chunks' outputs at their places, copied by the workers
  std::size_t patches = 0, indices = 0, cachedGroups = 0, cachedPairs = 0, cachedOrder = 0, cachedPatches = 0;
  for (std::size_t k = 0; k < chunks; ++k) {
    Output& o = chunks_[k];
    o.patchBase = patches;
    o.contactBase = indices;
    o.groupBase = cachedGroups;
    o.pairBase = cachedPairs;
    o.orderBase = cachedOrder;
    o.cachedPatchBase = cachedPatches;
    patches += o.patches.size();
    indices += o.contacts.size();
    cachedGroups += o.cache.groups.size();
    cachedPairs += o.cache.pairs.size();
    cachedOrder += o.cache.order.size();
    cachedPatches += o.cache.patches.size();
    out.stats += o.stats;
  }
  out.patches.resize(patches);
  out.contacts.resize(indices);
  cache_.groups.resize(cachedGroups);
  cache_.pairs.resize(cachedPairs);
  cache_.order.resize(cachedOrder);
  cache_.patches.resize(cachedPatches);
  const auto copy = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      const Output& o = chunks_[k];
      const auto contactBase = static_cast<std::uint32_t>(o.contactBase);
      for (std::size_t j = 0; j < o.patches.size(); ++j) {
        ContactPatch patch = o.patches[j];
        for (std::uint32_t i = patch.first; i < patch.first + patch.count; ++i)
          out.patchOfContact[o.contacts[i]] = static_cast<std::uint32_t>(o.patchBase + j);
        patch.first += contactBase;
        out.patches[o.patchBase + j] = patch;
      }
      std::copy(o.contacts.begin(), o.contacts.end(), out.contacts.begin() + static_cast<std::ptrdiff_t>(o.contactBase));
      for (std::size_t j = 0; j < o.cache.groups.size(); ++j) {
        CachedGroup c = o.cache.groups[j];
        c.pairFirst += static_cast<std::uint32_t>(o.pairBase);
        c.patchFirst += static_cast<std::uint32_t>(o.cachedPatchBase);
        cache_.groups[o.groupBase + j] = c;
      }
      std::copy(o.cache.pairs.begin(), o.cache.pairs.end(), cache_.pairs.begin() + static_cast<std::ptrdiff_t>(o.pairBase));
      std::copy(o.cache.order.begin(), o.cache.order.end(), cache_.order.begin() + static_cast<std::ptrdiff_t>(o.orderBase));
      std::copy(o.cache.patches.begin(), o.cache.patches.end(),
                cache_.patches.begin() + static_cast<std::ptrdiff_t>(o.cachedPatchBase));
    }
  };
  if (shared) pool->run(chunks, copy);
  else copy(0, 0, chunks);
  // lookups need the keys in order (they are, as groups come sorted, but a caller may order them otherwise)
  if (!std::is_sorted(cache_.groups.begin(), cache_.groups.end(),
                      [](const CachedGroup& x, const CachedGroup& y) { return x.key < y.key; }))
    cache_.clear();
}

void NarrowPhase::makePatches(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, Worker& w,
                              PatchSet& out) const {
  const std::uint32_t m = g.count;
  std::vector<std::uint32_t>& parent = w.parent;
  std::vector<std::uint32_t>& order = w.order;
  parent.resize(m);
  std::iota(parent.begin(), parent.end(), 0u);
  const ParticleContact* c = set.contacts.data() + g.first;
  const bool plane = g.plane.valid();
  auto near = [&](ParticleId x, ParticleId y) { return x == y || in.finder->connected(x, y); };
  // contacts are sorted by a: the ones sharing or neighbouring a_i are found by binary search
  auto byA = [&](ParticleId a) {
    return std::equal_range(c, c + m, a, [](const auto& l, const auto& r) {
      if constexpr (std::is_same_v<std::decay_t<decltype(l)>, ParticleContact>) return l.a < r;
      else return l < r.a;
    });
  };
  for (std::uint32_t i = 0; i < m; ++i) {
    auto visit = [&](ParticleId a) {
      const auto [lo, hi] = byA(a);
      for (const ParticleContact* cj = lo; cj != hi; ++cj) {
        const auto j = static_cast<std::uint32_t>(cj - c);
        // neighbours on both sides, facing roughly the same way (so the floor of a slot and its walls,
        // which a peg may touch or nearly touch at once, stay separate patches)
        if (j != i && (plane || near(c[i].b, cj->b)) && c[i].normal.dot(cj->normal) > 0.2) unite(parent, i, j);
      }
    };
    visit(c[i].a);
    for (const ParticleId n : in.finder->neighbours(c[i].a)) visit(n);
  }
  // patches in the order of their first contact
  order.resize(m);
  std::iota(order.begin(), order.end(), 0u);
  for (std::uint32_t i = 0; i < m; ++i) parent[i] = findRoot(parent, i);
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t x, std::uint32_t y) { return parent[x] < parent[y]; });
  std::uint32_t k = 0;
  while (k < m) {
    ContactPatch patch;
    patch.a = g.a;
    patch.b = g.b;
    patch.plane = g.plane;
    patch.first = static_cast<std::uint32_t>(w.o->contacts.size());
    const std::uint32_t root = parent[order[k]];
    for (; k < m && parent[order[k]] == root; ++k) w.o->contacts.push_back(g.first + order[k]);
    patch.count = static_cast<std::uint32_t>(w.o->contacts.size()) - patch.first;
    solvePatch(in, set, patch, w, out);
    w.o->patches.push_back(patch);
  }
}

void NarrowPhase::describeSide(const std::vector<Vec3>& points, double meanRadius, Side& side) const {
  const std::size_t n = points.size();
  side.centroid = Vec3::Zero();
  for (const Vec3& p : points) side.centroid += p;
  side.centroid /= static_cast<double>(std::max<std::size_t>(n, 1));
  side.meanRadius = meanRadius;
  side.line = Vec3::Zero();
  side.face = Vec3::Zero();
  side.collinear = true;
  if (n < 2) return;
  if (n == 2) {
    side.line = (points[1] - points[0]).normalized();
    return;
  }
  // best-fit line and plane of the centres
  Mat3 cov = Mat3::Zero();
  for (const Vec3& p : points) cov += (p - side.centroid) * (p - side.centroid).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov);
  side.line = eig.eigenvectors().col(2);
  double farthest = 0.0;
  for (const Vec3& p : points) {
    const Vec3 d = p - side.centroid;
    farthest = std::max(farthest, (d - d.dot(side.line) * side.line).norm());
  }
  side.collinear = farthest <= settings_.collinearTolerance * meanRadius;
  if (!side.collinear) side.face = eig.eigenvectors().col(0);
}

PlaneCase NarrowPhase::classify(const NarrowPhaseInput& in, const Side& a, const Side& b) {
  const bool aSmall = a.particles.size() <= b.particles.size();
  const Side& s = aSmall ? a : b;
  const Side& l = aSmall ? b : a;
  const std::size_t ns = s.particles.size(), nl = l.particles.size();
  if (ns == 1) {
    if (nl == 1) return PlaneCase::VertexFace11;
    if (l.collinear) {
      const bool onEdge = (in.particles->flags[s.particles[0].index()] & kParticleEdge) != 0;
      return onEdge ? PlaneCase::EdgeEdge12 : PlaneCase::VertexFace12;
    }
    return PlaneCase::VertexFace13;
  }
  if (ns == 2) {
    if (nl == 2) return PlaneCase::EdgeEdge22;
    return l.collinear ? PlaneCase::EdgeEdge23 : PlaneCase::EdgeFace23;
  }
  if (s.collinear && l.collinear) return PlaneCase::EdgeEdge23;
  if (s.collinear || l.collinear) return PlaneCase::EdgeFace33;
  return PlaneCase::FaceFace;
}

void NarrowPhase::ring(const NarrowPhaseInput& in, std::span<const ParticleId> seeds, int k, std::vector<ParticleId>& out,
                       Worker& w) {
  out.clear();
  if (++w.stamp == 0) {  // wrapped: clear the marks
    std::fill(w.mark.begin(), w.mark.end(), 0u);
    w.stamp = 1;
  }
  w.frontier.clear();
  for (const ParticleId s : seeds) {
    if (w.mark[s.index()] == w.stamp) continue;
    w.mark[s.index()] = w.stamp;
    out.push_back(s);
    w.frontier.push_back(s);
  }
  for (int r = 0; r < k; ++r) {
    w.next.clear();
    for (const ParticleId p : w.frontier)
      for (const ParticleId n : in.finder->neighbours(p)) {
        if (w.mark[n.index()] == w.stamp) continue;
        w.mark[n.index()] = w.stamp;
        out.push_back(n);
        w.next.push_back(n);
      }
    std::swap(w.frontier, w.next);
  }
}

bool NarrowPhase::lookAhead(const NarrowPhaseInput& in, ParticleId a, ParticleId b, std::vector<Vec3>& pointsA,
                            std::vector<Vec3>& pointsB, Vec3& contactDifference, Worker& w) const {
  const ParticleStore& p = *in.particles;
  const BodyStore& bodies = *in.bodies;
  const ParticleId seedA[1] = {a};
  const ParticleId seedB[1] = {b};
  ring(in, seedA, 1, w.aheadA, w);
  ring(in, seedB, 1, w.aheadB, w);
  const Vec3 xa = p.position[a.index()], xb = p.position[b.index()];
  Vec3 n = xb - xa;
  if (n.norm() < 1e-12) return false;
  n.normalize();
  // how fast the pair approaches along the centre line
  const double approach = -(particleVelocity(p, bodies, b) - particleVelocity(p, bodies, a)).dot(n);
  const double delta = settings_.lookAheadStep * std::min(p.radius[a.index()], p.radius[b.index()]);

  // predicted position of particle q after time tau along its body's motion
  auto predict = [&](ParticleId q, double tau) -> Vec3 {
    const BodyId body = p.body[q.index()];
    const BodyInfo& info = bodies.info[body.index()];
    const Vec3& x = p.position[q.index()];
    if (info.kind == BodyKind::Static) return x;
    if (info.kind == BodyKind::Deformable) return x + p.velocity[q.index()] * tau;
    const BodyState& s = bodies.state[body.index()];
    const Vec3 turn = s.angularVelocity * tau;
    const double angle = turn.norm();
    const Vec3 arm = x - s.position;
    const Vec3 turned = angle > 1e-15 ? Vec3(Eigen::AngleAxisd(angle, turn / angle) * arm) : arm;
    return s.position + s.linearVelocity * tau + turned;
  };

  for (int k = 1; k <= settings_.lookAheadSteps; ++k) {
    const double shift = k * delta;
    const bool moving = approach > 0.0 && shift / approach <= 8.0 * in.dt;
    w.aheadPosA.resize(w.aheadA.size());
    w.aheadPosB.resize(w.aheadB.size());
    for (std::size_t i = 0; i < w.aheadA.size(); ++i)
      w.aheadPosA[i] = moving ? predict(w.aheadA[i], shift / approach) : p.position[w.aheadA[i].index()];
    for (std::size_t j = 0; j < w.aheadB.size(); ++j)
      w.aheadPosB[j] = moving ? predict(w.aheadB[j], shift / approach) : Vec3(p.position[w.aheadB[j].index()] - n * shift);
    // touching pairs between the two small neighbourhoods
    pointsA.clear();
    pointsB.clear();
    std::size_t found = 0;
    Vec3 firstPoint = Vec3::Zero();
    contactDifference = Vec3::Zero();
    w.sideA.particles.clear();
    w.sideB.particles.clear();
    for (std::size_t i = 0; i < w.aheadA.size(); ++i)
      for (std::size_t j = 0; j < w.aheadB.size(); ++j) {
        const double rs = p.radius[w.aheadA[i].index()] + p.radius[w.aheadB[j].index()];
        const Vec3 d = w.aheadPosB[j] - w.aheadPosA[i];
        if (!(d.squaredNorm() < rs * rs) || w.aheadA[i] == w.aheadB[j]) continue;
        if (p.body[w.aheadA[i].index()] == p.body[w.aheadB[j].index()] && in.finder->connected(w.aheadA[i], w.aheadB[j])) continue;
        const Vec3 point = w.aheadPosA[i] + d * (p.radius[w.aheadA[i].index()] / rs);
        if (found == 0) firstPoint = point;
        else if (found == 1) contactDifference = point - firstPoint;
        ++found;
        if (std::find(w.sideA.particles.begin(), w.sideA.particles.end(), w.aheadA[i]) == w.sideA.particles.end()) {
          w.sideA.particles.push_back(w.aheadA[i]);
          pointsA.push_back(w.aheadPosA[i]);
        }
        if (std::find(w.sideB.particles.begin(), w.sideB.particles.end(), w.aheadB[j]) == w.sideB.particles.end()) {
          w.sideB.particles.push_back(w.aheadB[j]);
          pointsB.push_back(w.aheadPosB[j]);
        }
      }
    if (found >= 2) return true;
  }
  return false;
}

void NarrowPhase::addCandidates(const NarrowPhaseInput& in, const Side& a, const Side& b, const std::vector<Vec3>& pointsA,
                                const std::vector<Vec3>& pointsB, const Vec3& contactDifference, PlaneCase c, bool bIsPlane,
                                const Plane* plane, Worker& w) const {
  std::vector<Candidate>& cands = w.candidates;
  cands.clear();
  auto add = [&](const Vec3& v, NormalSource s) {
    const double len = v.norm();
    if (len > 1e-9) cands.push_back({v / len, s});
  };
  if (bIsPlane) {
    add(-plane->normal, NormalSource::Plane);
    return;
  }
  // the paper's cases
  const bool aSmall = a.particles.size() <= b.particles.size();
  const Side& s = aSmall ? a : b;
  const Side& l = aSmall ? b : a;
  const std::vector<Vec3>& sPoints = aSmall ? pointsA : pointsB;
  if (a.particles.size() >= 3 && !a.collinear) add(a.face, NormalSource::FaceA);
  if (b.particles.size() >= 3 && !b.collinear) add(b.face, NormalSource::FaceB);
  if (s.particles.size() >= 2 && l.particles.size() >= 2 && s.collinear && l.collinear) {
    const Vec3 cross = s.line.cross(l.line);
    if (cross.norm() > 1e-6) {
      add(cross, NormalSource::LineLine);
    } else {  // parallel lines: the perpendicular between them
      const Vec3 d = b.centroid - a.centroid;
      add(d - d.dot(a.line) * a.line, NormalSource::LinePerpendicular);
    }
  }
  if (s.particles.size() == 1 && l.particles.size() >= 2 && l.collinear) {
    // perpendicular from the line to the single particle, and the line x the contact points' difference
    const Vec3 v = sPoints[0] - l.centroid;
    add(v - v.dot(l.line) * l.line, NormalSource::LinePerpendicular);
    add(l.line.cross(contactDifference), NormalSource::LineContactPoints);
    if (c == PlaneCase::EdgeEdge12) {
      // the single particle's edge: its neighbours with the same cached normal lie along it
      const ParticleId q = s.particles[0];
      const Vec3 nq = worldNormal(in, q);
      for (const ParticleId nb : in.finder->neighbours(q)) {
        if ((worldNormal(in, nb) - nq).norm() > 1e-6) continue;
        add((in.particles->position[nb.index()] - in.particles->position[q.index()]).cross(l.line), NormalSource::NeighbourLine);
        break;
      }
    }
  }
  // cached surface normals of each side: the exact face normals behind them, and their mean
  auto cachedFaces = [&](const Side& side, double sign, NormalSource source) {
    Vec3 mean = Vec3::Zero();
    for (const ParticleId q : side.particles) {
      const std::int32_t k = in.particles->normalIndex[q.index()];
      if (k < 0) continue;
      const Quat& r = in.bodies->state[in.particles->body[q.index()].index()].orientation;
      mean += (*in.normals)[k];
      for (const Vec3& f : in.normals->faces(k)) {
        const Vec3 n = sign * Vec3(r * f);
        const bool seen = std::any_of(cands.begin(), cands.end(), [&](const Candidate& other) {
          return other.source == source && (other.normal - n).squaredNorm() < 1e-12;
        });
        if (!seen) add(n, source);
      }
    }
    if (!side.particles.empty())
      add(sign * Vec3(in.bodies->state[in.particles->body[side.particles[0].index()].index()].orientation * mean), source);
  };
  cachedFaces(a, 1.0, NormalSource::CachedA);
  cachedFaces(b, -1.0, NormalSource::CachedB);
  add(b.centroid - a.centroid, NormalSource::CentreLine);
}

void NarrowPhase::solvePatch(const NarrowPhaseInput& in, const ContactSet& set, ContactPatch& patch, Worker& w,
                             PatchSet& out) const {
  const ParticleStore& p = *in.particles;
  const bool isPlane = patch.plane.valid();
  const std::uint32_t* idx = w.o->contacts.data() + patch.first;

  // the sides: unique particles, ascending
  w.sideA.particles.clear();
  w.sideB.particles.clear();
  std::size_t deepest = idx[0];
  for (std::uint32_t i = 0; i < patch.count; ++i) {
    const ParticleContact& c = set.contacts[idx[i]];
    w.sideA.particles.push_back(c.a);
    if (!isPlane) w.sideB.particles.push_back(c.b);
    if (c.depth > set.contacts[deepest].depth) deepest = idx[i];
  }
  for (auto* v : {&w.sideA.particles, &w.sideB.particles}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  auto positions = [&](const std::vector<ParticleId>& ids, std::vector<Vec3>& pts, double& meanRadius) {
    pts.clear();
    meanRadius = 0.0;
    for (const ParticleId q : ids) {
      pts.push_back(p.position[q.index()]);
      meanRadius += p.radius[q.index()];
    }
    if (!ids.empty()) meanRadius /= static_cast<double>(ids.size());
  };
  double ra = 0.0, rb = 0.0;
  positions(w.sideA.particles, w.pointsA, ra);
  positions(w.sideB.particles, w.pointsB, rb);
  const ParticleContact& deep = set.contacts[deepest];
  Vec3 contactDifference = patch.count >= 2 ? Vec3(set.contacts[idx[1]].point - set.contacts[idx[0]].point) : Vec3::Zero();

  // real particles of the patch (validation uses them even when a look-ahead supplies the geometry)
  w.ringA.assign(w.sideA.particles.begin(), w.sideA.particles.end());
  w.ringB.assign(w.sideB.particles.begin(), w.sideB.particles.end());

  Side& a = w.sideA;
  Side& b = w.sideB;
  if (isPlane) {
    describeSide(w.pointsA, ra, a);
    patch.planeCase = PlaneCase::ParticlePlane;
  } else {
    if (patch.count == 1 && settings_.lookAheadSteps > 0) {
      ++w.o->stats.lookAheads;
      patch.lookAhead = lookAhead(in, deep.a, deep.b, w.pointsA, w.pointsB, contactDifference, w);
      if (!patch.lookAhead) {  // no second contact: back to the real single contact
        w.sideA.particles.assign(1, deep.a);
        w.sideB.particles.assign(1, deep.b);
        w.pointsA.assign(1, p.position[deep.a.index()]);
        w.pointsB.assign(1, p.position[deep.b.index()]);
      }
    }
    describeSide(w.pointsA, ra, a);
    describeSide(w.pointsB, rb, b);
    patch.planeCase = classify(in, a, b);
  }
  const Plane* plane = isPlane ? &in.planes[patch.plane.index()] : nullptr;
  addCandidates(in, a, b, w.pointsA, w.pointsB, contactDifference, patch.planeCase, isPlane, plane, w);

  // validation against the k-ring neighbourhoods of the real patch particles
  w.seedsA.assign(w.ringA.begin(), w.ringA.end());
  w.seedsB.assign(w.ringB.begin(), w.ringB.end());
  ring(in, w.seedsA, settings_.validationRings, w.ringA, w);
  ring(in, w.seedsB, settings_.validationRings, w.ringB, w);
  const Vec3 ref = isPlane ? Vec3(-plane->normal) : Vec3(b.centroid - a.centroid);
  const Vec3 fallback = deep.normal;
  const double rsum = p.radius[deep.a.index()] + (isPlane ? 0.0 : p.radius[deep.b.index()]);
  const double tol = settings_.validationTolerance * rsum;
  // validation: centres on the right side of the plane through the deepest contact point (slack >= -tol);
  // choice: among validated candidates the largest margin, the gap between the two sides' spheres along
  // the normal (negative: their overlap), i.e. the least penetration; without any validated candidate,
  // the one with the best slack
  double bestMargin = -std::numeric_limits<double>::infinity();
  double bestSlack = -std::numeric_limits<double>::infinity();
  bool bestValid = false;
  Candidate best{fallback, NormalSource::CentreLine};
  // the rings' particles, gathered once for all candidates
  const auto gather = [&](const std::vector<ParticleId>& ring, std::size_t seeds, std::vector<Worker::RingPoint>& points) {
    points.resize(ring.size());
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const ParticleId q = ring[i];
      points[i] = {p.position[q.index()], i < seeds ? Vec3::Zero() : worldNormal(in, q), p.radius[q.index()], i < seeds};
    }
  };
  gather(w.ringA, w.seedsA.size(), w.ringPointsA);
  gather(w.ringB, w.seedsB.size(), w.ringPointsB);
  for (Candidate& cand : w.candidates) {
    const Vec3 orient = ref.norm() > 1e-12 ? ref : fallback;
    if (cand.normal.dot(orient) < 0.0) cand.normal = -cand.normal;
    // the patch's own particles always count; a neighbour only if it is interior or its surface faces the
    // plane (around a concave corner the neighbourhood wraps onto a face that the plane must not judge)
    auto counts = [&](const Worker::RingPoint& q, double sign) {
      return q.own || q.n.isZero() || sign * q.n.dot(cand.normal) > 0.05;
    };
    double slack = std::numeric_limits<double>::infinity();
    double reachA = -std::numeric_limits<double>::infinity();  // farthest A sphere along n
    double reachB = std::numeric_limits<double>::infinity();   // nearest B sphere along n
    for (const Worker::RingPoint& q : w.ringPointsA) {
      if (!counts(q, 1.0)) continue;
      slack = std::min(slack, -cand.normal.dot(q.x - deep.point));
      reachA = std::max(reachA, cand.normal.dot(q.x) + q.r);
    }
    for (const Worker::RingPoint& q : w.ringPointsB) {
      if (!counts(q, -1.0)) continue;
      slack = std::min(slack, cand.normal.dot(q.x - deep.point));
      reachB = std::min(reachB, cand.normal.dot(q.x) - q.r);
    }
    // a plane: its surface is the B side
    if (isPlane) reachB = -plane->offset;
    const double margin = reachB - reachA;
    const bool valid = slack >= -tol;
    if ((valid && (!bestValid || margin > bestMargin)) || (!valid && !bestValid && slack > bestSlack)) {
      bestValid = valid;
      bestMargin = margin;
      bestSlack = slack;
      best = cand;
    }
  }
  w.o->stats.candidates += w.candidates.size();
  patch.normal = best.normal;
  patch.source = best.source;
  patch.margin = bestMargin;
  patch.validated = bestValid;
  patch.point = deep.point;
  if (!patch.validated) ++w.o->stats.unvalidated;
  ++w.o->stats.patches;
  ++w.o->stats.byCase[static_cast<std::size_t>(patch.planeCase)];

  // depth of every contact along the patch normal
  patch.depth = 0.0;
  for (std::uint32_t i = 0; i < patch.count; ++i) {
    const ParticleContact& c = set.contacts[idx[i]];
    double d;
    if (isPlane) {
      d = c.depth;  // the plane's normal is the contact's own
    } else {
      // overlap of the two particles' extents along the normal, r_a + r_b - n . (x_b - x_a): the plane
      // model's depth, in which a side's particle tops form a flat face (a particle resting in the groove
      // between two others rests on their tops, and slides over a lattice without bumping)
      d = p.radius[c.a.index()] + p.radius[c.b.index()] - patch.normal.dot(p.position[c.b.index()] - p.position[c.a.index()]);
    }
    out.depthAlongNormal[idx[i]] = d;
    patch.depth = std::max(patch.depth, d);
  }
}

}  // namespace volpar
