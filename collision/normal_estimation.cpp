#include "collision/normal_estimation.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
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

}  // namespace

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
    dist += d.norm();
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

void SurfaceEstimator::ring(const Neighbourhood& nb, std::uint32_t i, int hops, bool crack, std::vector<std::uint32_t>& out) {
  out.clear();
  if (++markStamp_ == 0) {
    std::fill(mark_.begin(), mark_.end(), 0u);
    markStamp_ = 1;
  }
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
  // the surface particles of the two-hop neighbourhood on the same side as this one; on a crack face, the
  // particles that lost a connector, within four connectors along them (they are the face, wherever it
  // meets the body's older faces, whose particles it leaves out; a crack across the lattice is a staircase,
  // whose plane a wider patch averages better)
  Vec3 m = own.missing;
  points_.clear();
  Vec3 sum = Vec3::Zero();
  const double mn = m.norm();
  const bool crack = opened(nb, i);
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
  Vec3 centre = Vec3::Zero();
  for (const Vec3& x : points_) centre += x;
  centre /= static_cast<double>(points_.size());
  Mat3 cov = Mat3::Zero();
  for (const Vec3& x : points_) cov += (x - centre) * (x - centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(cov, Eigen::ComputeEigenvectors);
  Vec3 n = eig.eigenvectors().col(0);
  if (n.dot(m) < 0.0) n = -n;
  f.normal = n;
  f.planar = eig.eigenvalues()[0] <= kPlanarSurface * eig.eigenvalues()[1];
  // a crack across the lattice is a staircase whose steps are at most a layer high: within a third of a
  // spacing of its plane (root mean square) it is that plane, however small the patch of it in reach
  const double stepHeight = kStaircase * own.meanDistance;
  if (crack && eig.eigenvalues()[0] <= stepHeight * stepHeight * static_cast<double>(points_.size())) f.planar = true;
  return f;
}

void SurfaceEstimator::estimate(const Neighbourhood& nb, std::span<const ParticleId> targets,
                                std::vector<SurfaceEstimate>& out, std::span<const std::uint8_t> kinds) {
  grow(nb.positions.size());
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
  return out;
}

}  // namespace volpar
