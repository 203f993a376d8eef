#include "volpar/collision/plane_solver.hpp"

#include "volpar/collision/polytope_cores.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

namespace volpar {

namespace {

constexpr double kFacing = 0.05;      // a neighbour's normal faces the other side: n . d above this
constexpr double kCapLean = 0.2;      // a normal leaning along a cylinder's axis by more than this is on its cap
constexpr double kFaceReach = 8.0;    // x radius: how far along a face its outermost centre is searched
constexpr std::size_t kFaceVisits = 64;  // most particles of a face searched for its outermost centre
constexpr int kFitRings = 3;          // rings of neighbours a curved core's fit reaches
constexpr double kFan = 0.94;        // cos 20 degrees: faces closer than this beside each other are a curved surface's
constexpr double kFlat = 0.99985;     // cos 1 degree: the normals of a flat side agree within this
constexpr double kAcross = 0.3;       // a sheet faces a direction that crosses it at more than 17 degrees

}  // namespace

void PlaneSolver::ring(const NarrowPhaseInput& in, std::span<const ParticleId> seeds, int k, std::vector<ParticleId>& out,
                       std::vector<std::uint32_t>& mark, std::uint32_t& stamp, std::vector<ParticleId>& frontier,
                       std::vector<ParticleId>& next) {
  out.clear();
  if (mark.size() < in.particles->size()) mark.resize(in.particles->size(), 0);
  if (++stamp == 0) {  // wrapped: clear the marks
    std::fill(mark.begin(), mark.end(), 0u);
    stamp = 1;
  }
  frontier.clear();
  for (const ParticleId s : seeds) {
    if (mark[s.index()] == stamp) continue;
    mark[s.index()] = stamp;
    out.push_back(s);
    frontier.push_back(s);
  }
  for (int r = 0; r < k; ++r) {
    next.clear();
    for (const ParticleId p : frontier)
      for (const ParticleId n : in.finder->neighbours(p)) {
        if (mark[n.index()] == stamp) continue;
        mark[n.index()] = stamp;
        out.push_back(n);
        next.push_back(n);
      }
    std::swap(frontier, next);
  }
}

void PlaneSolver::gather(const NarrowPhaseInput& in, Side& side, int rings) {
  ring(in, side.particles, rings, ringIds_, mark_, stamp_, frontier_, next_);
  const ParticleStore& p = *in.particles;
  side.local.resize(ringIds_.size());
  BodyId rotated;
  Mat3 r = Mat3::Identity();
  for (std::size_t i = 0; i < ringIds_.size(); ++i) {
    const ParticleId q = ringIds_[i];
    Local& l = side.local[i];
    l.x = p.position[q.index()];
    l.r = p.radius[q.index()];
    l.id = q;
    l.flags = p.flags[q.index()];
    l.own = i < side.particles.size();
    l.faceCount = 0;
    l.n = Vec3::Zero();
    const std::int32_t k = p.normalIndex[q.index()];
    if (k >= 0) {
      if (p.body[q.index()] != rotated) {
        rotated = p.body[q.index()];
        r = in.bodies->state[rotated.index()].orientation.toRotationMatrix();
      }
      l.n = r * (*in.normals)[k];
      const std::span<const Vec3> f = in.normals->faces(k);
      l.faceCount = static_cast<std::uint8_t>(f.size());
      for (std::size_t j = 0; j < f.size(); ++j) l.faces[j] = r * f[j];
    } else {
      l.flags = static_cast<std::uint8_t>(l.flags & ~kParticleSurface);
    }
  }
}

bool PlaneSolver::presents(const Local& q, const Vec3& towards) {
  // a sheet shows a face only to what is across it, not to particles beside it in its own layer
  return !(q.flags & kParticleSheet) || q.faceCount == 0 || std::abs(q.faces[0].dot(towards)) >= kAcross;
}

Vec3 PlaneSolver::facing(const Local& q, const Vec3& towards) {
  return facingNormal(q.flags, q.n, std::span<const Vec3>(q.faces.data(), q.faceCount), towards);
}

bool PlaneSolver::counts(const Local& q, const Vec3& towards) {
  if (q.own || !(q.flags & kParticleSurface) || (q.flags & (kParticleSheet | kParticleLine)) || q.n.isZero()) return true;
  return q.n.dot(towards) > kFacing;
}

bool PlaneSolver::select(Side& side, const Vec3& towards) {
  bool changed = false;
  std::size_t k = 0;
  for (std::uint32_t i = 0; i < side.local.size(); ++i) {
    if (!counts(side.local[i], towards)) continue;
    if (k >= side.hullLocal.size() || side.hullLocal[k] != i) changed = true;
    if (k < side.hullLocal.size()) side.hullLocal[k] = i;
    else side.hullLocal.push_back(i);
    ++k;
  }
  changed = changed || k != side.hullLocal.size();
  side.hullLocal.resize(k);
  side.hull.resize(k);
  for (std::size_t j = 0; j < k; ++j) side.hull[j] = side.local[side.hullLocal[j]].x;
  return changed;
}

PlaneSolver::Evaluation PlaneSolver::evaluate(const Vec3& n) const {
  double maxA = -std::numeric_limits<double>::infinity(), reachA = maxA;
  double minB = std::numeric_limits<double>::infinity(), reachB = minB;
  for (const Local& q : a_.local) {
    if (!counts(q, n)) continue;
    const double h = n.dot(q.x);
    maxA = std::max(maxA, h);
    reachA = std::max(reachA, h + q.r);
  }
  for (const Local& q : b_.local) {
    if (!counts(q, -n)) continue;
    const double h = n.dot(q.x);
    minB = std::min(minB, h);
    reachB = std::min(reachB, h - q.r);
  }
  return {minB - maxA, reachB - reachA};
}

bool PlaneSolver::featureNormal(const Side& side, const HullDistance& h, bool isA, const Vec3& towards, Vec3& normal,
                                bool& flat) const {
  // the feature's particles with their barycentric weights; the surface normal at the closest point is
  // interpolated from those not on an edge or corner
  Vec3 sum = Vec3::Zero();
  double weight = 0.0;
  for (int k = 0; k < h.count; ++k) {
    const std::uint32_t hi = isA ? h.indexA[static_cast<std::size_t>(k)] : h.indexB[static_cast<std::size_t>(k)];
    const Local& q = side.local[side.hullLocal[hi]];
    if (!(q.flags & kParticleSurface) || (q.flags & kParticleSharp) || q.n.isZero()) continue;
    if ((q.flags & kParticleSheet) && (q.flags & kParticleEdge)) continue;  // a sheet's rim
    if (!presents(q, towards)) continue;
    const double w = h.weight[static_cast<std::size_t>(k)];
    sum += w * facing(q, towards);
    weight += w;
  }
  if (!(weight > 0.0) || !(sum.norm() > 1e-12)) return false;
  normal = sum.normalized();
  // flat: the normals of the side's counted surface particles near the closest point all agree
  const Vec3& at = isA ? h.pointA : h.pointB;
  const double reach = 3.0 * side.meanRadius;
  flat = true;
  for (const std::uint32_t i : side.hullLocal) {
    const Local& q = side.local[i];
    if (!(q.flags & kParticleSurface) || (q.flags & kParticleSharp) || q.n.isZero()) continue;
    if ((q.x - at).squaredNorm() > reach * reach) continue;
    if (facing(q, towards).dot(normal) < kFlat) {
      flat = false;
      break;
    }
  }
  return true;
}

PlaneSolver::Feature PlaneSolver::sharpFeature(const Side& side, const HullDistance& h, bool isA) const {
  // the faces common to the feature's edge and corner particles
  std::array<Vec3, 3> common{};
  std::size_t count = 0;
  bool first = true;
  for (int k = 0; k < h.count; ++k) {
    const std::uint32_t hi = isA ? h.indexA[static_cast<std::size_t>(k)] : h.indexB[static_cast<std::size_t>(k)];
    const Local& q = side.local[side.hullLocal[hi]];
    if (!(q.flags & (kParticleEdge | kParticleCorner)) || (q.flags & kParticleSheet) || q.faceCount < 2) continue;
    if (first) {
      for (std::size_t f = 0; f < q.faceCount; ++f) common[f] = q.faces[f];
      count = q.faceCount;
      first = false;
      continue;
    }
    std::size_t kept = 0;
    for (std::size_t f = 0; f < count; ++f) {
      bool shared = false;
      for (std::size_t g = 0; g < q.faceCount; ++g) shared = shared || common[f].dot(q.faces[g]) > kFlat;
      if (shared) common[kept++] = common[f];
    }
    count = kept;
  }
  Feature out;
  if (count < 2) return out;
  // each face plane through the outermost counted particle along its normal
  std::array<double, 3> offset{};
  for (std::size_t f = 0; f < count; ++f) {
    offset[f] = -std::numeric_limits<double>::infinity();
    for (const std::uint32_t i : side.hullLocal) offset[f] = std::max(offset[f], common[f].dot(side.local[i].x));
  }
  const Vec3& at = isA ? h.pointA : h.pointB;
  if (count == 3) {
    Mat3 m;
    for (int f = 0; f < 3; ++f) m.row(f) = common[static_cast<std::size_t>(f)].transpose();
    if (!(std::abs(m.determinant()) > 1e-6)) return out;
    out.kind = 1;
    out.point = m.partialPivLu().solve(Vec3(offset[0], offset[1], offset[2]));
    return out;
  }
  const Vec3 e = common[0].cross(common[1]);
  if (!(e.norm() > 1e-3)) return out;
  // the point of the line nearest to `at`: at + a f1 + b f2 on both planes
  const double g = common[0].dot(common[1]);
  const double r1 = offset[0] - common[0].dot(at), r2 = offset[1] - common[1].dot(at);
  const double det = 1.0 - g * g;
  out.kind = 2;
  out.direction = e.normalized();
  out.point = at + ((r1 - g * r2) / det) * common[0] + ((r2 - g * r1) / det) * common[1];
  return out;
}

namespace {

/// The vertices of the polytope n . x <= d of `planes` (duplicates merged) into `out`.
void polytopeVertices(const std::vector<std::pair<Vec3, double>>& planes, double scale, std::vector<Vec3>& out) {
  out.clear();
  const std::size_t n = planes.size();
  const double tol = 1e-9 * scale;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j) {
      const Vec3 ij = planes[i].first.cross(planes[j].first);
      if (!(ij.squaredNorm() > 1e-12)) continue;
      for (std::size_t k = j + 1; k < n; ++k) {
        const double det = ij.dot(planes[k].first);
        if (!(std::abs(det) > 1e-6)) continue;
        // Cramer's rule for the three planes
        const Vec3 x = (planes[i].second * planes[j].first.cross(planes[k].first) +
                        planes[j].second * planes[k].first.cross(planes[i].first) + planes[k].second * ij) /
                       det;
        bool inside = true;
        for (std::size_t m = 0; m < n && inside; ++m) inside = planes[m].first.dot(x) <= planes[m].second + tol;
        if (!inside) continue;
        bool seen = false;
        for (const Vec3& v : out) seen = seen || (v - x).squaredNorm() <= 100.0 * tol * tol;
        if (!seen) out.push_back(x);
      }
    }
}

}  // namespace

bool PlaneSolver::flatCluster(const FaceCluster& c, double spacing) {
  if (c.count < 2) return false;
  // the members' spread across the normal, in a basis (u, v) of the plane: a line of them (the smaller
  // principal variance about nothing) is a ruling of a curved surface
  const Vec3 n = c.sum.normalized();
  const Vec3 u = n.unitOrthogonal(), v = n.cross(u);
  const Vec3 mean = c.position / c.count;
  const Mat3 cov = c.spread / c.count - mean * mean.transpose();
  const double uu = u.dot(cov * u), vv = v.dot(cov * v), uv = u.dot(cov * v);
  const double half = 0.5 * (uu + vv), dev = std::sqrt(0.25 * (uu - vv) * (uu - vv) + uv * uv);
  return half - dev > 0.04 * spacing * spacing;
}

bool PlaneSolver::exactFeature(const Side& side, const HullDistance& h, bool isA, const Vec3& towards, double spacing) const {
  // the feature's faces: those its particles share (a facet of one face's particles: that face; an edge's
  // particles: its two faces; a corner: its three), each particle on each of their planes
  std::array<Vec3, 3> faces{};
  std::size_t count = 0;
  bool first = true;
  const double tol = 1e-7 * spacing;
  for (int k = 0; k < h.count; ++k) {
    if (!(h.weight[static_cast<std::size_t>(k)] > 0.0)) continue;
    const std::uint32_t hi = isA ? h.indexA[static_cast<std::size_t>(k)] : h.indexB[static_cast<std::size_t>(k)];
    const std::uint32_t li = side.hullLocal[hi];
    const Local& q = side.local[li];
    if (!(q.flags & kParticleSurface) || (q.flags & kParticleLine) || q.n.isZero()) return false;
    std::array<Vec3, 3> own{};
    std::size_t owned = 0;
    if (q.flags & kParticleSheet) {
      if (!presents(q, towards)) return false;
      own[owned++] = facing(q, towards);
      if ((q.flags & kParticleEdge) && q.faceCount == 3) own[owned++] = q.faces[2];
    } else if (q.flags & (kParticleEdge | kParticleCorner)) {
      for (std::size_t f = 0; f < q.faceCount; ++f) own[owned++] = q.faces[f];
    } else {
      if (li >= flatLocal_.size() || !flatLocal_[li]) return false;  // a curved surface: no exact feature
      own[owned++] = q.n;
    }
    if (first) {
      faces = own;
      count = owned;
      first = false;
    } else {
      std::size_t kept = 0;
      for (std::size_t f = 0; f < count; ++f) {
        bool shared = false;
        for (std::size_t g = 0; g < owned; ++g) shared = shared || faces[f].dot(own[g]) > kFlat;
        if (shared) faces[kept++] = faces[f];
      }
      count = kept;
    }
  }
  if (count == 0) return false;
  for (int k = 0; k < h.count; ++k) {
    if (!(h.weight[static_cast<std::size_t>(k)] > 0.0)) continue;
    const std::uint32_t hi = isA ? h.indexA[static_cast<std::size_t>(k)] : h.indexB[static_cast<std::size_t>(k)];
    const Vec3& x = side.local[side.hullLocal[hi]].x;
    for (std::size_t f = 0; f < count; ++f) {
      bool on = false;
      for (const auto& [n, d] : planes_) on = on || (n.dot(faces[f]) > kFlat && std::abs(n.dot(x) - d) <= tol);
      if (!on) return false;
    }
  }
  // the direction as a combination of the feature's face normals with no negative weight
  const double slack = 1e-9;
  if (count == 1) return towards.dot(faces[0]) > 1.0 - slack;
  if (count == 2) {
    if (std::abs(towards.dot(faces[0].cross(faces[1]).normalized())) > slack) return false;
    const double g = faces[0].dot(faces[1]), t0 = towards.dot(faces[0]), t1 = towards.dot(faces[1]);
    const double det = 1.0 - g * g;
    return det > 1e-9 && (t0 - g * t1) / det >= -slack && (t1 - g * t0) / det >= -slack;
  }
  Mat3 m;
  for (int f = 0; f < 3; ++f) m.col(f) = faces[static_cast<std::size_t>(f)];
  if (!(std::abs(m.determinant()) > 1e-6)) return false;
  const Vec3 w = m.partialPivLu().solve(towards);
  return w.minCoeff() >= -slack;
}

double PlaneSolver::faceSupport(const NarrowPhaseInput& in, const Vec3& f, ParticleId from) {
  const ParticleStore& p = *in.particles;
  // (the face normal in the frame of the body's cached normals; a face does not leave its body)
  const BodyId body = p.body[from.index()];
  const Vec3 fb = in.bodies->state[body.index()].orientation.conjugate() * f;
  const auto carries = [&](ParticleId q) {
    const std::int32_t k = p.normalIndex[q.index()];
    if (k < 0 || p.body[q.index()] != body) return false;
    if ((*in.normals)[k].dot(fb) > kFlat) return true;
    for (const Vec3& face : in.normals->faces(k))
      if (face.dot(fb) > kFlat) return true;
    return false;
  };
  // a face along the lattice: its particles beside `from` all stand at its height, and so does the rest
  const Vec3& origin = p.position[from.index()];
  const double level = f.dot(origin), step = 1e-6 * p.radius[from.index()];
  bool stepped = false;
  for (const ParticleId nb : in.finder->neighbours(from))
    if (std::abs(f.dot(p.position[nb.index()]) - level) > step && carries(nb)) {
      stepped = true;
      break;
    }
  if (!stepped) return level;
  // otherwise breadth first over the particles that carry the face, from `from`, up to kFaceVisits of them
  // within kFaceReach: a face oblique to the lattice is a staircase whose outermost steps recur every few
  // particles, so climbing to the nearest higher neighbour stops on a step that is not the face's top
  std::array<std::uint32_t, 2 * kFaceVisits> seen;  // open addressing, particle index + 1 (0: empty)
  seen.fill(0);
  const auto visit = [&](ParticleId q) {
    const std::uint32_t key = q.index() + 1;
    std::size_t slot = (key * 2654435761u) % seen.size();
    while (seen[slot] != 0) {
      if (seen[slot] == key) return false;
      slot = (slot + 1) % seen.size();
    }
    seen[slot] = key;
    return true;
  };
  std::array<ParticleId, kFaceVisits> queue;
  std::size_t head = 0, tail = 0;
  queue[tail++] = from;
  visit(from);
  const double within = kFaceReach * p.radius[from.index()];
  double best = level;
  while (head < tail) {
    const ParticleId at = queue[head++];
    for (const ParticleId nb : in.finder->neighbours(at)) {
      if (tail == queue.size()) break;
      if ((p.position[nb.index()] - origin).squaredNorm() > within * within || !carries(nb) || !visit(nb)) continue;
      // (higher by more than round-off: a face along the lattice keeps the height of its first particle)
      if (const double h = f.dot(p.position[nb.index()]); h > best + 1e-9 * p.radius[nb.index()]) best = h;
      queue[tail++] = nb;
    }
  }
  return best;
}

bool PlaneSolver::localCore(const NarrowPhaseInput& in, const Side& side, const HullDistance& h, bool isA,
                            const Vec3& towards, std::vector<Vec3>& out, bool& curved, bool& exact) {
  const Vec3& at = isA ? h.pointA : h.pointB;
  curved = false;
  exact = false;
  out.clear();
  const double spacing = 2.0 * side.meanRadius;
  const double nearReach = 1.5 * spacing;
  clusters_.clear();
  const auto addFace = [&](const Vec3& f, const Vec3& x, bool sharp, bool near) {
    for (FaceCluster& c : clusters_)
      if (c.first.dot(f) > kFlat) {
        c.sum += f;
        c.position += x;
        c.spread += x * x.transpose();
        ++c.count;
        c.sharp = c.sharp || sharp;
        c.near = c.near || near;
        return;
      }
    clusters_.push_back({f, f, x, x * x.transpose(), 1, sharp, near});
  };
  for (const std::uint32_t i : side.hullLocal) {
    const Local& q = side.local[i];
    if (!(q.flags & kParticleSurface) || (q.flags & kParticleLine) || q.n.isZero()) continue;
    const bool near = (q.x - at).squaredNorm() <= nearReach * nearReach;
    if (q.flags & kParticleSheet) {
      // a sheet: the side facing the contact (if it crosses the sheet); on its rim both sides and the rim's
      // face, whose planes cut out the sheet's core there, a strip of no thickness (its edge faces every way
      // from one side of the sheet round to the other)
      if ((q.flags & kParticleEdge) && q.faceCount == 3) {
        addFace(q.faces[0], q.x, true, near);
        addFace(q.faces[1], q.x, true, near);
        addFace(q.faces[2], q.x, true, near);
        continue;
      }
      if (presents(q, towards)) addFace(facing(q, towards), q.x, false, near);
      continue;
    }
    if (q.flags & (kParticleEdge | kParticleCorner)) {
      for (std::size_t f = 0; f < q.faceCount; ++f) addFace(q.faces[f], q.x, true, near);
      continue;
    }
    addFace(q.n, q.x, false, near);
  }
  if (clusters_.empty()) return false;
  // flat faces: normals shared by several particles or by an edge; curved: many distinct normals near `at`
  bool flatNear = false;
  int distinctNear = 0;
  // a face that an edge bounds is flat, unless faces a few degrees apart lie beside it: the rulings of a
  // curved surface (a cylinder's side, each ruling ending at the rim) in the lattice's steps
  for (FaceCluster& c : clusters_) {
    c.flat = flatCluster(c, spacing);
    if (c.flat || !c.sharp) continue;
    const Vec3 n = c.sum.normalized();
    int beside = 0;
    Mat3 fan = n * n.transpose();
    for (const FaceCluster& o : clusters_) {
      const Vec3 m = o.sum.normalized();
      if (&o == &c || o.first.dot(c.first) > kFlat || !(m.dot(n) > kFan)) continue;
      fan += m * m.transpose();
      ++beside;
    }
    // (a fan: the normals turn about one axis, as a cylinder's do)
    Eigen::SelfAdjointEigenSolver<Mat3> turn;
    if (beside >= 2) turn.computeDirect(fan);
    c.flat = beside == 0 || (beside >= 2 && !(turn.eigenvalues()[0] < 0.05 * turn.eigenvalues()[1]));
  }
  for (const FaceCluster& c : clusters_) {
    const bool flat = c.flat;
    if (c.near) {
      flatNear = flatNear || flat;
      ++distinctNear;
    }
  }
  // which particles lie on flat faces (the curvature fit leaves them out)
  flatLocal_.assign(side.local.size(), 0);
  for (const std::uint32_t i : side.hullLocal) {
    const Local& q = side.local[i];
    if (!(q.flags & kParticleSurface) || q.n.isZero()) continue;
    if (q.flags & (kParticleSharp | kParticleSheet)) {
      flatLocal_[i] = 1;
      continue;
    }
    for (const FaceCluster& c : clusters_)
      if (c.first.dot(q.n) > kFlat) {
        flatLocal_[i] = c.flat ? 1 : 0;
        break;
      }
  }
  if (!flatNear && distinctNear >= 2 && curvatureCentres(side, at, towards, out)) {
    curved = true;
    return true;
  }
  int curvedNear = 0;
  for (const FaceCluster& c : clusters_) curvedNear += c.near && !c.flat ? 1 : 0;
  if (flatNear && curvedNear >= 1 && roundedCore(in, side, at, towards, out)) {
    curved = true;
    return true;
  }
  // the polytope: each face plane through the outermost counted centre along it, boxed in around `at`
  planes_.clear();
  for (const FaceCluster& c : clusters_) {
    const bool flat = c.flat;
    if (!flat && !c.near) continue;
    const Vec3 n = c.sum.normalized();
    if (n.dot(towards) < -0.1) continue;  // a face turned away cannot hold the closest point
    double d = -std::numeric_limits<double>::infinity();
    std::uint32_t top = side.hullLocal.front();
    for (const std::uint32_t i : side.hullLocal)
      if (const double along = n.dot(side.local[i].x); along > d) {
        d = along;
        top = i;
      }
    if (flat) d = std::max(d, faceSupport(in, n, side.local[top].id));
    planes_.emplace_back(n, d);
  }
  // the particles' hull already is the core at its closest feature when every particle of the feature lies
  // on the planes of its (flat) faces and the direction lies in the feature's normal cone
  exact = exactFeature(side, h, isA, towards, spacing);
  return !planes_.empty();
}

bool PlaneSolver::coreVertices(std::vector<std::pair<Vec3, double>>& planes, const Vec3& at, double reach,
                               std::vector<Vec3>& out) {
  out.clear();
  // a face, an edge or a corner: points whose hull is the core near `at` (a square of the face; the edge
  // line with a strip of each face; the corner with a stretch of each edge); more planes (a staircase of
  // faces, tangent planes of a curved part next to flat ones): the polytope's vertices inside a box
  const std::size_t faces = planes.size();
  if (faces == 1) {
    const Vec3& n = planes[0].first;
    const Vec3 o = at + (planes[0].second - n.dot(at)) * n;
    const Vec3 u = n.unitOrthogonal() * reach, v = n.cross(n.unitOrthogonal()) * reach;
    out.assign({o + u + v, o + u - v, o - u + v, o - u - v});
    return true;
  }
  if (faces == 2) {
    const Vec3 &f1 = planes[0].first, &f2 = planes[1].first;
    const Vec3 e = f1.cross(f2);
    if (e.norm() > 1e-3) {
      const Vec3 dir = e.normalized();
      const double g = f1.dot(f2), r1 = planes[0].second - f1.dot(at), r2 = planes[1].second - f2.dot(at);
      const double det = 1.0 - g * g;
      const Vec3 o = at + ((r1 - g * r2) / det) * f1 + ((r2 - g * r1) / det) * f2;
      // along each face away from the edge (into the solid side of the other face)
      Vec3 t1 = f1.cross(dir), t2 = f2.cross(dir);
      if (t1.dot(f2) > 0.0) t1 = -t1;
      if (t2.dot(f1) > 0.0) t2 = -t2;
      for (const double s : {-reach, reach}) {
        const Vec3 p = o + s * dir;
        out.push_back(p);
        out.push_back(p + reach * t1);
        out.push_back(p + reach * t2);
      }
      return true;
    }
  }
  if (faces == 3) {
    Mat3 m;
    for (int f = 0; f < 3; ++f) m.row(f) = planes[static_cast<std::size_t>(f)].first.transpose();
    if (std::abs(m.determinant()) > 1e-3) {
      const Vec3 corner = m.partialPivLu().solve(Vec3(planes[0].second, planes[1].second, planes[2].second));
      out.push_back(corner);
      // each edge (two planes meet) runs away from the corner into the third plane's solid side
      for (int f = 0; f < 3; ++f) {
        const Vec3& a = planes[static_cast<std::size_t>((f + 1) % 3)].first;
        const Vec3& b = planes[static_cast<std::size_t>((f + 2) % 3)].first;
        Vec3 e = a.cross(b).normalized();
        if (e.dot(planes[static_cast<std::size_t>(f)].first) > 0.0) e = -e;
        out.push_back(corner + reach * e);
      }
      return true;
    }
  }
  for (int k = 0; k < 3; ++k) {
    planes.emplace_back(Vec3::Unit(k), at[k] + reach);
    planes.emplace_back(-Vec3::Unit(k), reach - at[k]);
  }
  polytopeVertices(planes, reach + at.norm(), out);
  planes.resize(faces);
  return !out.empty();
}

bool PlaneSolver::curvatureCentres(const Side& side, const Vec3& at, const Vec3& towards, std::vector<Vec3>& out) const {
  out.clear();
  const double reach = 6.0 * side.meanRadius;
  // the particles of the curved surface near `at`, and their normals
  struct Ray {
    Vec3 x, n;
  };
  std::array<Ray, 256> rays;
  std::size_t count = 0;
  for (const std::uint32_t i : side.hullLocal) {
    const Local& q = side.local[i];
    if (!(q.flags & kParticleSurface) || (q.flags & kParticleSharp) || q.n.isZero()) continue;
    if ((q.flags & kParticleSheet) && (q.flags & kParticleEdge)) continue;
    if (!presents(q, towards)) continue;
    if (i < flatLocal_.size() && flatLocal_[i]) continue;
    if ((q.x - at).squaredNorm() > reach * reach) continue;
    const Vec3 n = facing(q, towards);
    if (!(n.dot(towards) > kFacing)) continue;
    if (count == rays.size()) break;  // (far more than a surface holds within six radii of one point)
    rays[count++] = {q.x, n};
  }
  // least squares: the point c nearest to the lines x_i + t n_i, sum (I - n_i n_i^T) c = sum (I - n_i n_i^T) x_i,
  // over the rays `use` accepts
  const auto centre = [&](const auto& use, Vec3& c, Vec3& meanNormal, Vec3& meanPosition, Mat3& normals) {
    Mat3 m = Mat3::Zero();
    Vec3 rhs = Vec3::Zero();
    normals = Mat3::Zero();
    meanNormal = meanPosition = Vec3::Zero();
    int used = 0;
    for (std::size_t k = 0; k < count; ++k) {
      if (!use(rays[k])) continue;
      const Vec3& n = rays[k].n;
      const Mat3 p = Mat3::Identity() - n * n.transpose();
      m += p;
      rhs += p * rays[k].x;
      normals += n * n.transpose();
      meanNormal += n;
      meanPosition += rays[k].x;
      ++used;
    }
    if (used < 4) return false;
    meanNormal.normalize();
    meanPosition /= used;
    Eigen::SelfAdjointEigenSolver<Mat3> eig;
    eig.computeDirect(m);
    const Vec3 mu = eig.eigenvalues();
    if (!(mu[0] > 1e-12 * mu[2])) return false;
    c = Vec3::Zero();
    for (int k = 0; k < 3; ++k) c += eig.eigenvectors().col(k).dot(rhs) / mu[k] * eig.eigenvectors().col(k);
    return c.allFinite();
  };
  Vec3 c, meanNormal, meanPosition;
  Mat3 normals;
  if (!centre([](const Ray&) { return true; }, c, meanNormal, meanPosition, normals)) return false;
  // the normals spread over a cone (a surface curved both ways) or a fan in one plane (curved one way:
  // a cylinder, whose axis is the plane's normal)
  Eigen::SelfAdjointEigenSolver<Mat3> spread;
  spread.computeDirect(normals);
  if (!(spread.eigenvalues()[1] > 1e-6 * spread.eigenvalues()[2])) return false;  // all alike: flat
  // a cylinder whose side may end in a rounded cap (a capsule): the normals that lean along the axis belong
  // to the cap and pull the side's fit off its axis; the side is fitted without them (the split made again
  // with the side's own axis), and the cap, where there is one, ends the axis at its own centre
  Vec3 axis = spread.eigenvectors().col(0);
  const auto onSide = [&](const Ray& r) { return std::abs(r.n.dot(axis)) <= kCapLean; };
  const auto onCap = [&](const Ray& r) { return std::abs(r.n.dot(axis)) > kCapLean; };
  Vec3 sideCentre = Vec3::Zero(), sideNormal = Vec3::Zero(), sidePosition = Vec3::Zero();
  Mat3 sideNormals;
  bool sideFit = false, sideFan = false;
  for (int pass = 0; pass < 2; ++pass) {
    if (!centre(onSide, sideCentre, sideNormal, sidePosition, sideNormals)) break;
    Eigen::SelfAdjointEigenSolver<Mat3> sideSpread;
    sideSpread.computeDirect(sideNormals);
    if (!(sideSpread.eigenvalues()[1] > 1e-6 * sideSpread.eigenvalues()[2])) break;
    axis = sideSpread.eigenvectors().col(0);
    sideFit = true;
    sideFan = sideSpread.eigenvalues()[0] < 0.1 * sideSpread.eigenvalues()[1];
  }
  Vec3 capCentre = Vec3::Zero(), capNormal = Vec3::Zero(), capPosition = Vec3::Zero();
  Mat3 capNormals;
  const bool cap = sideFan && centre(onCap, capCentre, capNormal, capPosition, capNormals) && (capCentre - capPosition).dot(capNormal) < 0.0;
  // which model the normal lines fit: all through one point (a sphere), or the side's through the axis line
  // and the cap's through the cap's centre (a capsule near where its side meets its cap, whose normals
  // spread over a cone too)
  bool cylinder = spread.eigenvalues()[0] < 0.1 * spread.eigenvalues()[1];
  if (!cylinder && sideFan) {
    const auto offPoint = [](const Ray& r, const Vec3& p) { return ((p - r.x) - (p - r.x).dot(r.n) * r.n).squaredNorm(); };
    double sphere = 0.0, capsule = 0.0;
    for (std::size_t k = 0; k < count; ++k) {
      const Ray& r = rays[k];
      sphere += offPoint(r, c);
      if (onSide(r)) {
        const Vec3 m = axis.cross(r.n);
        capsule += m.squaredNorm() > 1e-12 ? std::pow((r.x - sideCentre).dot(m), 2) / m.squaredNorm() : offPoint(r, sideCentre);
      } else {
        // (leaning normals without a cap to meet: no capsule)
        capsule += cap ? offPoint(r, capCentre) : std::numeric_limits<double>::infinity();
      }
    }
    // (a sphere's lines meet within 2 % of its radius: its normals' own error, not a capsule's side)
    const double floor = static_cast<double>(count) * std::pow(0.02 * (c - meanPosition).norm(), 2);
    cylinder = sphere > floor && capsule < 0.25 * sphere;
  }
  if (!cylinder) {
    // a convex surface has its centre behind it; a concave one (a cloth wrapped round what it touches, the
    // inside of a bowl) has it in front, and is no sphere about it
    if (!((c - meanPosition).dot(meanNormal) < 0.0)) return false;
    out.push_back(c);
    return true;
  }
  if (sideFit) {
    // the centre: the point of the side's axis line nearest the lines, whatever its place along the axis
    c = sideCentre;
    meanNormal = sideNormal;
    meanPosition = sidePosition;
  }
  if (!((c - meanPosition).dot(meanNormal) < 0.0)) return false;
  const double half = 20.0 * side.meanRadius;
  if (cap) {
    // the axis from the cap's centre (projected onto it) away from the cap
    const double along = (capCentre - c).dot(axis);
    const Vec3 end = c + along * axis;
    out.push_back(end);
    out.push_back(end - (along >= 0.0 ? half : -half) * axis);
    return end.allFinite();
  }
  out.push_back(c - half * axis);
  out.push_back(c + half * axis);
  return c.allFinite();
}

bool PlaneSolver::roundedCore(const NarrowPhaseInput& in, const Side& side, const Vec3& at, const Vec3& towards,
                              std::vector<Vec3>& out) {
  // a surface curved one way (a cylinder's side) that flat faces cut off (its caps): the fitted cylinder's
  // rulings every few degrees round from `at`, each clipped by the flat faces' planes; their hull is the core
  // there, its rim a fine polygon instead of the few tangent planes of the particles beside the contact
  // the curved particles facing the other side within a few spacings (more rings than validation looks at: a
  // single contact's ring holds too few of them to fit)
  const double within = 6.0 * side.meanRadius;
  wide_.particles.assign(side.particles.begin(), side.particles.end());
  gather(in, wide_, kFitRings);
  curvedLocal_.clear();
  for (std::uint32_t i = 0; i < wide_.local.size(); ++i) {
    const Local& q = wide_.local[i];
    if (!(q.flags & kParticleSurface) || (q.flags & (kParticleSharp | kParticleSheet)) || q.n.isZero()) continue;
    if ((q.x - at).squaredNorm() > within * within || !(q.n.dot(towards) > kFacing)) continue;
    bool flat = false;
    for (const FaceCluster& c : clusters_) flat = flat || (c.flat && c.first.dot(q.n) > kFlat);
    if (!flat) curvedLocal_.push_back(i);
  }
  // the axis: the direction the normals spread least along; normals that lean along it (the blend of a
  // side and its cap in estimated normals) are left out, and the axis found again
  Vec3 axis = Vec3::Zero();
  for (int pass = 0; pass < 2; ++pass) {
    Mat3 spread = Mat3::Zero();
    int count = 0;
    for (const std::uint32_t i : curvedLocal_) {
      const Vec3& n = wide_.local[i].n;
      if (pass == 1 && std::abs(n.dot(axis)) > 0.2) continue;
      spread += n * n.transpose();
      ++count;
    }
    if (count < 4) return false;
    Eigen::SelfAdjointEigenSolver<Mat3> eig;
    eig.computeDirect(spread);
    if (!(eig.eigenvalues()[0] < 0.1 * eig.eigenvalues()[1])) return false;  // curved both ways: no cylinder
    axis = eig.eigenvectors().col(0);
  }
  // the axis' point nearest to the normal lines, in the plane across the axis
  Mat3 m = Mat3::Zero();
  Vec3 rhs = Vec3::Zero(), meanPosition = Vec3::Zero(), meanNormal = Vec3::Zero();
  int count = 0;
  const Mat3 across = Mat3::Identity() - axis * axis.transpose();
  for (const std::uint32_t i : curvedLocal_) {
    const Local& q = wide_.local[i];
    if (std::abs(q.n.dot(axis)) > 0.2) continue;
    const Vec3 n = (across * q.n).normalized();
    const Mat3 p = across - n * n.transpose();
    m += p;
    rhs += p * q.x;
    meanPosition += q.x;
    meanNormal += n;
    ++count;
  }
  if (count < 4) return false;
  meanPosition /= count;
  m += axis * axis.transpose();  // (fixes the point's position along the axis at the particles' mean)
  rhs += axis * axis.dot(meanPosition);
  const Vec3 c = m.partialPivLu().solve(rhs);
  if (!c.allFinite() || !((c - meanPosition).dot(meanNormal) < 0.0)) return false;
  double radius = 0.0;
  for (const std::uint32_t i : curvedLocal_) radius = std::max(radius, (across * (wide_.local[i].x - c)).norm());
  Vec3 u = at - c;
  u -= u.dot(axis) * axis;
  if (!(radius > 0.0) || !(u.norm() > 1e-9 * radius)) return false;
  u.normalize();
  const Vec3 v = axis.cross(u);
  // the flat faces' planes, each through the outermost local particle along it
  planes_.clear();
  for (const FaceCluster& f : clusters_) {
    if (!f.flat) continue;
    const Vec3 n = f.sum.normalized();
    double d = -std::numeric_limits<double>::infinity();
    for (const std::uint32_t i : side.hullLocal) d = std::max(d, n.dot(side.local[i].x));
    planes_.emplace_back(n, d);
  }
  const double reach = 20.0 * side.meanRadius;
  out.clear();
  constexpr int kSteps = 20;               // each way round from `at`
  constexpr double kStep = 3.0 * std::numbers::pi / 180.0;
  for (int k = -kSteps; k <= kSteps; ++k) {
    const double t = k * kStep;
    const Vec3 base = c + radius * (std::cos(t) * u + std::sin(t) * v);
    double lo = -reach, hi = reach;
    for (const auto& [n, d] : planes_) {
      const double along = n.dot(axis), room = d - n.dot(base);
      if (std::abs(along) < 1e-9) {
        if (room < 0.0) hi = lo - 1.0;
      } else if (along > 0.0) {
        hi = std::min(hi, room / along);
      } else {
        lo = std::max(lo, room / along);
      }
    }
    if (!(lo <= hi)) continue;
    out.push_back(base + lo * axis);
    out.push_back(base + hi * axis);
  }
  return out.size() >= 4;
}

void PlaneSolver::curvedCore(bool onA, bool onB, Choice& out) const {
  if (onA == onB) return;
  const std::vector<Vec3>& centres = onA ? centresA_ : centresB_;
  if (centres.empty() || centres.size() > 2) return;
  out.curvedSide = onA ? 0 : 1;
  out.core = {centres.front(), centres.back()};
}

PlaneSolver::Choice PlaneSolver::separationPlane(const NarrowPhaseInput& in, const Vec3& d0) {
  Choice out;
  out.open = true;
  select(a_, d0);
  select(b_, -d0);
  if (a_.hull.empty() || b_.hull.empty()) return out;
  hull_ = hullDistance(a_.hull, b_.hull);
  if (!hull_.separated) return out;
  // the counted particles along the hulls' direction, and the closest points again if they changed
  const Vec3 d1 = hull_.direction;
  const bool changedA = select(a_, d1);  // both sides are selected again, whatever the first returns
  const bool changedB = select(b_, -d1);
  if (changedA || changedB) {
    const HullDistance again = hullDistance(a_.hull, b_.hull);
    if (!again.separated) {
      select(a_, d0);
      select(b_, -d0);
    } else {
      hull_ = again;
    }
  }
  const Vec3 nG = hull_.direction;
  out.found = true;
  out.normal = nG;
  out.source = NormalSource::Separation;
  // the sides' cores near the closest points, rebuilt from the faces their particles carry
  // (a deformable sheet or chain has no core to rebuild: it has no inside, its normals estimate a surface
  // that bends from step to step, and its particles are all there is of it; a cloth's face planes, turned
  // along its folds, would cut off a polytope that is not there)
  const auto thinDeformable = [&](const Side& side) {
    const ParticleStore& p = *in.particles;
    if (in.kindOf(p.body[side.particles.front().index()]) != BodyKind::Deformable) return false;
    for (const ParticleId q : side.particles)
      if (!(p.flags[q.index()] & (kParticleSheet | kParticleLine))) return false;
    return true;
  };
  const bool thinA = thinDeformable(a_), thinB = thinDeformable(b_);
  // a side without a core: its counted particles' hull, a thin deformable side's own touching particles (against a
  // curved core the direction turns from one of them to the next: each patch's plane is its own contacts')
  const auto coreless = [](const Side& side, bool thin) {
    return thin ? std::span<const Vec3>(side.points) : std::span<const Vec3>(side.hull);
  };
  bool curvedA = false, curvedB = false, exactA = false, exactB = false;
  const bool coreA = !thinA && localCore(in, a_, hull_, true, nG, centresA_, curvedA, exactA);
  planesA_.assign(planes_.begin(), planes_.end());
  if (!coreA) planesA_.clear();
  const bool coreB = !thinB && localCore(in, b_, hull_, false, -nG, centresB_, curvedB, exactB);
  planesB_.assign(planes_.begin(), planes_.end());
  if (!coreB) planesB_.clear();
  if (exactA && exactB) {  // the particles' hulls are the cores at their closest features
    out.source = NormalSource::Surface;
    out.open = hull_.count == 1;  // vertex on vertex
    out.settled = true;
    return out;
  }
  // a side whose core there is one face: a half-space, whose closest-point direction to anything is its
  // normal (of two such faces, the one across which the particles are farther apart)
  const Vec3 faceA = coreA && !curvedA && planesA_.size() == 1 ? planesA_[0].first : Vec3::Zero();
  const Vec3 faceB = coreB && !curvedB && planesB_.size() == 1 ? Vec3(-planesB_[0].first) : Vec3::Zero();
  if (!faceA.isZero() || !faceB.isZero()) {
    Vec3 n = faceA.isZero() ? faceB : faceA;
    if (!faceA.isZero() && !faceB.isZero() && evaluate(faceB).separation > evaluate(faceA).separation) n = faceB;
    if (n.dot(nG) > 0.5) {
      out.normal = n;
      out.source = NormalSource::Surface;
      out.open = false;
      out.settled = true;
      return out;
    }
  }
  if (coreA && !curvedA) coreVertices(planesA_, hull_.pointA, 12.0 * a_.meanRadius, coreA_);
  else coreA_.assign(centresA_.begin(), centresA_.end());
  if (coreB && !curvedB) coreVertices(planesB_, hull_.pointB, 12.0 * b_.meanRadius, coreB_);
  else coreB_.assign(centresB_.begin(), centresB_.end());
  if (coreA || coreB) {
    const HullDistance c = hullDistance(coreA ? std::span<const Vec3>(coreA_) : coreless(a_, thinA),
                                        coreB ? std::span<const Vec3>(coreB_) : coreless(b_, thinB));
    if (c.separated && c.direction.dot(nG) > 0.5) {
      out.normal = c.direction;
      out.source = NormalSource::Surface;
      curvedCore(curvedA && thinB, curvedB && thinA, out);
      // corner on corner: two points, their line is all the geometry says
      int pointsA = 0, pointsB = 0;
      for (int k = 0; k < c.count; ++k) {
        bool seenA = false, seenB = false;
        for (int l = 0; l < k; ++l) {
          seenA = seenA || c.indexA[static_cast<std::size_t>(l)] == c.indexA[static_cast<std::size_t>(k)];
          seenB = seenB || c.indexB[static_cast<std::size_t>(l)] == c.indexB[static_cast<std::size_t>(k)];
        }
        pointsA += seenA ? 0 : 1;
        pointsB += seenB ? 0 : 1;
      }
      out.open = coreA && coreB && !curvedA && !curvedB && pointsA == 1 && pointsB == 1;
      return out;
    }
  }
  Vec3 nA, nB;
  bool flatA = false, flatB = false;
  const bool surfA = featureNormal(a_, hull_, true, nG, nA, flatA);
  const bool surfB = featureNormal(b_, hull_, false, -nG, nB, flatB);
  if (!surfA && !surfB) {
    // edge on edge: across both edges; edge and corner: from the line to the point; corner and corner:
    // between the points; where a feature cannot be rebuilt, the hulls' direction
    const Feature fa = sharpFeature(a_, hull_, true), fb = sharpFeature(b_, hull_, false);
    Vec3 n = Vec3::Zero();
    if (fa.kind == 2 && fb.kind == 2) {
      const Vec3 cross = fa.direction.cross(fb.direction);
      if (cross.norm() > 0.1) {
        n = cross.normalized();
        if (n.dot(nG) < 0.0) n = -n;
      } else {
        const Vec3 d = fb.point - fa.point;
        n = d - d.dot(fa.direction) * fa.direction;
      }
    } else if (fa.kind == 2 && fb.kind == 1) {
      const Vec3 d = fb.point - fa.point;
      n = d - d.dot(fa.direction) * fa.direction;
    } else if (fa.kind == 1 && fb.kind == 2) {
      const Vec3 d = fb.point - fa.point;
      n = d - d.dot(fb.direction) * fb.direction;
    } else if (fa.kind == 1 && fb.kind == 1) {
      n = fb.point - fa.point;
    }
    if (n.norm() > 1e-9 && n.normalized().dot(nG) > 0.5) {
      out.normal = n.normalized();
      out.source = NormalSource::Surface;
      out.open = fa.kind != 2 && fb.kind != 2;  // (an edge fixes the normal's plane)
    }
    return out;
  }
  // a curved side is a sphere (or cylinder) about its centres of curvature: the normal is the closest-point
  // direction of those centres and the other side (its centres, when curved too)
  flatLocal_.clear();  // (no face clusters here: every non-sharp particle takes part)
  curvedA = surfA && !flatA && curvatureCentres(a_, hull_.pointA, nG, centresA_);
  curvedB = surfB && !flatB && curvatureCentres(b_, hull_.pointB, -nG, centresB_);
  Vec3 n = Vec3::Zero();
  if (curvedA || curvedB) {
    const HullDistance c = hullDistance(curvedA ? std::span<const Vec3>(centresA_) : coreless(a_, thinA),
                                        curvedB ? std::span<const Vec3>(centresB_) : coreless(b_, thinB));
    if (c.separated) {
      n = c.direction;
      curvedCore(curvedA && thinB && !curvedB, curvedB && thinA && !curvedA, out);
    }
  }
  if (n.isZero()) {
    if (surfA && !surfB) {
      n = nA;
    } else if (surfB && !surfA) {
      n = -nB;
    } else if (flatA != flatB) {
      n = flatA ? nA : Vec3(-nB);
    } else if (flatA) {
      // two flat faces: the one across which the particles are farther apart
      n = evaluate(nA).separation >= evaluate(-nB).separation ? nA : Vec3(-nB);
    } else {
      n = (nA - nB).normalized();
    }
  }
  if (!(n.dot(nG) > 0.0)) return out;
  out.normal = n;
  out.source = NormalSource::Surface;
  out.open = false;
  return out;
}

bool PlaneSolver::lookAhead(const NarrowPhaseInput& in, bool single, double sink, Vec3& normal,
                            PlaneCase& predicted, NarrowPhaseStats& stats) {
  const ParticleStore& p = *in.particles;
  const BodyStore& bodies = *in.bodies;
  // each local particle's velocity: its rigid body's motion at it, a deformable particle's own
  const auto velocity = [&](const Local& q) -> Vec3 {
    const BodyId b = p.body[q.id.index()];
    switch (in.kindOf(b)) {
      case BodyKind::Static: return Vec3::Zero();
      case BodyKind::Deformable: return p.velocity[q.id.index()];
      default: {
        const BodyState& s = bodies.state[b.index()];
        return s.linearVelocity + s.angularVelocity.cross(q.x - s.position);
      }
    }
  };
  velocityA_.resize(a_.local.size());
  velocityB_.resize(b_.local.size());
  for (std::size_t i = 0; i < a_.local.size(); ++i) velocityA_[i] = velocity(a_.local[i]);
  for (std::size_t j = 0; j < b_.local.size(); ++j) velocityB_[j] = velocity(b_.local[j]);
  // a pair at rest has nothing to foresee
  double fastest = 0.0;
  for (const Vec3& v : velocityA_) fastest = std::max(fastest, v.squaredNorm());
  for (const Vec3& v : velocityB_) fastest = std::max(fastest, v.squaredNorm());
  events_.clear();
  if (!(fastest > 1e-18)) return false;
  ++stats.lookAheads;
  // the first time two centres, d + t v apart, come within `reach` of each other: |d + t v| = reach (infinity
  // when they never do; 0 when they already are)
  const auto closesTo = [](const Vec3& d, const Vec3& v, double reach) {
    constexpr double kNever = std::numeric_limits<double>::infinity();
    if (!(reach > 0.0)) return kNever;
    const double c = d.squaredNorm() - reach * reach;
    if (!(c > 0.0)) return 0.0;
    const double a = v.squaredNorm(), bb = d.dot(v);
    if (!(a > 1e-18) || !(bb < 0.0)) return kNever;
    const double disc = bb * bb - a * c;
    if (disc < 0.0) return kNever;
    return (-bb - std::sqrt(disc)) / a;
  };
  const auto between = [&](std::uint32_t i, std::uint32_t j) {
    return std::pair<Vec3, Vec3>(b_.local[j].x - a_.local[i].x, velocityB_[j] - velocityA_[i]);
  };
  // The motion is followed in straight lines, as if nothing pushed back. That holds only until a pair of
  // spheres in the configuration has sunk `sink` deeper into each other than it is now (a touching pair,
  // or one of the pairs met on the way, from touching): from there on its contact turns the motion, and a
  // configuration further on is not the one the pair comes to.
  double trusted = 8.0 * in.dt;  // the horizon
  for (std::uint32_t i = 0; i < a_.particles.size(); ++i)
    for (std::uint32_t j = 0; j < b_.particles.size(); ++j) {
      const auto [d, v] = between(i, j);
      trusted = std::min(trusted, closesTo(d, v, std::min(d.norm(), a_.local[i].r + b_.local[j].r) - sink));
    }
  // the time each pair of local spheres not yet touching meets, within the horizon: |d + t v| = r_i + r_j
  for (std::uint32_t i = 0; i < a_.local.size(); ++i)
    for (std::uint32_t j = 0; j < b_.local.size(); ++j) {
      const auto [d, v] = between(i, j);
      const double t = closesTo(d, v, a_.local[i].r + b_.local[j].r);
      if (t > 0.0 && t <= trusted) events_.push_back({t, i, j});
    }
  if (events_.empty()) return false;
  std::sort(events_.begin(), events_.end(), [](const Event& x, const Event& y) {
    return x.time != y.time ? x.time < y.time : (x.i != y.i ? x.i < y.i : x.j < y.j);
  });
  // the configuration after each new contact, until it has a plane of its own: two contacts for a single
  // contact, an edge on a face for parallel edges
  const auto at = [&](const Side& side, const std::vector<Vec3>& v, std::uint32_t k, double t) -> Vec3 {
    return side.local[k].x + t * v[k];
  };
  for (std::size_t e = 0; e < events_.size(); ++e) {
    const double t = events_[e].time;
    if (t > trusted) return false;
    {
      const auto [d, v] = between(events_[e].i, events_[e].j);
      trusted = std::min(trusted, closesTo(d, v, a_.local[events_[e].i].r + b_.local[events_[e].j].r - sink));
    }
    if (e + 1 < events_.size() && events_[e + 1].time == t) continue;  // take simultaneous contacts together
    aheadA_.particles.clear();
    aheadB_.particles.clear();
    aheadA_.points.clear();
    aheadB_.points.clear();
    const auto addPair = [&](std::uint32_t i, std::uint32_t j) {
      if (std::find(aheadA_.particles.begin(), aheadA_.particles.end(), a_.local[i].id) == aheadA_.particles.end()) {
        aheadA_.particles.push_back(a_.local[i].id);
        aheadA_.points.push_back(at(a_, velocityA_, i, t));
      }
      if (std::find(aheadB_.particles.begin(), aheadB_.particles.end(), b_.local[j].id) == aheadB_.particles.end()) {
        aheadB_.particles.push_back(b_.local[j].id);
        aheadB_.points.push_back(at(b_, velocityB_, j, t));
      }
    };
    // the patch's own contacts (the own particles come first in `local`) and the new ones so far
    std::size_t pairs = 0;
    for (std::uint32_t i = 0; i < a_.particles.size(); ++i)
      for (std::uint32_t j = 0; j < b_.particles.size(); ++j) {
        const double rs = a_.local[i].r + b_.local[j].r;
        if ((at(b_, velocityB_, j, t) - at(a_, velocityA_, i, t)).squaredNorm() < rs * rs) {
          addPair(i, j);
          ++pairs;
        }
      }
    for (std::size_t k = 0; k <= e; ++k) {
      addPair(events_[k].i, events_[k].j);
      ++pairs;
    }
    aheadA_.meanRadius = a_.meanRadius;
    aheadB_.meanRadius = b_.meanRadius;
    describe(aheadA_);
    describe(aheadB_);
    const PlaneCase c = classify(in, aheadA_, aheadB_);
    const bool resolved = single ? pairs >= 2
                                 : (c == PlaneCase::EdgeFace23 || c == PlaneCase::EdgeFace33 || c == PlaneCase::FaceFace ||
                                    c == PlaneCase::VertexFace13);
    if (!resolved) continue;
    // the plane of that configuration: the closest points of the counted local particles, moved there
    coreA_.clear();
    coreB_.clear();
    for (const std::uint32_t i : a_.hullLocal) coreA_.push_back(at(a_, velocityA_, i, t));
    for (const std::uint32_t j : b_.hullLocal) coreB_.push_back(at(b_, velocityB_, j, t));
    // (the predicted contacts themselves carry the configuration's features)
    const HullDistance h = hullDistance(aheadA_.points, aheadB_.points);
    const HullDistance local = hullDistance(coreA_, coreB_);
    Vec3 n = Vec3::Zero();
    if (c == PlaneCase::FaceFace || c == PlaneCase::EdgeFace33 || c == PlaneCase::EdgeFace23 || c == PlaneCase::VertexFace13) {
      // a face in contact: its best-fit plane
      const Side& face = (!aheadA_.collinear && aheadA_.particles.size() >= 3) ? aheadA_ : aheadB_;
      n = face.face;
      if (n.dot(aheadB_.centroid - aheadA_.centroid) < 0.0) n = -n;
    } else if (local.separated) {
      n = local.direction;
    } else if (h.separated) {
      n = h.direction;
    }
    if (n.isZero()) return false;
    normal = n.normalized();
    predicted = c;
    return true;
  }
  return false;
}

void PlaneSolver::describe(Side& side) const {
  const auto& points = side.points;
  const std::size_t n = points.size();
  side.centroid = Vec3::Zero();
  for (const Vec3& x : points) side.centroid += x;
  side.centroid /= static_cast<double>(std::max<std::size_t>(n, 1));
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
  for (const Vec3& x : points) cov += (x - side.centroid) * (x - side.centroid).transpose();
  Eigen::SelfAdjointEigenSolver<Mat3> eig;
  eig.computeDirect(cov);
  side.line = eig.eigenvectors().col(2);
  double farthest = 0.0;
  for (const Vec3& x : points) {
    const Vec3 d = x - side.centroid;
    farthest = std::max(farthest, (d - d.dot(side.line) * side.line).norm());
  }
  side.collinear = farthest <= settings_.collinearTolerance * side.meanRadius;
  if (!side.collinear) side.face = eig.eigenvectors().col(0);
}

PlaneCase PlaneSolver::classify(const NarrowPhaseInput& in, const Side& a, const Side& b) {
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

void PlaneSolver::paperCandidates(const NarrowPhaseInput& in, const Vec3& contactDifference, PlaneCase c) {
  auto& cands = candidates_;
  cands.clear();
  auto add = [&](const Vec3& v, NormalSource s) {
    const double len = v.norm();
    if (len > 1e-9) cands.push_back({v / len, s});
  };
  const Side& a = a_;
  const Side& b = b_;
  const bool aSmall = a.particles.size() <= b.particles.size();
  const Side& s = aSmall ? a : b;
  const Side& l = aSmall ? b : a;
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
    const Vec3 v = s.points[0] - l.centroid;
    add(v - v.dot(l.line) * l.line, NormalSource::LinePerpendicular);
    add(l.line.cross(contactDifference), NormalSource::LineContactPoints);
    if (c == PlaneCase::EdgeEdge12) {
      // the single particle's edge: its neighbours with the same cached normal lie along it
      const ParticleId q = s.particles[0];
      const Vec3 nq = cachedWorldNormal(*in.particles, *in.bodies, *in.normals, q);
      for (const ParticleId nb : in.finder->neighbours(q)) {
        if ((cachedWorldNormal(*in.particles, *in.bodies, *in.normals, nb) - nq).norm() > 1e-6) continue;
        add((in.particles->position[nb.index()] - in.particles->position[q.index()]).cross(l.line), NormalSource::NeighbourLine);
        break;
      }
    }
  }
  // cached surface normals of each side: the faces behind them, and their mean
  const auto cached = [&](const Side& side, double sign, NormalSource source) {
    Vec3 mean = Vec3::Zero();
    for (std::size_t i = 0; i < side.particles.size() && i < side.local.size(); ++i) {
      const Local& q = side.local[i];
      if (q.n.isZero()) continue;
      mean += q.n;
      for (std::size_t f = 0; f < q.faceCount; ++f) add(sign * q.faces[f], source);
    }
    add(sign * mean, source);
  };
  cached(a, 1.0, NormalSource::CachedA);
  cached(b, -1.0, NormalSource::CachedB);
  add(b.centroid - a.centroid, NormalSource::CentreLine);
}

void PlaneSolver::solve(const NarrowPhaseInput& in, const ContactSet& set, std::span<const std::uint32_t> idx,
                        std::span<const std::uint8_t> flipped, ContactPatch& patch, std::span<double> depthAlongNormal,
                        NarrowPhaseStats& stats) {
  const ParticleStore& p = *in.particles;
  const bool isPlane = patch.plane.valid();
  const auto isFlipped = [&](std::uint32_t ci) { return !flipped.empty() && flipped[ci] != 0; };
  ++stats.patches;

  // the deepest contact, and the sides' own particles (unique, ascending)
  std::uint32_t deepest = idx[0];
  a_.particles.clear();
  b_.particles.clear();
  for (const std::uint32_t ci : idx) {
    const ParticleContact& c = set.contacts[ci];
    if (c.depth > set.contacts[deepest].depth) deepest = ci;
    const bool f = isFlipped(ci);
    a_.particles.push_back(f ? c.b : c.a);
    if (!isPlane) b_.particles.push_back(f ? c.a : c.b);
  }
  for (auto* v : {&a_.particles, &b_.particles}) {
    std::sort(v->begin(), v->end());
    v->erase(std::unique(v->begin(), v->end()), v->end());
  }
  const ParticleContact& deep = set.contacts[deepest];
  patch.point = deep.point;
  patch.lookAhead = false;

  if (isPlane) {
    // against a plane the plane's own normal is exact
    const Plane& pl = in.planes[patch.plane.index()];
    patch.planeCase = PlaneCase::ParticlePlane;
    patch.normal = -pl.normal;
    patch.source = NormalSource::Plane;
    patch.validated = true;
    patch.margin = std::numeric_limits<double>::infinity();
    patch.depth = 0.0;
    for (const std::uint32_t ci : idx) {
      const ParticleContact& c = set.contacts[ci];
      depthAlongNormal[ci] = c.depth;
      patch.depth = std::max(patch.depth, c.depth);
      patch.margin = std::min(patch.margin, -c.depth);
    }
    ++stats.candidates;
    ++stats.byCase[static_cast<std::size_t>(patch.planeCase)];
    return;
  }

  // the paper's case, from the sides' own particles
  for (Side* side : {&a_, &b_}) {
    side->points.clear();
    side->meanRadius = 0.0;
    for (const ParticleId q : side->particles) {
      side->points.push_back(p.position[q.index()]);
      side->meanRadius += p.radius[q.index()];
    }
    side->meanRadius /= static_cast<double>(std::max<std::size_t>(side->particles.size(), 1));
    describe(*side);
  }
  patch.planeCase = classify(in, a_, b_);
  ++stats.byCase[static_cast<std::size_t>(patch.planeCase)];

  // the local particles of both sides, and the plane across which they are farthest apart
  const auto gatherSides = [&](int rings) {
    gather(in, a_, rings);
    gather(in, b_, rings);
    if (patch.a != patch.b) return;
    // a body touching itself: neighbours within reach of both sides belong to neither (a layer pressed
    // together side by side shares them)
    const auto drop = [&](Side& from, const Side& other) {
      if (++stamp_ == 0) {
        std::fill(mark_.begin(), mark_.end(), 0u);
        stamp_ = 1;
      }
      for (const Local& q : other.local) mark_[q.id.index()] = stamp_;
      std::erase_if(from.local, [&](const Local& q) { return !q.own && mark_[q.id.index()] == stamp_; });
    };
    drop(a_, b_);
    drop(b_, a_);
  };
  gatherSides(settings_.validationRings);
  Vec3 d0 = Vec3::Zero();
  for (const std::uint32_t ci : idx) d0 += (isFlipped(ci) ? -1.0 : 1.0) * set.contacts[ci].normal;
  if (!(d0.norm() > 1e-12)) d0 = b_.centroid - a_.centroid;
  if (!(d0.norm() > 1e-12)) d0 = deep.normal;
  d0.normalize();
  const double rsum = p.radius[deep.a.index()] + p.radius[deep.b.index()];
  const double tol = settings_.validationTolerance * rsum;

  Vec3 best = d0;
  NormalSource bestSource = NormalSource::CentreLine;
  patch.curvedSide = -1;
  Evaluation bestEval{-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()};
  bool valid = false;
  Choice plane = separationPlane(in, d0);
  // where the plane is not settled by exact features, the cores are rebuilt from one ring more between two
  // rigid bodies: a face that bounds the core near the contact (an edge's second face, a staircase's next
  // step) may carry no particle of the first ring
  const auto rigid = [&](BodyId b) { return in.kindOf(b) != BodyKind::Deformable; };
  if (plane.found && !plane.settled && rigid(patch.a) && rigid(patch.b)) {
    gatherSides(settings_.validationRings + 1);
    const Choice wide = separationPlane(in, d0);
    if (wide.found) {
      plane = wide;
    } else {
      gatherSides(settings_.validationRings);
      plane = separationPlane(in, d0);
    }
  }
  if (plane.found) {
    Evaluation e = evaluate(plane.normal);
    ++stats.candidates;
    Vec3 n = plane.normal;
    NormalSource source = plane.source;
    if (!(e.separation >= -2.0 * tol) && source != NormalSource::Separation) {
      n = hull_.direction;
      source = NormalSource::Separation;
      e = evaluate(n);
      ++stats.candidates;
    }
    best = n;
    bestSource = source;
    bestEval = e;
    valid = e.separation >= -2.0 * tol;
    if (valid && source == plane.source) {
      patch.curvedSide = plane.curvedSide;
      patch.core = plane.core;
    }
    // a single contact or parallel edges: where the pair moves, its next contacts may decide
    const bool single = idx.size() == 1;
    if (valid && ((single && plane.open) || patch.planeCase == PlaneCase::EdgeEdge23)) {
      Vec3 ahead;
      PlaneCase predicted;
      const bool found = lookAhead(in, single, tol, ahead, predicted, stats);
      if (found && (!single || plane.open)) {
        if (ahead.dot(d0) < 0.0) ahead = -ahead;
        const Evaluation ea = evaluate(ahead);
        ++stats.candidates;
        if (ea.separation >= -2.0 * tol) {
          best = ahead;
          bestEval = ea;
          patch.lookAhead = true;
          patch.lookAheadCase = predicted;
          patch.curvedSide = -1;
          ++stats.lookAheadsDecided;
        }
      }
    }
  }
  if (!valid) {
    // the local hulls overlap: the paper's candidates, the validated one with the largest margin (or the
    // one that comes closest to validating)
    const Vec3 difference = idx.size() >= 2 ? Vec3(set.contacts[idx[1]].point - set.contacts[idx[0]].point) : Vec3::Zero();
    paperCandidates(in, difference, patch.planeCase);
    for (Candidate& cand : candidates_) {
      if (cand.normal.dot(d0) < 0.0) cand.normal = -cand.normal;
      const Evaluation e = evaluate(cand.normal);
      ++stats.candidates;
      const bool ok = e.separation >= -2.0 * tol;
      if ((ok && (!valid || e.margin > bestEval.margin)) || (!ok && !valid && e.separation > bestEval.separation)) {
        valid = ok;
        best = cand.normal;
        bestSource = cand.source;
        bestEval = e;
      }
    }
  }
  // nothing was evaluated (one contact between interior particles whose centres coincide): the centre
  // line's own margin, not the -infinity the search started from
  if (!std::isfinite(bestEval.margin)) {
    bestEval = evaluate(best);
    ++stats.candidates;
  }
  patch.normal = best;
  patch.source = bestSource;
  patch.normalSide = !patch.lookAhead && (bestSource == NormalSource::FaceB || bestSource == NormalSource::CachedB) ? 1 : 0;
  patch.margin = bestEval.margin;
  patch.validated = valid;
  if (!valid) ++stats.unvalidated;

  // depth of every contact along its normal: r_a + r_b - n . (x_b - x_a), the plane model's overlap, in which
  // a side's particle tops form a flat face
  patch.depth = 0.0;
  for (const std::uint32_t ci : idx) {
    const ParticleContact& c = set.contacts[ci];
    const Vec3 n = contactNormal(patch, p.position[c.a.index()], p.position[c.b.index()], isFlipped(ci));
    const double d = p.radius[c.a.index()] + p.radius[c.b.index()] - n.dot(p.position[c.b.index()] - p.position[c.a.index()]);
    depthAlongNormal[ci] = d;
    patch.depth = std::max(patch.depth, d);
  }
}

bool PlaneSolver::solveCores(const NarrowPhaseInput& in, const ContactSet& set, std::span<const std::uint32_t> idx,
                             ContactPatch& patch, std::span<double> depthAlongNormal, NarrowPhaseStats& stats) {
  const ParticleStore& p = *in.particles;
  // the two cores in the world
  const auto place = [&](BodyId body, std::vector<Vec3>& out) {
    const std::span<const Vec3> v = in.cores->vertices(body);
    const BodyState& s = in.bodies->state[body.index()];
    const Mat3 r = s.orientation.toRotationMatrix();
    out.resize(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) out[i] = s.position + r * v[i];
  };
  place(patch.a, coreA_);
  place(patch.b, coreB_);
  if (coreA_.empty() || coreB_.empty()) return false;
  const HullDistance h = hullDistance(coreA_, coreB_);
  if (!h.separated) return false;
  // a corner on a corner leaves the normal open
  const auto features = [&](const std::array<std::uint32_t, 4>& index) {
    std::array<std::uint32_t, 4> seen{};
    int n = 0;
    for (int k = 0; k < h.count; ++k) {
      const std::uint32_t v = index[static_cast<std::size_t>(k)];
      const bool known = std::find(seen.begin(), seen.begin() + n, v) != seen.begin() + n;
      if (!(h.weight[static_cast<std::size_t>(k)] > 0.0) || known) continue;
      seen[static_cast<std::size_t>(n++)] = v;
    }
    return n;
  };
  const int featuresA = features(h.indexA), featuresB = features(h.indexB);
  if (featuresA <= 1 && featuresB <= 1) return false;

  // the paper's case, from the sides' own particles (parallel edges are left to solve(), which looks ahead)
  std::uint32_t deepest = idx[0];
  a_.particles.clear();
  b_.particles.clear();
  for (const std::uint32_t ci : idx) {
    const ParticleContact& c = set.contacts[ci];
    if (c.depth > set.contacts[deepest].depth) deepest = ci;
    a_.particles.push_back(c.a);
    b_.particles.push_back(c.b);
  }
  for (Side* side : {&a_, &b_}) {
    std::sort(side->particles.begin(), side->particles.end());
    side->particles.erase(std::unique(side->particles.begin(), side->particles.end()), side->particles.end());
    side->points.clear();
    side->meanRadius = 0.0;
    for (const ParticleId q : side->particles) {
      side->points.push_back(p.position[q.index()]);
      side->meanRadius += p.radius[q.index()];
    }
    side->meanRadius /= static_cast<double>(side->particles.size());
    describe(*side);
  }
  const PlaneCase c = classify(in, a_, b_);
  if (c == PlaneCase::EdgeEdge23) return false;

  ++stats.patches;
  ++stats.candidates;
  ++stats.byCase[static_cast<std::size_t>(c)];
  patch.planeCase = c;
  patch.normal = h.direction;
  patch.source = NormalSource::Cores;
  // (a corner or an edge of A's core against a face of B's: the normal is that face's)
  patch.normalSide = featuresB >= 3 && featuresA <= 2 ? 1 : 0;
  patch.validated = true;
  patch.lookAhead = false;
  patch.curvedSide = -1;
  patch.point = set.contacts[deepest].point;
  // the contacts' depths along the normal; the margin of the patch's own spheres
  const Vec3& n = patch.normal;
  double topA = -std::numeric_limits<double>::infinity(), bottomB = std::numeric_limits<double>::infinity();
  for (const ParticleId q : a_.particles) topA = std::max(topA, n.dot(p.position[q.index()]) + p.radius[q.index()]);
  for (const ParticleId q : b_.particles) bottomB = std::min(bottomB, n.dot(p.position[q.index()]) - p.radius[q.index()]);
  patch.margin = bottomB - topA;
  patch.depth = 0.0;
  for (const std::uint32_t ci : idx) {
    const ParticleContact& ct = set.contacts[ci];
    const double d = p.radius[ct.a.index()] + p.radius[ct.b.index()] - n.dot(p.position[ct.b.index()] - p.position[ct.a.index()]);
    depthAlongNormal[ci] = d;
    patch.depth = std::max(patch.depth, d);
  }
  return true;
}

}  // namespace volpar
