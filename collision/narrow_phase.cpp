#include "volpar/collision/narrow_phase.hpp"

#include "volpar/collision/polytope_cores.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <numeric>

namespace volpar {

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
    case NormalSource::Cores: return "cores";
  }
  return "unknown";
}


void NarrowPhase::clearCache() {
  cache_.clear();
  everyKeepsCache();
}

bool NarrowPhase::cacheable(const NarrowPhaseInput& in, const ContactGroup& g) {
  if (g.a == g.b) return false;  // self-contact of a deformable body
  if (in.kindOf(g.a) == BodyKind::Deformable) return false;
  return g.plane.valid() || in.kindOf(g.b) != BodyKind::Deformable;
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

std::uint32_t NarrowPhase::takenOver(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                                     CacheCursor& cursor) const {
  // (groups mostly come in key order, like the cache: the cursor walks forward, a binary search when not)
  const GroupKey key = keyOf(g);
  const auto byKey = [](const CachedGroup& c, const GroupKey& k) { return c.key < k; };
  if (cursor == cache_.groups.cbegin() || !(std::prev(cursor)->key < key))
    cursor = std::lower_bound(cache_.groups.cbegin(), cache_.groups.cend(), key, byKey);
  while (cursor != cache_.groups.cend() && cursor->key < key) ++cursor;
  if (cursor == cache_.groups.cend() || !(cursor->key == key) || !reusable(in, set, g, *cursor)) return kNoMatch;
  return static_cast<std::uint32_t>(cursor - cache_.groups.cbegin());
}

void NarrowPhase::reuse(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, std::uint32_t entry,
                        Worker& w, PatchSet& out) const {
  const CachedGroup& c = cache_.groups[entry];
  const ParticleStore& p = *in.particles;
  const Quat& qa = in.bodies->state[g.a.index()].orientation;
  const bool plane = g.plane.valid();
  std::uint32_t k = c.pairFirst;  // position in cache order (parallel to pairs)
  for (std::uint32_t j = 0; j < c.patchCount; ++j) {
    const CachedPatch& cp = cache_.patches[c.patchFirst + j];
    ContactPatch patch;
    patch.a = g.a;
    patch.b = g.b;
    patch.plane = g.plane;
    // (the normal turns with the body whose face it is: ContactPatch::normalSide)
    const Quat& frame = cp.normalSide == 1 ? in.bodies->state[g.b.index()].orientation : qa;
    patch.normal = plane ? cp.normal : Vec3(frame * cp.normal);
    patch.normalSide = cp.normalSide;
    patch.margin = cp.margin;
    patch.planeCase = cp.planeCase;
    patch.source = cp.source;
    patch.validated = cp.validated;
    patch.lookAhead = cp.lookAhead;
    patch.lookAheadCase = cp.lookAheadCase;
    patch.curvedSide = cp.curvedSide;
    if (!plane)
      for (std::size_t e = 0; e < 2; ++e) patch.core[e] = in.bodies->state[g.a.index()].position + qa * cp.core[e];
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
      const Vec3 n = contactNormal(patch, p.position[ct.a.index()], p.position[ct.b.index()], out.flipped[ci] != 0);
      const double d = plane ? ct.depth
                             : p.radius[ct.a.index()] + p.radius[ct.b.index()] -
                                   n.dot(p.position[ct.b.index()] - p.position[ct.a.index()]);
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
  // the entry goes on as it is: the pose of the computation, not this step's (the tolerance bounds the total
  // drift), and the normals in their bodies' frames as computed
  copyEntry(cache_, entry, w.o->cache);
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
    cp.normalSide = !g.plane.valid() && patch.normalSide == 1 ? 1 : 0;
    const Quat toFrame = cp.normalSide == 1 ? Quat(in.bodies->state[g.b.index()].orientation.conjugate()) : toA;
    cp.normal = g.plane.valid() ? patch.normal : Vec3(toFrame * patch.normal);
    cp.margin = patch.margin;
    cp.count = patch.count;
    cp.planeCase = patch.planeCase;
    cp.source = patch.source;
    cp.validated = patch.validated;
    cp.lookAhead = patch.lookAhead;
    cp.lookAheadCase = patch.lookAheadCase;
    cp.curvedSide = patch.curvedSide;
    if (!g.plane.valid())
      for (std::size_t e = 0; e < 2; ++e) cp.core[e] = toA * (patch.core[e] - in.bodies->state[g.a.index()].position);
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
  out.flipped.assign(contacts.contacts.size(), 0);
  const std::size_t groups = contacts.groups.size();
  // (with processes, this one's contiguous run of the groups)
  const int ranks = processes_ ? processes_->size() : 1, me = processes_ ? processes_->rank() : 0;
  if (ranks > 1) divideGroups(in, contacts);
  const std::size_t lo = ranks > 1 ? groupStart_[static_cast<std::size_t>(me)] : 0;
  const std::size_t hi = ranks > 1 ? groupStart_[static_cast<std::size_t>(me) + 1] : groups;
  const bool shared = pool && pool->worthSharing(hi - lo, 128);
  const std::size_t workers = shared ? static_cast<std::size_t>(pool->workers()) : 1;
  const std::size_t chunks = shared ? PacedSplit::pieces(static_cast<int>(workers)) : 1;
  if (workers_.size() < workers) workers_.resize(workers);
  for (std::size_t k = 0; k < workers; ++k) workers_[k].solver.setSettings(settings_);
  if (chunks_.size() < chunks) chunks_.resize(chunks);
  for (std::size_t k = 0; k < chunks; ++k) {
    Output& o = chunks_[k];
    o.patches.clear();
    o.contacts.clear();
    o.stats = NarrowPhaseStats{};
    o.taken.clear();
    o.cache.clear();
  }
  // the groups in one contiguous range per worker, sized by the ranges' costs in the last run and cut into
  // pieces (chunks) that workers done with their own take over (PacedSplit: a group whose patches are
  // taken over costs a small part of one whose patches are computed, and those come in runs); outputs
  // merged in chunk order
  const auto work = [&](int worker, std::size_t k, std::size_t begin, std::size_t end) {
    Worker& w = workers_[static_cast<std::size_t>(worker)];
    w.o = &chunks_[k];
    CacheCursor cursor = cache_.groups.cbegin();
    for (std::size_t gi = lo + begin; gi < lo + end; ++gi) {
      const ContactGroup& g = contacts.groups[gi];
      const bool cacheableGroup = settings_.reuse && cacheable(in, g);
      std::uint32_t match = kNoMatch;
      if (ranks == 1) {
        if (cacheableGroup) match = takenOver(in, contacts, g, cursor);
      } else {
        // (the entry found already, by divideGroups(), tested here; whether it was taken over travels)
        if (match_[gi] != kNoMatch && reusable(in, contacts, g, cache_.groups[match_[gi]])) match = match_[gi];
        w.o->taken.push_back(match != kNoMatch ? 1 : 0);
      }
      if (match != kNoMatch) {
        reuse(in, contacts, g, match, w, out);
        continue;
      }
      const std::size_t patchBegin = w.o->patches.size();
      makePatches(in, contacts, g, w, out);
      if (cacheableGroup) remember(in, contacts, g, patchBegin, w);
    }
  };
  if (shared) groupSplit_.run(*pool, static_cast<int>(workers), hi - lo, work);
  else work(0, 0, 0, hi - lo);
  // (with processes: every process's chunks, in process order, and the contacts' values its workers wrote)
  auto& list = ranks > 1 ? gathered_ : chunks_;
  const std::size_t listed = ranks > 1 ? gatherChunks(chunks) : chunks;
  if (ranks > 1) {
    shareContacts(contacts, out.depthAlongNormal);
    shareContacts(contacts, out.flipped);
  }
  // the chunks' outputs at their places, copied by the workers: every process's patches, and the entries for
  // reuse of this process's own chunks (with one process, the chunks are its own)
  std::size_t patches = 0, indices = 0, cachedGroups = 0, cachedPairs = 0, cachedOrder = 0, cachedPatches = 0;
  for (std::size_t k = 0; k < listed; ++k) {
    Output& o = list[k];
    o.patchBase = patches;
    o.contactBase = indices;
    patches += o.patches.size();
    indices += o.contacts.size();
    out.stats += o.stats;
  }
  for (std::size_t k = 0; k < chunks; ++k) {
    Output& o = chunks_[k];
    o.groupBase = cachedGroups;
    o.pairBase = cachedPairs;
    o.orderBase = cachedOrder;
    o.cachedPatchBase = cachedPatches;
    cachedGroups += o.cache.groups.size();
    cachedPairs += o.cache.pairs.size();
    cachedOrder += o.cache.order.size();
    cachedPatches += o.cache.patches.size();
  }
  out.patches.resize(patches);
  out.contacts.resize(indices);
  cache_.groups.resize(cachedGroups);
  cache_.pairs.resize(cachedPairs);
  cache_.order.resize(cachedOrder);
  cache_.patches.resize(cachedPatches);
  const auto copy = [&](std::size_t k) {
    const Output& o = list[k];
    const auto contactBase = static_cast<std::uint32_t>(o.contactBase);
    for (std::size_t j = 0; j < o.patches.size(); ++j) {
      ContactPatch patch = o.patches[j];
      for (std::uint32_t i = patch.first; i < patch.first + patch.count; ++i)
        out.patchOfContact[o.contacts[i]] = static_cast<std::uint32_t>(o.patchBase + j);
      patch.first += contactBase;
      out.patches[o.patchBase + j] = patch;
    }
    std::copy(o.contacts.begin(), o.contacts.end(), out.contacts.begin() + static_cast<std::ptrdiff_t>(o.contactBase));
  };
  const auto copyCache = [&](std::size_t k) {
    const Output& o = chunks_[k];
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
  };
  const auto copyBoth = [&](int, std::size_t begin, std::size_t end) {
    for (std::size_t k = begin; k < end; ++k) {
      if (k < listed) copy(k);
      if (k < chunks) copyCache(k);
    }
  };
  const std::size_t items = std::max(listed, chunks);
  if (pool && pool->worthSharing(items, 1)) pool->run(items, copyBoth);
  else copyBoth(0, 0, items);
  // lookups need the keys in order (they are, as groups come sorted, but a caller may order them otherwise;
  // with processes, every process decides alike from all the groups' keys)
  const bool inOrder = ranks > 1 ? keysInOrder_
                                 : std::is_sorted(cache_.groups.begin(), cache_.groups.end(),
                                                  [](const CachedGroup& x, const CachedGroup& y) { return x.key < y.key; });
  if (!inOrder) cache_.clear();
  if (ranks > 1) noteKeepers(contacts, listed);
}

template <class T>
void NarrowPhase::shareContacts(const ContactSet& contacts, LargeVector<T>& values) {
  const int ranks = processes_->size();
  shareOffset_.assign(static_cast<std::size_t>(ranks), 0);
  shareCount_.assign(static_cast<std::size_t>(ranks), 0);
  for (int r = 0; r < ranks; ++r) {
    const std::size_t a = groupStart_[static_cast<std::size_t>(r)], b = groupStart_[static_cast<std::size_t>(r) + 1];
    if (a == b) continue;
    // (a group's contacts are contiguous, and the groups come in the contacts' order)
    const ContactGroup &first = contacts.groups[a], &last = contacts.groups[b - 1];
    VOLPAR_ASSERT(last.first >= first.first, "contact groups out of the contacts' order");
    shareOffset_[static_cast<std::size_t>(r)] = first.first * sizeof(T);
    shareCount_[static_cast<std::size_t>(r)] = (last.first + last.count - first.first) * sizeof(T);
  }
  processes_->share(std::as_writable_bytes(std::span<T>(values)), shareOffset_, shareCount_);
}

void NarrowPhase::makePatches(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, Worker& w,
                              PatchSet& out) const {
  const bool cores = settings_.polytopeCores && in.cores && !g.plane.valid() && g.a != g.b &&
                     !in.cores->vertices(g.a).empty() && !in.cores->vertices(g.b).empty();
  if (cores) {
    // two whole polytope cores: one patch, the plane between them
    w.order.resize(g.count);
    std::iota(w.order.begin(), w.order.end(), g.first);
    ContactPatch patch;
    patch.a = g.a;
    patch.b = g.b;
    if (w.solver.solveCores(in, set, w.order, patch, out.depthAlongNormal, w.o->stats)) {
      patch.first = static_cast<std::uint32_t>(w.o->contacts.size());
      patch.count = g.count;
      w.o->contacts.insert(w.o->contacts.end(), w.order.begin(), w.order.end());
      w.o->patches.push_back(patch);
      return;
    }
  }
  w.builder.build(in, set, g, out.flipped, w.order, w.sizes);
  // each patch's plane; a patch that validates none is split in two and each part solved again, down to
  // single contacts, which are then resolved along their own centre lines (counted)
  std::uint32_t begin = 0;
  for (const std::uint32_t size : w.sizes) {
    w.ranges.clear();
    w.ranges.emplace_back(begin, begin + size);
    begin += size;
    while (!w.ranges.empty()) {
      const auto [first, last] = w.ranges.back();
      w.ranges.pop_back();
      const std::span<std::uint32_t> idx(w.order.data() + first, last - first);
      ContactPatch patch;
      patch.a = g.a;
      patch.b = g.b;
      patch.plane = g.plane;
      NarrowPhaseStats tried;
      w.solver.solve(in, set, idx, out.flipped, patch, out.depthAlongNormal, tried);
      if (!patch.validated && idx.size() >= 2) {
        const auto half = static_cast<std::uint32_t>(w.builder.split(in, set, idx, out.flipped));
        w.ranges.emplace_back(first + half, last);
        w.ranges.emplace_back(first, first + half);
        w.o->stats.candidates += tried.candidates;
        w.o->stats.lookAheads += tried.lookAheads;
        ++w.o->stats.splits;
        continue;
      }
      if (!patch.validated || patch.a == patch.b) {
        patch.source = NormalSource::ContactLines;
        ++tried.contactLines;
      }
      w.o->stats += tried;
      patch.first = static_cast<std::uint32_t>(w.o->contacts.size());
      patch.count = static_cast<std::uint32_t>(idx.size());
      w.o->contacts.insert(w.o->contacts.end(), idx.begin(), idx.end());
      w.o->patches.push_back(patch);
    }
  }
}

}  // namespace volpar
