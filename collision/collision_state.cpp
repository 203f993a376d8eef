// Checkpoint arrays of the collision stage: contacts, patches, the normal cache, the narrow phase's reuse
// cache and the broadphase's restored proxies.

#include "volpar/collision/collision_state.hpp"

#include <string>

#include "volpar/collision/broadphase.hpp"
#include "volpar/collision/narrow_phase.hpp"
#include "volpar/collision/normal_cache.hpp"

namespace volpar {

namespace {

constexpr std::uint32_t kInvalid = 0xffffffffu;

template <class Tag>
std::uint32_t raw(Id<Tag> id) {
  return id.value;
}

/// An index that may be invalid (kInvalid) or below `bound`.
bool optionalBelow(std::uint32_t i, std::size_t bound) { return i == kInvalid || i < bound; }

void putFlags(std::vector<std::uint8_t>& out, PlaneCase c, NormalSource s, bool validated, bool lookAhead,
              PlaneCase lookAheadCase, std::int8_t curvedSide) {
  out.insert(out.end(), {static_cast<std::uint8_t>(c), static_cast<std::uint8_t>(s), static_cast<std::uint8_t>(validated),
                         static_cast<std::uint8_t>(lookAhead), static_cast<std::uint8_t>(lookAheadCase),
                         static_cast<std::uint8_t>(curvedSide + 1)});
}

/// Reads six flags written by putFlags; false where one is out of its range.
template <class P>
bool takeFlags(const std::uint8_t* f, P& p) {
  if (f[0] >= kPlaneCaseCount || f[1] >= kNormalSourceCount || f[2] > 1 || f[3] > 1 || f[4] >= kPlaneCaseCount || f[5] > 2)
    return false;
  p.planeCase = static_cast<PlaneCase>(f[0]);
  p.source = static_cast<NormalSource>(f[1]);
  p.validated = f[2] != 0;
  p.lookAhead = f[3] != 0;
  p.lookAheadCase = static_cast<PlaneCase>(f[4]);
  p.curvedSide = static_cast<std::int8_t>(static_cast<int>(f[5]) - 1);
  return true;
}

}  // namespace

void saveContacts(StateArchive& archive, const ContactSet& set) {
  const std::size_t n = set.contacts.size();
  std::vector<std::uint32_t> ids;
  std::vector<Vec3> point(n), normal(n);
  std::vector<double> depth(n);
  ids.reserve(3 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const ParticleContact& c = set.contacts[i];
    ids.insert(ids.end(), {raw(c.a), raw(c.b), raw(c.plane)});
    point[i] = c.point;
    normal[i] = c.normal;
    depth[i] = c.depth;
  }
  archive.put("contacts/particles_and_plane", std::span<const std::uint32_t>(ids), 3);
  archive.putVec3("contacts/point", point);
  archive.putVec3("contacts/normal", normal);
  archive.put("contacts/depth", std::span<const double>(depth));
  std::vector<std::uint32_t> groups;
  groups.reserve(5 * set.groups.size());
  for (const ContactGroup& g : set.groups) groups.insert(groups.end(), {raw(g.a), raw(g.b), raw(g.plane), g.first, g.count});
  archive.put("contacts/groups", std::span<const std::uint32_t>(groups), 5);
}

bool restoreContacts(StateReader& r, ContactSet& out, std::size_t particles, std::size_t bodies, std::size_t planes) {
  const std::vector<std::uint32_t> ids = r.get<std::uint32_t>("contacts/particles_and_plane", 3);
  const std::size_t n = ids.size() / 3;
  const std::vector<Vec3> point = r.vec3("contacts/point", n), normal = r.vec3("contacts/normal", n);
  const std::vector<double> depth = r.get<double>("contacts/depth", 1, n);
  const std::vector<std::uint32_t> groups = r.get<std::uint32_t>("contacts/groups", 5);
  if (!r.ok()) return false;
  out.clear();
  out.contacts.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t a = ids[3 * i], b = ids[3 * i + 1], plane = ids[3 * i + 2];
    if (a >= particles || !optionalBelow(b, particles) || !optionalBelow(plane, planes) || (b == kInvalid) == (plane == kInvalid)) {
      r.fail("checkpoint contact " + std::to_string(i) + " names particles or a plane the world does not have");
      return false;
    }
    ParticleContact& c = out.contacts[i];
    c.a = ParticleId(a);
    c.b = ParticleId(b);
    c.plane = PlaneId(plane);
    c.point = point[i];
    c.normal = normal[i];
    c.depth = depth[i];
  }
  const std::size_t ng = groups.size() / 5;
  out.groups.resize(ng);
  for (std::size_t k = 0; k < ng; ++k) {
    const std::uint32_t* g = groups.data() + 5 * k;
    if (g[0] >= bodies || !optionalBelow(g[1], bodies) || !optionalBelow(g[2], planes) ||
        static_cast<std::uint64_t>(g[3]) + g[4] > n) {
      r.fail("checkpoint contact group " + std::to_string(k) + " names bodies, a plane or contacts the world does not have");
      return false;
    }
    out.groups[k] = ContactGroup{BodyId(g[0]), BodyId(g[1]), PlaneId(g[2]), g[3], g[4]};
  }
  return true;
}

void savePatches(StateArchive& archive, const PatchSet& set) {
  std::vector<std::uint32_t> ids;
  std::vector<double> vectors, scalars;
  std::vector<std::uint8_t> flags;
  for (const ContactPatch& p : set.patches) {
    ids.insert(ids.end(), {raw(p.a), raw(p.b), raw(p.plane), p.first, p.count});
    for (const Vec3* v : {&p.normal, &p.point, &p.core[0], &p.core[1]}) vectors.insert(vectors.end(), {v->x(), v->y(), v->z()});
    scalars.insert(scalars.end(), {p.depth, p.margin});
    putFlags(flags, p.planeCase, p.source, p.validated, p.lookAhead, p.lookAheadCase, p.curvedSide);
  }
  archive.put("patches/bodies_plane_and_contacts", std::span<const std::uint32_t>(ids), 5);
  archive.put("patches/normal_point_core", std::span<const double>(vectors), 12);
  archive.put("patches/depth_and_margin", std::span<const double>(scalars), 2);
  archive.put("patches/flags", std::span<const std::uint8_t>(flags), 6);
  archive.put("patches/contacts", std::span<const std::uint32_t>(set.contacts));
  archive.put("patches/depth_along_normal", std::span<const double>(set.depthAlongNormal));
  archive.put("patches/patch_of_contact", std::span<const std::uint32_t>(set.patchOfContact));
  archive.put("patches/flipped", std::span<const std::uint8_t>(set.flipped));
  const NarrowPhaseStats& s = set.stats;
  std::vector<std::int64_t> stats{static_cast<std::int64_t>(s.patches), static_cast<std::int64_t>(s.candidates),
                                  static_cast<std::int64_t>(s.lookAheads), static_cast<std::int64_t>(s.lookAheadsDecided),
                                  static_cast<std::int64_t>(s.unvalidated), static_cast<std::int64_t>(s.contactLines),
                                  static_cast<std::int64_t>(s.splits), static_cast<std::int64_t>(s.reused)};
  for (const std::size_t c : s.byCase) stats.push_back(static_cast<std::int64_t>(c));
  archive.put("patches/statistics", std::span<const std::int64_t>(stats));
}

bool restorePatches(StateReader& r, PatchSet& out, const ContactSet& contacts, std::size_t bodies, std::size_t planes) {
  const std::vector<std::uint32_t> ids = r.get<std::uint32_t>("patches/bodies_plane_and_contacts", 5);
  const std::size_t n = ids.size() / 5;
  const std::vector<double> vectors = r.get<double>("patches/normal_point_core", 12, n);
  const std::vector<double> scalars = r.get<double>("patches/depth_and_margin", 2, n);
  const std::vector<std::uint8_t> flags = r.get<std::uint8_t>("patches/flags", 6, n);
  std::vector<std::uint32_t> members = r.get<std::uint32_t>("patches/contacts");
  const std::size_t nc = contacts.contacts.size();
  std::vector<double> along = r.get<double>("patches/depth_along_normal", 1, nc);
  std::vector<std::uint32_t> patchOf = r.get<std::uint32_t>("patches/patch_of_contact", 1, nc);
  std::vector<std::uint8_t> flipped = r.get<std::uint8_t>("patches/flipped", 1, nc);
  const std::vector<std::int64_t> stats = r.get<std::int64_t>("patches/statistics", 1, 8 + kPlaneCaseCount);
  if (!r.ok()) return false;
  r.checkIndices(members, nc, "patches' contacts");
  for (const std::uint32_t p : patchOf)
    if (!optionalBelow(p, n)) r.fail("the checkpoint's contacts name a patch it does not have");
  if (!r.ok()) return false;
  out.patches.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t* id = ids.data() + 5 * i;
    ContactPatch& p = out.patches[i];
    if (id[0] >= bodies || !optionalBelow(id[1], bodies) || !optionalBelow(id[2], planes) ||
        static_cast<std::uint64_t>(id[3]) + id[4] > members.size() || !takeFlags(flags.data() + 6 * i, p)) {
      r.fail("checkpoint patch " + std::to_string(i) + " names bodies, a plane, contacts or a case the world does not have");
      return false;
    }
    p.a = BodyId(id[0]);
    p.b = BodyId(id[1]);
    p.plane = PlaneId(id[2]);
    p.first = id[3];
    p.count = id[4];
    const double* v = vectors.data() + 12 * i;
    p.normal = Vec3(v[0], v[1], v[2]);
    p.point = Vec3(v[3], v[4], v[5]);
    p.core[0] = Vec3(v[6], v[7], v[8]);
    p.core[1] = Vec3(v[9], v[10], v[11]);
    p.depth = scalars[2 * i];
    p.margin = scalars[2 * i + 1];
  }
  out.contacts.assign(members.begin(), members.end());
  out.depthAlongNormal.assign(along.begin(), along.end());
  out.patchOfContact.assign(patchOf.begin(), patchOf.end());
  out.flipped.assign(flipped.begin(), flipped.end());
  NarrowPhaseStats& s = out.stats;
  const auto count = [&](std::size_t k) { return static_cast<std::size_t>(std::max<std::int64_t>(stats[k], 0)); };
  s.patches = count(0);
  s.candidates = count(1);
  s.lookAheads = count(2);
  s.lookAheadsDecided = count(3);
  s.unvalidated = count(4);
  s.contactLines = count(5);
  s.splits = count(6);
  s.reused = count(7);
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) s.byCase[k] = count(8 + k);
  return true;
}

void NormalCache::save(StateArchive& archive) const {
  archive.putVec3("normals/normal", normals_);
  std::vector<double> faces;
  std::vector<std::uint8_t> counts;
  faces.reserve(9 * faces_.size());
  for (const Faces& f : faces_) {
    for (const Vec3& v : f.normal) faces.insert(faces.end(), {v.x(), v.y(), v.z()});
    counts.push_back(f.count);
  }
  archive.put("normals/faces", std::span<const double>(faces), 9);
  archive.put("normals/face_count", std::span<const std::uint8_t>(counts));
  std::vector<std::uint32_t> free(free_.begin(), free_.end());
  archive.put("normals/free", std::span<const std::uint32_t>(free));
}

bool NormalCache::restore(StateReader& r) {
  std::vector<Vec3> normals = r.vec3("normals/normal");
  const std::size_t n = normals.size();
  const std::vector<double> faces = r.get<double>("normals/faces", 9, n);
  const std::vector<std::uint8_t> counts = r.get<std::uint8_t>("normals/face_count", 1, n);
  const std::vector<std::uint32_t> free = r.get<std::uint32_t>("normals/free");
  if (!r.ok()) return false;
  r.checkIndices(free, n, "free normal entries");
  for (const std::uint8_t c : counts)
    if (c > 3) r.fail("a checkpoint normal entry has " + std::to_string(c) + " faces; expected at most 3");
  if (!r.ok()) return false;
  normals_ = std::move(normals);
  faces_.assign(n, Faces{});
  for (std::size_t i = 0; i < n; ++i) {
    faces_[i].count = counts[i];
    for (std::size_t k = 0; k < 3; ++k)
      faces_[i].normal[k] = Vec3(faces[9 * i + 3 * k], faces[9 * i + 3 * k + 1], faces[9 * i + 3 * k + 2]);
  }
  free_.assign(free.begin(), free.end());
  users_.assign(n, 0);  // (counted by countUsers())
  shared_.clear();
  return true;
}

void NarrowPhase::saveCache(StateArchive& archive) const {
  const Cache cache = wholeCache();
  std::vector<std::uint32_t> groups;
  std::vector<Quat> rotation;
  std::vector<Vec3> position;
  for (const CachedGroup& g : cache.groups) {
    groups.insert(groups.end(), {g.key.kind, g.key.a, g.key.b, g.pairFirst, g.pairCount, g.patchFirst, g.patchCount});
    rotation.push_back(g.relRotation);
    position.push_back(g.relPosition);
  }
  archive.put("narrow_phase/groups", std::span<const std::uint32_t>(groups), 7);
  archive.putQuat("narrow_phase/group_rotation", rotation);
  archive.putVec3("narrow_phase/group_position", position);
  std::vector<std::uint32_t> pairs;
  for (const auto& [a, b] : cache.pairs) pairs.insert(pairs.end(), {raw(a), raw(b)});
  archive.put("narrow_phase/pairs", std::span<const std::uint32_t>(pairs), 2);
  archive.put("narrow_phase/order", std::span<const std::uint32_t>(cache.order));
  std::vector<double> vectors, margin;
  std::vector<std::uint32_t> count;
  std::vector<std::uint8_t> flags;
  for (const CachedPatch& p : cache.patches) {
    for (const Vec3* v : {&p.normal, &p.core[0], &p.core[1]}) vectors.insert(vectors.end(), {v->x(), v->y(), v->z()});
    margin.push_back(p.margin);
    count.push_back(p.count);
    putFlags(flags, p.planeCase, p.source, p.validated, p.lookAhead, p.lookAheadCase, p.curvedSide);
  }
  archive.put("narrow_phase/patch_normal_core", std::span<const double>(vectors), 9);
  archive.put("narrow_phase/patch_margin", std::span<const double>(margin));
  archive.put("narrow_phase/patch_count", std::span<const std::uint32_t>(count));
  archive.put("narrow_phase/patch_flags", std::span<const std::uint8_t>(flags), 6);
  std::vector<std::uint8_t> normalSide;
  for (const CachedPatch& p : cache.patches) normalSide.push_back(static_cast<std::uint8_t>(p.normalSide));
  archive.put("narrow_phase/patch_normal_side", std::span<const std::uint8_t>(normalSide));
}

bool NarrowPhase::restoreCache(StateReader& r) {
  const std::vector<std::uint32_t> groups = r.get<std::uint32_t>("narrow_phase/groups", 7);
  const std::size_t ng = groups.size() / 7;
  const std::vector<Quat> rotation = r.quat("narrow_phase/group_rotation", ng);
  const std::vector<Vec3> position = r.vec3("narrow_phase/group_position", ng);
  const std::vector<std::uint32_t> pairs = r.get<std::uint32_t>("narrow_phase/pairs", 2);
  const std::size_t np = pairs.size() / 2;
  std::vector<std::uint32_t> order = r.get<std::uint32_t>("narrow_phase/order", 1, np);
  const std::vector<double> vectors = r.get<double>("narrow_phase/patch_normal_core", 9);
  const std::size_t nq = vectors.size() / 9;
  const std::vector<double> margin = r.get<double>("narrow_phase/patch_margin", 1, nq);
  const std::vector<std::uint32_t> count = r.get<std::uint32_t>("narrow_phase/patch_count", 1, nq);
  const std::vector<std::uint8_t> flags = r.get<std::uint8_t>("narrow_phase/patch_flags", 6, nq);
  // (a checkpoint written before normals were carried in B's frame has none: every normal is in A's)
  const std::vector<std::uint8_t> normalSide = r.has("narrow_phase/patch_normal_side")
                                                   ? r.get<std::uint8_t>("narrow_phase/patch_normal_side", 1, nq)
                                                   : std::vector<std::uint8_t>(nq, 0);
  if (!r.ok()) return false;
  Cache c;
  c.groups.resize(ng);
  for (std::size_t k = 0; k < ng; ++k) {
    const std::uint32_t* g = groups.data() + 7 * k;
    CachedGroup& cg = c.groups[k];
    cg.key = GroupKey{g[0], g[1], g[2]};
    cg.pairFirst = g[3];
    cg.pairCount = g[4];
    cg.patchFirst = g[5];
    cg.patchCount = g[6];
    cg.relRotation = rotation[k];
    cg.relPosition = position[k];
    bool fits = g[0] <= 1 && (k == 0 || c.groups[k - 1].key < cg.key) && g[4] > 0 &&
                static_cast<std::uint64_t>(g[3]) + g[4] <= np && static_cast<std::uint64_t>(g[5]) + g[6] <= nq;
    // the patches of a group take its contacts in turn (NarrowPhase::reuse), each once
    std::uint64_t taken = 0;
    for (std::uint32_t j = 0; fits && j < g[6]; ++j) taken += count[g[5] + j];
    fits = fits && taken == g[4];
    for (std::uint32_t j = 0; fits && j < g[4]; ++j) fits = order[g[3] + j] < g[4];
    if (!fits) {
      r.fail("checkpoint narrow-phase group " + std::to_string(k) + " does not fit its pairs and patches");
      return false;
    }
  }
  c.pairs.resize(np);
  for (std::size_t i = 0; i < np; ++i) c.pairs[i] = {ParticleId(pairs[2 * i]), ParticleId(pairs[2 * i + 1])};
  c.order.assign(order.begin(), order.end());
  c.patches.resize(nq);
  for (std::size_t i = 0; i < nq; ++i) {
    CachedPatch& p = c.patches[i];
    if (!takeFlags(flags.data() + 6 * i, p)) {
      r.fail("checkpoint narrow-phase patch " + std::to_string(i) + " has a case or source out of range");
      return false;
    }
    const double* v = vectors.data() + 9 * i;
    p.normal = Vec3(v[0], v[1], v[2]);
    p.core[0] = Vec3(v[3], v[4], v[5]);
    p.core[1] = Vec3(v[6], v[7], v[8]);
    p.margin = margin[i];
    p.count = count[i];
    if (normalSide[i] > 1) {
      r.fail("checkpoint narrow-phase patch " + std::to_string(i) + " has a normal side out of range");
      return false;
    }
    p.normalSide = static_cast<std::int8_t>(normalSide[i]);
  }
  cache_ = std::move(c);
  everyKeepsCache();  // (with processes, every process keeps every entry until its first run)
  return true;
}

void Broadphase::restoreBody(BodyId id, const Aabb& fat, bool isStatic) {
  if (proxies_.size() <= id.index()) proxies_.resize(id.index() + 1);
  Proxy& p = proxies_[id.index()];
  p.isStatic = isStatic;
  p.node = (isStatic ? static_ : moving_).createProxy(fat, 0.0, id.value);
  copyFatBox(id);
  if (!isStatic) movingBodies_.insert(std::lower_bound(movingBodies_.begin(), movingBodies_.end(), id), id);
  if (moved_.size() <= id.index()) moved_.resize(id.index() + 1, 0);
  pairsDirty_ = true;
}

}  // namespace volpar
