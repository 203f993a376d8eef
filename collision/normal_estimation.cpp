#include "volpar/collision/normal_estimation.hpp"

#include "volpar/collision/rounded_core.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <complex>
#include <functional>
#include <limits>

namespace volpar {

namespace {

enum : std::uint8_t { kInterior, kVolume, kSheet, kRim, kLine, kPoint };

constexpr double kSurfaceOffset = 0.15;     // |m| / (count x mean distance) above which a particle is surface
constexpr double kFlatNeighbourhood = 0.05;  // smallest / middle principal variance of a sheet's neighbours
constexpr double kPlanarSurface = 0.1;       // smallest / middle principal variance of a face's surface particles
constexpr double kCompatible = 0.5;          // cos 60 degrees: missing vectors of one face
constexpr double kSameFace = 0.9396926;      // cos 20 degrees: normals of one face
constexpr double kTight = 0.9961947;         // cos 5 degrees: how far a face's normals may spread
constexpr int kCrackHops = 4;               // how far along a crack's own particles its plane is fitted
constexpr double kStaircase = 0.3;          // rms distance from a crack's plane, in spacings, of its steps
constexpr double kFacesOut = 0.3;            // a face around an edge particle faces its way

bool opened(const Neighbourhood& nb, std::uint32_t i) { return !nb.opened.empty() && nb.opened[i] != 0; }

constexpr double kCurved = 0.5;         // a quadric that halves a plane's squared residual: a curved surface
constexpr double kNoBend = 0.01;        // squared residual, in steps^2 per point, below which no bend is sought
constexpr double kOneWay = 0.3;         // a quadric whose lesser curvature is under this share of the greater
                                        // bends one way (a cylinder)
constexpr std::size_t kFacesPerParticle = 4;  // faces a particle may be found on (the three largest are kept)
constexpr double kFaceSlab = 0.6;       // a face's particles lie within this many spacings of its plane
constexpr double kFaceRms = 0.35;       // ... and within this many of it (root mean square)
constexpr double kFaceBend = 0.6;       // the most, in spacings, a quadric over a face may bend away from it
constexpr double kFacetTurn = 0.5;      // cos 60 degrees: past a face's edge the surface turns by more
constexpr double kFacetWidth = 2.0;     // a strip narrower than this (spacings, standard deviation) that the
                                        // surface beyond turns from by less is a facet of a curved surface
constexpr double kOutermost = 0.5;      // a face's plane is fitted again to the outer half of its steps
constexpr std::size_t kCurvedFewest = 12;  // particles a curved surface is fitted whole over at least
constexpr double kCoreRms = 0.35;       // spacings (root mean square) a curved surface lies within its core's
constexpr double kCoreTurn = 0.9063078; // cos 25 degrees: the most a core's normal turns a particle's own
constexpr double kCoreOff = 1.0;        // spacings a particle the core takes lies within its surface

/// w = c0 + c1 u + c2 v + c3 u^2 + c4 uv + c5 v^2 about `origin` in the frame (t1, t2, n), least squares.
struct QuadricFit {
  bool ok = false;
  Eigen::Matrix<double, 6, 1> c = Eigen::Matrix<double, 6, 1>::Zero();
  double residual = 0.0;  // sum of squared residuals
};
template <class Points>
QuadricFit fitQuadric(const Points& points, const Vec3& origin, const Vec3& n, const Vec3& t1, const Vec3& t2) {
  Eigen::Matrix<double, 6, 6> ata = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> atw = Eigen::Matrix<double, 6, 1>::Zero();
  double ww = 0.0;
  for (const Vec3& p : points) {
    const Vec3 d = p - origin;
    const double u = d.dot(t1), v = d.dot(t2), w = d.dot(n);
    Eigen::Matrix<double, 6, 1> row;
    row << 1.0, u, v, u * u, u * v, v * v;
    ata += row * row.transpose();
    atw += row * w;
    ww += w * w;
  }
  QuadricFit q;
  const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(ata);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-10)) return q;
  q.c = ldlt.solve(atw);
  q.ok = q.c.allFinite();
  q.residual = std::max(ww - q.c.dot(atw), 0.0);
  return q;
}

/// The gradient at the origin of the algebraic sphere (D = 3) or circle (D = 2)
/// s(x) = u0 + u . x + u4 |x|^2 = 0 that best fits `points` (coordinates about the origin, about a unit
/// apart), with Pratt's normalisation |u|^2 - 4 u0 u4 = 1 (a plane is the sphere of infinite radius): it
/// points from the centre through the origin on a convex side. Unlike a height field over a plane, a sphere
/// goes round a polygon of flat runs (a lattice's outline of a circle) to its circle.
template <int D>
bool prattGradient(std::span<const Eigen::Matrix<double, D, 1>> points, Eigen::Matrix<double, D, 1>& out) {
  constexpr int K = D + 2;
  using MatK = Eigen::Matrix<double, K, K>;
  using VecK = Eigen::Matrix<double, K, 1>;
  MatK m = MatK::Zero();
  for (const auto& d : points) {
    VecK z;
    z[0] = 1.0;
    z.template segment<D>(1) = d;
    z[D + 1] = d.squaredNorm();
    m += z * z.transpose();
  }
  MatK pratt = MatK::Zero();
  pratt(0, D + 1) = pratt(D + 1, 0) = -2.0;
  for (int k = 1; k <= D; ++k) pratt(k, k) = 1.0;
  const Eigen::LDLT<MatK> ldlt(m);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
  // m u = eta pratt u with the smallest eta >= 0: the largest eigenvalue 1 / eta of m^-1 pratt
  const MatK a = ldlt.solve(pratt);
  const Eigen::EigenSolver<MatK> eig(a, true);
  if (eig.info() != Eigen::Success) return false;
  int best = -1;
  double largest = 0.0;
  for (int k = 0; k < K; ++k) {
    const std::complex<double> l = eig.eigenvalues()[k];
    if (std::abs(l.imag()) <= 1e-9 * std::abs(l.real()) && l.real() > largest) {
      largest = l.real();
      best = k;
    }
  }
  if (best < 0) return false;
  out = eig.eigenvectors().col(best).real().template segment<D>(1);
  return out.allFinite() && out.norm() > 0.0;
}

/// The normal at x of a curved surface through `points`, from its quadric over the plane (t1, t2, n): a
/// sphere's where it bends both ways, a cylinder's (a circle across its axis, the quadric's straight
/// direction) where it bends one way.
bool roundNormal(std::span<const Vec3> points, const Vec3& x, double scale, const Vec3& n, const Vec3& t1,
                 const Vec3& t2, const Eigen::Matrix<double, 6, 1>& c, Vec3& normal) {
  Eigen::Matrix2d hess;
  hess << 2.0 * c[3], c[4], c[4], 2.0 * c[5];
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> k(hess);
  const Eigen::Vector2d kappa = k.eigenvalues();
  const int straight = std::abs(kappa[0]) <= std::abs(kappa[1]) ? 0 : 1;
  if (std::abs(kappa[straight]) < kOneWay * std::abs(kappa[1 - straight])) {
    const Eigen::Vector2d e = k.eigenvectors().col(straight);
    const Vec3 axis = (e[0] * t1 + e[1] * t2).normalized();
    const Vec3 b1 = n, b2 = axis.cross(n);
    std::array<Eigen::Vector2d, 256> across;
    std::size_t count = 0;
    for (const Vec3& p : points) {
      if (count == across.size()) break;
      const Vec3 d = (p - x) / scale;
      across[count++] = Eigen::Vector2d(d.dot(b1), d.dot(b2));
    }
    Eigen::Vector2d g;
    if (!prattGradient<2>(std::span<const Eigen::Vector2d>(across.data(), count), g)) return false;
    normal = (g[0] * b1 + g[1] * b2).normalized();
  } else {
    std::array<Vec3, 256> about;
    std::size_t count = 0;
    for (const Vec3& p : points) {
      if (count == about.size()) break;
      about[count++] = (p - x) / scale;
    }
    Vec3 g;
    if (!prattGradient<3>(std::span<const Vec3>(about.data(), count), g)) return false;
    normal = g.normalized();
  }
  if (normal.dot(n) < 0.0) normal = -normal;
  return true;
}

/// The positions of some particles, as a range of points.
struct Gathered {
  std::span<const Vec3> positions;
  std::span<const std::uint32_t> ids;
  struct It {
    const Gathered* g;
    std::size_t k;
    const Vec3& operator*() const { return g->positions[g->ids[k]]; }
    It& operator++() {
      ++k;
      return *this;
    }
    bool operator!=(const It& o) const { return k != o.k; }
  };
  [[nodiscard]] It begin() const { return {this, 0}; }
  [[nodiscard]] It end() const { return {this, ids.size()}; }
};

/// The best-fit plane of some points: their centroid and the principal axes of their spread about it
/// (`variances` ascending, each the sum of squared offsets along its axis; axes.col(0) is the normal).
struct PlaneFit {
  Vec3 centre = Vec3::Zero();
  Vec3 variances = Vec3::Zero();
  Mat3 axes = Mat3::Identity();
  std::size_t count = 0;
};
template <class Points>
PlaneFit fitPlane(const Points& points) {
  PlaneFit f;
  for (const Vec3& p : points) {
    f.centre += p;
    ++f.count;
  }
  if (f.count == 0) return f;
  f.centre /= static_cast<double>(f.count);
  Mat3 cov = Mat3::Zero();
  for (const Vec3& p : points) cov += (p - f.centre) * (p - f.centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov, Eigen::ComputeEigenvectors);
  f.variances = eig.eigenvalues();
  f.axes = eig.eigenvectors();
  return f;
}

/// The surface through `points` at x, oriented along `out`: their best-fit plane where they lie within a
/// lattice step of it (rms `step`) and a quadric height field over it does not take up their residual;
/// else a curved surface, whose normal at x is its best-fit sphere's or cylinder's (`roundNormal`), or the
/// quadric's slope where that fit fails. False where the points are too few to tell.
bool surfaceThrough(std::span<const Vec3> points, const Vec3& x, const Vec3& out, double step, Vec3& normal,
                    bool& planar) {
  if (points.size() < 6) return false;
  const PlaneFit plane = fitPlane(points);
  const Vec3& l = plane.variances;
  if (!(l[0] <= 0.5 * l[1])) return false;  // not spread over a surface
  Vec3 n0 = plane.axes.col(0);
  if (n0.dot(out) < 0.0) n0 = -n0;
  const double n = static_cast<double>(points.size());
  if (std::max(l[0], 0.0) <= kNoBend * step * step * n) {  // flat within a small part of a step: a plane
    normal = n0;
    planar = true;
    return true;
  }
  // a quadric height field over the plane about x
  const Vec3 t1 = n0.unitOrthogonal(), t2 = n0.cross(t1);
  const QuadricFit q = fitQuadric(points, x, n0, t1, t2);
  // the plane's and the quadric's squared residuals: a staircase is a plane the quadric hardly improves on,
  // a curved surface one whose bend it takes up
  const double planeSs = std::max(l[0], 0.0);
  const bool bends = q.ok && q.residual < kCurved * planeSs;
  if (planeSs <= step * step * n && !bends) {
    normal = n0;
    planar = true;
    return true;
  }
  if (!q.ok) return false;
  // curved: the sphere or cylinder through the points, whose normal the quadric's slope only approaches
  // where the lattice's steps flatten it
  if (Vec3 round; roundNormal(points, x, step / kStaircase, n0, t1, t2, q.c, round)) {
    normal = round;
    planar = false;
    return true;
  }
  const Vec3 g = n0 - q.c[1] * t1 - q.c[2] * t2;
  if (!g.allFinite() || !(g.norm() > 0.0)) return false;
  normal = g.normalized();
  planar = false;
  return true;
}

}  // namespace

void SurfaceEstimator::nextMark() {
  if (++markStamp_ != 0) return;
  std::fill(mark_.begin(), mark_.end(), 0u);
  std::fill(beyondMark_.begin(), beyondMark_.end(), 0u);
  markStamp_ = 1;
}

void SurfaceEstimator::grow(std::size_t n) {
  if (raw_.size() >= n) return;
  raw_.resize(n);
  fit_.resize(n);
  rawStamp_.resize(n, 0);
  fitStamp_.resize(n, 0);
  mark_.resize(n, 0);
}

const SurfaceEstimator::Raw& SurfaceEstimator::raw(const Neighbourhood& nb, std::uint32_t i) {
  Raw& r = raw_[i];
  if (rawStamp_[i] == stamp_) return r;
  rawStamp_[i] = stamp_;
  r = Raw{};
  const Vec3& x = nb.positions[i];
  Mat3 cov = Mat3::Zero();
  double dist = 0.0;
  int count = 0;
  for (std::uint32_t k = nb.start[i]; k < nb.start[i + 1]; ++k) {
    const Vec3 d = nb.positions[nb.neighbours[k].index()] - x;
    r.missing -= d;
    const double dn = d.norm();
    r.spacing = count == 0 ? dn : std::min(r.spacing, dn);
    dist += dn;
    cov += d * d.transpose();
    ++count;
  }
  if (count == 0) {
    r.kind = kPoint;
    return r;
  }
  r.meanDistance = dist / count;
  const bool offset = r.missing.norm() > kSurfaceOffset * dist;
  // the shape of the neighbourhood: principal variances of the neighbour offsets about the particle
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov, Eigen::ComputeEigenvectors);
  const Vec3 l = eig.eigenvalues();
  if (l[1] <= kFlatNeighbourhood * l[2]) {
    r.kind = kLine;
    r.axis = eig.eigenvectors().col(2);
    return r;
  }
  if (count >= 2 && l[0] <= kFlatNeighbourhood * l[1]) {
    // neighbours in a plane through the particle: a sheet; on its rim where they lie to one side
    r.axis = eig.eigenvectors().col(0);
    const Vec3 inPlane = r.missing - r.missing.dot(r.axis) * r.axis;
    r.kind = inPlane.norm() > kSurfaceOffset * dist ? kRim : kSheet;
    return r;
  }
  r.kind = count < 4 || offset || opened(nb, i) ? kVolume : kInterior;
  return r;
}

Mat3 SurfaceEstimator::neighbourAxes(const Neighbourhood& nb, std::uint32_t i) {
  Mat3 cov = Mat3::Zero();
  for (std::uint32_t k = nb.start[i]; k < nb.start[i + 1]; ++k) {
    const Vec3 d = nb.positions[nb.neighbours[k].index()] - nb.positions[i];
    cov += d * d.transpose();
  }
  return Eigen::SelfAdjointEigenSolver<Mat3>(cov, Eigen::ComputeEigenvectors).eigenvectors();
}

void SurfaceEstimator::ring(const Neighbourhood& nb, std::uint32_t i, int hops, bool crack, std::vector<std::uint32_t>& out,
                            bool surface) {
  out.clear();
  nextMark();
  mark_[i] = markStamp_;
  out.push_back(i);
  std::size_t begin = 0;
  for (int hop = 0; hop < hops; ++hop) {
    const std::size_t end = out.size();
    for (std::size_t k = begin; k < end; ++k) {
      const std::uint32_t q = out[k];
      for (std::uint32_t e = nb.start[q]; e < nb.start[q + 1]; ++e) {
        const std::uint32_t j = nb.neighbours[e].value;
        if (mark_[j] == markStamp_ || (crack && !opened(nb, j))) continue;
        if (surface && raw(nb, j).kind != kVolume) continue;
        mark_[j] = markStamp_;
        out.push_back(j);
      }
    }
    begin = end;
  }
}

const SurfaceEstimator::Fit& SurfaceEstimator::fit(const Neighbourhood& nb, std::uint32_t i) {
  Fit& f = fit_[i];
  if (fitStamp_[i] == stamp_) return f;
  fitStamp_[i] = stamp_;
  f = Fit{};
  const Raw& own = raw(nb, i);
  if (own.kind != kVolume) return f;
  // off a crack: the surface patch along the surface (`surfaceThrough`), or where it holds too few points to
  // tell, the plane of the surface particles of the two-hop neighbourhood on the same side as this one; on
  // a crack face, the particles that lost a connector, within four connectors along them (they are the
  // face, wherever it meets the body's older faces, whose particles it leaves out; a crack across the
  // lattice is a staircase, whose plane a wider patch averages better)
  Vec3 m = own.missing;
  points_.clear();
  Vec3 sum = Vec3::Zero();
  const double mn = m.norm();
  const bool crack = opened(nb, i);
  if (!crack) {
    // the surface particles along the surface within four hops that face its way: a plane where they lie
    // within a lattice step of one (a staircase across the lattice), a curved surface otherwise
    ring(nb, i, reach_, false, wideRing_, true);
    for (const std::uint32_t q : wideRing_) {
      const Raw& rq = raw(nb, q);
      const double qn = rq.missing.norm();
      if (q != i && mn > 0.0 && qn > 0.0 && rq.missing.dot(m) < kCompatible * mn * qn) continue;
      points_.push_back(nb.positions[q]);
      sum += rq.missing;
    }
    const Vec3 out = mn > 1e-12 * std::max(own.meanDistance, 1e-300) ? m : sum;
    Vec3 n;
    bool planar = false;
    if (surfaceThrough(points_, nb.positions[i], out, kStaircase * own.spacing, n, planar)) {
      f.normal = n;
      f.planar = planar;
      return f;
    }
    points_.clear();
    sum = Vec3::Zero();
  }
  ring(nb, i, crack ? kCrackHops : 2, crack, fitRing_);
  for (const std::uint32_t q : fitRing_) {
    const Raw& rq = raw(nb, q);
    if (rq.kind != kVolume) continue;
    if (crack) {
      if (!opened(nb, q) || (q != i && !(rq.missing.dot(m) > 0.0))) continue;
    } else {
      const double qn = rq.missing.norm();
      if (q != i && mn > 0.0 && qn > 0.0 && rq.missing.dot(m) < kCompatible * mn * qn) continue;
    }
    points_.push_back(nb.positions[q]);
    sum += rq.missing;
  }
  // a particle without its own direction, or on a crack (where the crack meets an older face, its own
  // missing vector leans towards that face; the crack's particles together point out of the crack)
  if (crack || mn <= 1e-12 * std::max(own.meanDistance, 1e-300)) m = sum;
  if (points_.size() < 3) {
    f.normal = m.norm() > 0.0 ? Vec3(m.normalized()) : Vec3::Zero();
    f.planar = false;
    return f;
  }
  const PlaneFit plane = fitPlane(points_);
  Vec3 n = plane.axes.col(0);
  if (n.dot(m) < 0.0) n = -n;
  f.normal = n;
  f.planar = plane.variances[0] <= kPlanarSurface * plane.variances[1];
  // a crack across the lattice is a staircase whose steps are at most a layer high: within a third of a
  // spacing of its plane (root mean square) it is that plane, however small the patch of it in reach
  const double stepHeight = kStaircase * own.meanDistance;
  if (crack && plane.variances[0] <= stepHeight * stepHeight * static_cast<double>(points_.size())) f.planar = true;
  return f;
}

void SurfaceEstimator::estimate(const Neighbourhood& nb, std::span<const ParticleId> targets,
                                std::vector<SurfaceEstimate>& out, std::span<const std::uint8_t> kinds, int reach) {
  grow(nb.positions.size());
  reach_ = reach;
  if (++stamp_ == 0) {  // wrapped: forget every memo
    std::fill(rawStamp_.begin(), rawStamp_.end(), 0u);
    std::fill(fitStamp_.begin(), fitStamp_.end(), 0u);
    stamp_ = 1;
  }
  out.assign(targets.size(), SurfaceEstimate{});
  for (std::size_t t = 0; t < targets.size(); ++t) {
    const std::uint32_t i = targets[t].value;
    SurfaceEstimate& e = out[t];
    Raw r = raw(nb, i);
    // a sheet or a chain stays one when it bends (its neighbours are then no longer in a plane or on a line)
    if (t < kinds.size() && r.kind != kPoint && (kinds[t] & (kParticleSheet | kParticleLine))) {
      const Mat3 axes = neighbourAxes(nb, i);
      if (kinds[t] & kParticleLine) {
        r.kind = kLine;
        r.axis = axes.col(2);
      } else {
        r.axis = axes.col(0);
        r.kind = (kinds[t] & kParticleEdge) ? kRim : kSheet;
      }
    }
    switch (r.kind) {
      case kInterior: continue;
      case kPoint: e.flags = kParticleSurface; continue;
      case kLine:
        e.flags = kParticleSurface | kParticleLine;
        e.normal = r.axis;
        continue;
      case kSheet:
      case kRim: {
        e.flags = kParticleSurface | kParticleSheet;
        Vec3 n = r.axis;
        e.faces = {n, Vec3(-n), Vec3::Zero()};
        e.faceCount = 2;
        e.normal = n;
        if (r.kind == kRim) {
          const Vec3 inPlane = (r.missing - r.missing.dot(n) * n).normalized();
          e.flags |= kParticleEdge;
          e.faces[2] = inPlane;
          e.faceCount = 3;
          e.normal = inPlane;
        }
        continue;
      }
      default: break;
    }
    e.flags = kParticleSurface;
    const Fit f = fit(nb, i);
    // a planar crack face: where it meets the body's older faces (their particles kept their connectors),
    // those faces join it, and the particle lies on an edge or a corner
    const bool crackFace = opened(nb, i) && f.planar;
    if (f.normal.isZero() || (f.planar && !crackFace)) {
      e.normal = f.normal;
      e.faces[0] = f.normal;
      e.faceCount = f.normal.isZero() ? 0 : 1;
      continue;
    }
    // not on a plane: an edge or a corner where the planar surface particles around it that face its way
    // make two or more tight clusters of normals (faces meeting at an angle), a curved surface otherwise
    const Vec3 own = f.normal;
    const Vec3 away = r.missing.norm() > 0.0 ? Vec3(r.missing.normalized()) : own;
    std::array<Vec3, 8> sums{};
    std::array<Vec3, 8> firsts{};
    std::array<int, 8> counts{};
    std::array<double, 8> spread{};
    std::size_t clusters = 0;
    if (crackFace) {  // the crack's own face comes first, whatever the others
      firsts[0] = own;
      sums[0] = own;
      counts[0] = std::numeric_limits<int>::max();
      spread[0] = 1.0;
      clusters = 1;
    }
    ring(nb, i, 2, false, ring_);
    for (const std::uint32_t q : ring_) {
      if (q == i || raw(nb, q).kind != kVolume || (crackFace && opened(nb, q))) continue;
      const Fit& fq = fit(nb, q);
      if (!fq.planar || !(fq.normal.dot(away) > kFacesOut)) continue;
      std::size_t c = 0;
      while (c < clusters && firsts[c].dot(fq.normal) < kSameFace) ++c;
      if (c == clusters) {
        if (clusters == sums.size()) continue;
        firsts[c] = fq.normal;
        sums[c] = Vec3::Zero();
        counts[c] = 0;
        spread[c] = 1.0;
        ++clusters;
      }
      if (crackFace && c == 0) continue;  // the crack's face, seen from an older face's particle
      sums[c] += fq.normal;
      spread[c] = std::min(spread[c], firsts[c].dot(fq.normal));
      ++counts[c];
    }
    // the tight clusters of two or more, largest first (ties: the first found)
    std::array<std::size_t, 8> order{};
    std::size_t tight = 0;
    for (std::size_t c = 0; c < clusters; ++c)
      if (counts[c] >= 2 && spread[c] >= kTight) order[tight++] = c;
    std::stable_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(tight),
                     [&](std::size_t x, std::size_t y) { return counts[x] > counts[y]; });
    const std::size_t faces = std::min<std::size_t>(tight, 3);
    if (faces < 2) {
      e.normal = own;
      e.faces[0] = own;
      e.faceCount = 1;
      continue;
    }
    Vec3 mean = Vec3::Zero();
    for (std::size_t k = 0; k < faces; ++k) {
      e.faces[k] = sums[order[k]].normalized();
      mean += e.faces[k];
    }
    e.faceCount = static_cast<std::uint8_t>(faces);
    e.flags |= faces == 2 ? kParticleEdge : kParticleCorner;
    e.normal = mean.normalized();
  }
}

bool SurfaceEstimator::growFace(const Neighbourhood& nb, std::uint32_t seed, Vec3& normal) {
  const double h = raw(nb, seed).spacing;
  const double tol = kFaceSlab * h;
  double offset = normal.dot(nb.positions[seed]);
  const auto candidate = [&](std::uint32_t q) { return raw(nb, q).kind == kVolume && !opened(nb, q); };
  for (int pass = 0; pass < 4; ++pass) {
    // the surface particles connected to the seed through others that lie within `tol` of the plane and
    // face its way
    members_.clear();
    nextMark();
    mark_[seed] = markStamp_;
    members_.push_back(seed);
    for (std::size_t k = 0; k < members_.size(); ++k)
      for (std::uint32_t e = nb.start[members_[k]]; e < nb.start[members_[k] + 1]; ++e) {
        const std::uint32_t j = nb.neighbours[e].value;
        if (mark_[j] == markStamp_) continue;
        mark_[j] = markStamp_;
        if (!candidate(j) || !(raw(nb, j).missing.dot(normal) > 0.0)) continue;
        if (std::abs(normal.dot(nb.positions[j]) - offset) > tol) continue;
        members_.push_back(j);
      }
    if (members_.size() < 6) return false;
    const PlaneFit plane = fitPlane(Gathered{nb.positions, members_});
    const Vec3& centre = plane.centre;
    Vec3 fitted = plane.axes.col(0);
    if (fitted.dot(normal) < 0.0) fitted = -fitted;
    const double count = static_cast<double>(members_.size());
    // a face: within a lattice step of its plane (rms), and no quadric over it bends away from the plane by
    // more than a step across it
    if (!(std::max(plane.variances[0], 0.0) <= kFaceRms * kFaceRms * h * h * count)) return false;
    const Vec3 t1 = fitted.unitOrthogonal(), t2 = fitted.cross(t1);
    const QuadricFit quadric = fitQuadric(Gathered{nb.positions, members_}, centre, fitted, t1, t2);
    if (quadric.ok) {
      double bend = 0.0;
      for (const std::uint32_t q : members_) {
        const Vec3 d = nb.positions[q] - centre;
        const double u = d.dot(t1), v = d.dot(t2);
        bend = std::max(bend, std::abs(quadric.c[3] * u * u + quadric.c[4] * u * v + quadric.c[5] * v * v));
      }
      if (bend > kFaceBend * h) return false;
    }
    // the surface particles two rings beyond the face: past a face's edge the surface turns away by the
    // edge's angle; past the lattice's flat patches on a sphere or along a cylinder's side, narrow strips
    // of a curved surface, it turns by much less
    beyond_.clear();
    const double middle = fitted.dot(centre);
    const auto visit = [&](std::uint32_t q) {
      for (std::uint32_t e = nb.start[q]; e < nb.start[q + 1]; ++e) {
        const std::uint32_t j = nb.neighbours[e].value;
        if (beyondMark_[j] == markStamp_ || !candidate(j) || !(raw(nb, j).missing.dot(fitted) > 0.0)) continue;
        if (!(std::abs(fitted.dot(nb.positions[j]) - middle) > tol)) continue;  // on the face's plane
        beyondMark_[j] = markStamp_;
        beyond_.push_back(j);
      }
    };
    for (const std::uint32_t q : members_) visit(q);
    for (std::size_t k = 0, end = beyond_.size(); k < end; ++k) visit(beyond_[k]);
    turns_.clear();
    for (const std::uint32_t j : beyond_)
      if (const Fit& fj = fit(nb, j); !fj.normal.isZero()) turns_.push_back(fj.normal.dot(fitted));
    if (!turns_.empty()) {
      // the quartile of the least turned (the largest cosines)
      const auto quartile = turns_.begin() + static_cast<std::ptrdiff_t>(turns_.size() / 4);
      std::nth_element(turns_.begin(), quartile, turns_.end(), std::greater<>());
      const double narrow = std::sqrt(std::max(plane.variances[1], 0.0) / count);
      if (*quartile > kFacetTurn && narrow <= kFacetWidth * h) return false;
    }
    const bool same = fitted.dot(normal) > 1.0 - 1e-12;
    normal = fitted;
    offset = normal.dot(centre);
    if (same) break;
  }
  // the plane again through the face's outermost particles: its steps lie below it by up to a layer, the
  // deeper ones in a pattern of the lattice that need not even out across a small face
  for (int pass = 0; pass < 2; ++pass) {
    double top = -std::numeric_limits<double>::infinity(), bottom = std::numeric_limits<double>::infinity();
    for (const std::uint32_t q : members_) {
      top = std::max(top, normal.dot(nb.positions[q]));
      bottom = std::min(bottom, normal.dot(nb.positions[q]));
    }
    const double cut = top - kOutermost * (top - bottom);
    beyond_.clear();  // (the outer half, in members' order)
    for (const std::uint32_t q : members_)
      if (normal.dot(nb.positions[q]) >= cut) beyond_.push_back(q);
    if (beyond_.size() < 6) break;
    const PlaneFit outer = fitPlane(Gathered{nb.positions, beyond_});
    Vec3 refit = outer.axes.col(0);
    if (refit.dot(normal) < 0.0) refit = -refit;
    if (!(refit.dot(normal) > kSameFace) || !(outer.variances[0] <= kPlanarSurface * outer.variances[1])) break;
    normal = refit;
  }
  return true;
}

void SurfaceEstimator::joinFaces(const Neighbourhood& nb, std::vector<SurfaceEstimate>& out) {
  const std::size_t n = nb.positions.size();
  if (out.size() != n) return;
  grow(n);
  beyondMark_.assign(n, 0);
  regionOf_.assign(n * kFacesPerParticle, 0);
  regionCount_.assign(n, 0);
  faceNormals_.clear();
  faceSizes_.clear();
  for (std::uint32_t seed = 0; seed < n; ++seed) {
    if (raw(nb, seed).kind != kVolume || opened(nb, seed) || regionCount_[seed] != 0) continue;
    const Fit& fs = fit(nb, seed);
    if (!fs.planar || fs.normal.isZero()) continue;
    Vec3 normal = fs.normal;
    if (!growFace(nb, seed, normal)) continue;
    const auto id = static_cast<std::uint32_t>(faceNormals_.size());
    faceNormals_.push_back(normal);
    faceSizes_.push_back(static_cast<std::uint32_t>(members_.size()));
    for (const std::uint32_t q : members_)
      if (regionCount_[q] < kFacesPerParticle) regionOf_[q * kFacesPerParticle + regionCount_[q]++] = id;
  }
  // a particle on one face takes its plane, on two an edge, on three or more a corner (the largest three)
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::size_t count = regionCount_[i];
    if (count == 0) continue;
    std::array<std::uint32_t, kFacesPerParticle> ids{};
    for (std::size_t k = 0; k < count; ++k) ids[k] = regionOf_[i * kFacesPerParticle + k];
    std::stable_sort(ids.begin(), ids.begin() + static_cast<std::ptrdiff_t>(count),
                     [&](std::uint32_t a, std::uint32_t b) { return faceSizes_[a] > faceSizes_[b]; });
    SurfaceEstimate& e = out[i];
    std::array<Vec3, 3> f{};
    std::size_t fc = 0;
    const auto add = [&](const Vec3& v) {
      for (std::size_t j = 0; j < fc; ++j)
        if (f[j].dot(v) > kSameFace) return;
      if (fc < f.size()) f[fc++] = v;
    };
    for (std::size_t k = 0; k < count; ++k) add(faceNormals_[ids[k]]);
    // where a face meets a curved surface (a cylinder's cap its side) the local estimate's other faces stay
    if (e.flags & kParticleSharp)
      for (std::size_t k = 0; k < e.faceCount; ++k) add(e.faces[k]);
    Vec3 mean = Vec3::Zero();
    for (std::size_t k = 0; k < fc; ++k) mean += f[k];
    e.flags = static_cast<std::uint8_t>(kParticleSurface | (fc == 2 ? kParticleEdge : 0) | (fc >= 3 ? kParticleCorner : 0));
    e.faces = f;
    e.faceCount = static_cast<std::uint8_t>(fc);
    e.normal = mean.normalized();
  }
  joinCurved(nb, out);
}

void SurfaceEstimator::joinCurved(const Neighbourhood& nb, std::vector<SurfaceEstimate>& out) {
  const std::size_t n = nb.positions.size();
  // a particle of a curved surface: on no flat face, on no edge or corner, its own fit not planar
  const auto curved = [&](std::uint32_t i) {
    const SurfaceEstimate& e = out[i];
    return raw(nb, i).kind == kVolume && !opened(nb, i) && regionCount_[i] == 0 && e.faceCount == 1 &&
           !(e.flags & kParticleSharp) && !fit(nb, i).planar && !e.normal.isZero();
  };
  nextMark();
  for (std::uint32_t seed = 0; seed < n; ++seed) {
    if (mark_[seed] == markStamp_ || !curved(seed)) continue;
    // the connected curved surface through the seed
    members_.clear();
    members_.push_back(seed);
    mark_[seed] = markStamp_;
    double spacing = 0.0;
    for (std::size_t k = 0; k < members_.size(); ++k) {
      spacing += raw(nb, members_[k]).spacing;
      for (std::uint32_t e = nb.start[members_[k]]; e < nb.start[members_[k] + 1]; ++e) {
        const std::uint32_t j = nb.neighbours[e].value;
        if (mark_[j] == markStamp_ || !curved(j)) continue;
        mark_[j] = markStamp_;
        members_.push_back(j);
      }
    }
    if (members_.size() < kCurvedFewest) continue;
    spacing /= static_cast<double>(members_.size());
    curvedPoints_.clear();
    curvedNormals_.clear();
    for (const std::uint32_t q : members_) {
      curvedPoints_.push_back(nb.positions[q]);
      curvedNormals_.push_back(out[q].normal);
    }
    const RoundedCore core = fitRoundedCore(curvedPoints_, curvedNormals_, kCoreRms * spacing);
    if (core.kind == RoundedCore::Kind::None) continue;
    // a hollow (a surface whose outside faces its core, as a bowl's inside does) takes the normals towards it
    double agree = 0.0;
    for (std::size_t k = 0; k < members_.size(); ++k) agree += core.normalAt(curvedPoints_[k]).dot(curvedNormals_[k]);
    const double sign = agree >= 0.0 ? 1.0 : -1.0;
    for (std::size_t k = 0; k < members_.size(); ++k) {
      const Vec3 nk = sign * core.normalAt(curvedPoints_[k]);
      // (a particle the core does not take: off its surface, or its own normal far from the core's)
      if (!(std::abs(core.distance(curvedPoints_[k])) <= kCoreOff * spacing) || !(nk.dot(curvedNormals_[k]) > kCoreTurn)) continue;
      SurfaceEstimate& e = out[members_[k]];
      e.normal = nk;
      e.faces[0] = nk;
    }
  }
}

std::vector<SurfaceEstimate> estimateSurface(std::span<const Vec3> positions,
                                             std::span<const std::array<std::uint32_t, 2>> connectors) {
  const std::size_t n = positions.size();
  std::vector<std::uint32_t> start(n + 1, 0);
  for (const auto& c : connectors) {
    ++start[c[0] + 1];
    ++start[c[1] + 1];
  }
  for (std::size_t i = 0; i < n; ++i) start[i + 1] += start[i];
  std::vector<ParticleId> items(start[n]);
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (const auto& c : connectors) {
    items[fill[c[0]]++] = ParticleId(c[1]);
    items[fill[c[1]]++] = ParticleId(c[0]);
  }
  std::vector<ParticleId> all(n);
  for (std::size_t i = 0; i < n; ++i) all[i] = ParticleId(i);
  SurfaceEstimator estimator;
  std::vector<SurfaceEstimate> out;
  estimator.estimate({positions, start, items, {}}, all, out);
  estimator.joinFaces({positions, start, items, {}}, out);
  return out;
}

}  // namespace volpar
