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

Vec3 cachedWorldNormal(const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals, ParticleId p) {
  const std::int32_t k = particles.normalIndex[p.index()];
  if (k < 0) return Vec3::Zero();
  return bodies.state[particles.body[p.index()].index()].orientation * normals[k];
}

Vec3 NarrowPhase::worldNormal(const NarrowPhaseInput& in, ParticleId p) const {
  return cachedWorldNormal(*in.particles, *in.bodies, *in.normals, p);
}

void NarrowPhase::run(const NarrowPhaseInput& in, const ContactSet& contacts, PatchSet& out) {
  out.patches.clear();
  out.contacts.clear();
  out.stats = NarrowPhaseStats{};
  out.depthAlongNormal.assign(contacts.contacts.size(), 0.0);
  out.patchOfContact.assign(contacts.contacts.size(), 0);
  if (mark_.size() < in.particles->size()) mark_.resize(in.particles->size(), 0);
  for (const ContactGroup& g : contacts.groups) makePatches(in, contacts, g, out);
}

void NarrowPhase::makePatches(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, PatchSet& out) {
  const std::uint32_t m = g.count;
  parent_.resize(m);
  std::iota(parent_.begin(), parent_.end(), 0u);
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
        if (j != i && (plane || near(c[i].b, cj->b)) && c[i].normal.dot(cj->normal) > 0.2) unite(parent_, i, j);
      }
    };
    visit(c[i].a);
    for (const ParticleId n : in.finder->neighbours(c[i].a)) visit(n);
  }
  // patches in the order of their first contact
  order_.resize(m);
  std::iota(order_.begin(), order_.end(), 0u);
  for (std::uint32_t i = 0; i < m; ++i) parent_[i] = findRoot(parent_, i);
  std::stable_sort(order_.begin(), order_.end(), [&](std::uint32_t x, std::uint32_t y) { return parent_[x] < parent_[y]; });
  std::uint32_t k = 0;
  while (k < m) {
    ContactPatch patch;
    patch.a = g.a;
    patch.b = g.b;
    patch.plane = g.plane;
    patch.first = static_cast<std::uint32_t>(out.contacts.size());
    const std::uint32_t root = parent_[order_[k]];
    for (; k < m && parent_[order_[k]] == root; ++k) out.contacts.push_back(g.first + order_[k]);
    patch.count = static_cast<std::uint32_t>(out.contacts.size()) - patch.first;
    solvePatch(in, set, patch, out);
    for (std::uint32_t i = patch.first; i < patch.first + patch.count; ++i)
      out.patchOfContact[out.contacts[i]] = static_cast<std::uint32_t>(out.patches.size());
    out.patches.push_back(patch);
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

PlaneCase NarrowPhase::classify(const NarrowPhaseInput& in, const Side& a, const Side& b) const {
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

void NarrowPhase::ring(const NarrowPhaseInput& in, std::span<const ParticleId> seeds, int k, std::vector<ParticleId>& out) {
  out.clear();
  if (++stamp_ == 0) {  // wrapped: clear the marks
    std::fill(mark_.begin(), mark_.end(), 0u);
    stamp_ = 1;
  }
  frontier_.clear();
  for (const ParticleId s : seeds) {
    if (mark_[s.index()] == stamp_) continue;
    mark_[s.index()] = stamp_;
    out.push_back(s);
    frontier_.push_back(s);
  }
  for (int r = 0; r < k; ++r) {
    next_.clear();
    for (const ParticleId p : frontier_)
      for (const ParticleId n : in.finder->neighbours(p)) {
        if (mark_[n.index()] == stamp_) continue;
        mark_[n.index()] = stamp_;
        out.push_back(n);
        next_.push_back(n);
      }
    std::swap(frontier_, next_);
  }
}

bool NarrowPhase::lookAhead(const NarrowPhaseInput& in, ParticleId a, ParticleId b, std::vector<Vec3>& pointsA,
                            std::vector<Vec3>& pointsB, Vec3& contactDifference) {
  const ParticleStore& p = *in.particles;
  const BodyStore& bodies = *in.bodies;
  const ParticleId seedA[1] = {a};
  const ParticleId seedB[1] = {b};
  ring(in, seedA, 1, aheadA_);
  ring(in, seedB, 1, aheadB_);
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
    const Vec3 w = s.angularVelocity * tau;
    const double angle = w.norm();
    const Vec3 arm = x - s.position;
    const Vec3 turned = angle > 1e-15 ? Vec3(Eigen::AngleAxisd(angle, w / angle) * arm) : arm;
    return s.position + s.linearVelocity * tau + turned;
  };

  for (int k = 1; k <= settings_.lookAheadSteps; ++k) {
    const double shift = k * delta;
    const bool moving = approach > 0.0 && shift / approach <= 8.0 * in.dt;
    aheadPosA_.resize(aheadA_.size());
    aheadPosB_.resize(aheadB_.size());
    for (std::size_t i = 0; i < aheadA_.size(); ++i)
      aheadPosA_[i] = moving ? predict(aheadA_[i], shift / approach) : p.position[aheadA_[i].index()];
    for (std::size_t j = 0; j < aheadB_.size(); ++j)
      aheadPosB_[j] = moving ? predict(aheadB_[j], shift / approach) : Vec3(p.position[aheadB_[j].index()] - n * shift);
    // touching pairs between the two small neighbourhoods
    pointsA.clear();
    pointsB.clear();
    std::size_t found = 0;
    Vec3 firstPoint = Vec3::Zero();
    contactDifference = Vec3::Zero();
    sideA_.particles.clear();
    sideB_.particles.clear();
    for (std::size_t i = 0; i < aheadA_.size(); ++i)
      for (std::size_t j = 0; j < aheadB_.size(); ++j) {
        const double rs = p.radius[aheadA_[i].index()] + p.radius[aheadB_[j].index()];
        const Vec3 d = aheadPosB_[j] - aheadPosA_[i];
        if (!(d.squaredNorm() < rs * rs) || aheadA_[i] == aheadB_[j]) continue;
        if (p.body[aheadA_[i].index()] == p.body[aheadB_[j].index()] && in.finder->connected(aheadA_[i], aheadB_[j])) continue;
        const Vec3 point = aheadPosA_[i] + d * (p.radius[aheadA_[i].index()] / rs);
        if (found == 0) firstPoint = point;
        else if (found == 1) contactDifference = point - firstPoint;
        ++found;
        if (std::find(sideA_.particles.begin(), sideA_.particles.end(), aheadA_[i]) == sideA_.particles.end()) {
          sideA_.particles.push_back(aheadA_[i]);
          pointsA.push_back(aheadPosA_[i]);
        }
        if (std::find(sideB_.particles.begin(), sideB_.particles.end(), aheadB_[j]) == sideB_.particles.end()) {
          sideB_.particles.push_back(aheadB_[j]);
          pointsB.push_back(aheadPosB_[j]);
        }
      }
    if (found >= 2) return true;
  }
  return false;
}

void NarrowPhase::addCandidates(const NarrowPhaseInput& in, const Side& a, const Side& b, const std::vector<Vec3>& pointsA,
                                const std::vector<Vec3>& pointsB, const Vec3& contactDifference, PlaneCase c, bool bIsPlane,
                                const Plane* plane) {
  candidates_.clear();
  auto add = [&](const Vec3& v, NormalSource s) {
    const double len = v.norm();
    if (len > 1e-9) candidates_.push_back({v / len, s});
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
        const bool seen = std::any_of(candidates_.begin(), candidates_.end(), [&](const Candidate& other) {
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

void NarrowPhase::solvePatch(const NarrowPhaseInput& in, const ContactSet& set, ContactPatch& patch, PatchSet& out) {
  const ParticleStore& p = *in.particles;
  const bool isPlane = patch.plane.valid();
  const std::uint32_t* idx = out.contacts.data() + patch.first;

  // the sides: unique particles, ascending
  sideA_.particles.clear();
  sideB_.particles.clear();
  std::size_t deepest = idx[0];
  for (std::uint32_t i = 0; i < patch.count; ++i) {
    const ParticleContact& c = set.contacts[idx[i]];
    sideA_.particles.push_back(c.a);
    if (!isPlane) sideB_.particles.push_back(c.b);
    if (c.depth > set.contacts[deepest].depth) deepest = idx[i];
  }
  for (auto* v : {&sideA_.particles, &sideB_.particles}) {
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
  positions(sideA_.particles, pointsA_, ra);
  positions(sideB_.particles, pointsB_, rb);
  const ParticleContact& deep = set.contacts[deepest];
  Vec3 contactDifference = patch.count >= 2 ? Vec3(set.contacts[idx[1]].point - set.contacts[idx[0]].point) : Vec3::Zero();

  // real particles of the patch (validation uses them even when a look-ahead supplies the geometry)
  ringA_.assign(sideA_.particles.begin(), sideA_.particles.end());
  ringB_.assign(sideB_.particles.begin(), sideB_.particles.end());

  Side& a = sideA_;
  Side& b = sideB_;
  if (isPlane) {
    describeSide(pointsA_, ra, a);
    patch.planeCase = PlaneCase::ParticlePlane;
  } else {
    if (patch.count == 1 && settings_.lookAheadSteps > 0) {
      ++out.stats.lookAheads;
      patch.lookAhead = lookAhead(in, deep.a, deep.b, pointsA_, pointsB_, contactDifference);
      if (!patch.lookAhead) {  // no second contact: back to the real single contact
        sideA_.particles.assign(1, deep.a);
        sideB_.particles.assign(1, deep.b);
        pointsA_.assign(1, p.position[deep.a.index()]);
        pointsB_.assign(1, p.position[deep.b.index()]);
      }
    }
    describeSide(pointsA_, ra, a);
    describeSide(pointsB_, rb, b);
    patch.planeCase = classify(in, a, b);
  }
  const Plane* plane = isPlane ? &in.planes[patch.plane.index()] : nullptr;
  addCandidates(in, a, b, pointsA_, pointsB_, contactDifference, patch.planeCase, isPlane, plane);

  // validation against the k-ring neighbourhoods of the real patch particles
  seedsA_.assign(ringA_.begin(), ringA_.end());
  seedsB_.assign(ringB_.begin(), ringB_.end());
  ring(in, seedsA_, settings_.validationRings, ringA_);
  ring(in, seedsB_, settings_.validationRings, ringB_);
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
  for (Candidate& cand : candidates_) {
    const Vec3 orient = ref.norm() > 1e-12 ? ref : fallback;
    if (cand.normal.dot(orient) < 0.0) cand.normal = -cand.normal;
    // the patch's own particles always count; a neighbour only if it is interior or its surface faces the
    // plane (around a concave corner the neighbourhood wraps onto a face that the plane must not judge)
    auto counts = [&](ParticleId q, std::size_t seeds, std::size_t i, double sign) {
      if (i < seeds) return true;
      const Vec3 nq = worldNormal(in, q);
      return nq.isZero() || sign * nq.dot(cand.normal) > 0.05;
    };
    double slack = std::numeric_limits<double>::infinity();
    double reachA = -std::numeric_limits<double>::infinity();  // farthest A sphere along n
    double reachB = std::numeric_limits<double>::infinity();   // nearest B sphere along n
    for (std::size_t i = 0; i < ringA_.size(); ++i) {
      if (!counts(ringA_[i], seedsA_.size(), i, 1.0)) continue;
      const Vec3& x = p.position[ringA_[i].index()];
      slack = std::min(slack, -cand.normal.dot(x - deep.point));
      reachA = std::max(reachA, cand.normal.dot(x) + p.radius[ringA_[i].index()]);
    }
    for (std::size_t i = 0; i < ringB_.size(); ++i) {
      if (!counts(ringB_[i], seedsB_.size(), i, -1.0)) continue;
      const Vec3& x = p.position[ringB_[i].index()];
      slack = std::min(slack, cand.normal.dot(x - deep.point));
      reachB = std::min(reachB, cand.normal.dot(x) - p.radius[ringB_[i].index()]);
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
  out.stats.candidates += candidates_.size();
  patch.normal = best.normal;
  patch.source = best.source;
  patch.margin = bestMargin;
  patch.validated = bestValid;
  patch.point = deep.point;
  if (!patch.validated) ++out.stats.unvalidated;
  ++out.stats.patches;
  ++out.stats.byCase[static_cast<std::size_t>(patch.planeCase)];

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
