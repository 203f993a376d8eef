#include "volpar/collision/rounded_core.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace volpar {

namespace {

constexpr double kSideLean = 0.42;      // sin 25 degrees: a normal leaning less along the axis is the side's
constexpr std::size_t kFewest = 6;      // particles a sphere, circle or cap is fitted to at least
constexpr double kFirstTurn = 0.035;    // the axis search's first step [rad], about 2 degrees
constexpr double kLastTurn = 1e-4;      // ... and its last
constexpr int kMostMoves = 200;         // ... and the most steps it takes (each lowers the fit's rms)
constexpr double kCapSlack = 0.15;      // share of the tolerance a cap's radius may differ from the side's by
                                        // (a lattice outlines a sphere and a cylinder at slightly different depths)

/// A sphere or a circle fitted to points: its centre and radius, and the points' rms distance from it.
template <int D>
struct RoundFit {
  bool ok = false;
  Eigen::Matrix<double, D, 1> centre = Eigen::Matrix<double, D, 1>::Zero();
  double radius = 0.0, rms = 0.0;
};

/// The sphere (D = 3) or circle (D = 2) through the n points coords(i), algebraic least squares about their
/// mean m: |y|^2 = 2 c . y + k with y = p - m, centre m + c, radius sqrt(k + |c|^2).
template <int D, class Coords>
RoundFit<D> algebraicFit(std::size_t n, const Coords& coords) {
  using VecD = Eigen::Matrix<double, D, 1>;
  using VecK = Eigen::Matrix<double, D + 1, 1>;
  using MatK = Eigen::Matrix<double, D + 1, D + 1>;
  RoundFit<D> out;
  if (n < kFewest) return out;
  VecD mean = VecD::Zero();
  for (std::size_t i = 0; i < n; ++i) mean += coords(i);
  mean /= static_cast<double>(n);
  MatK a = MatK::Zero();
  VecK b = VecK::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const VecD y = coords(i) - mean;
    VecK row;
    row << 2.0 * y, 1.0;
    a += row * row.transpose();
    b += row * y.squaredNorm();
  }
  const Eigen::LDLT<MatK> ldlt(a);
  if (ldlt.info() != Eigen::Success) return out;
  const VecK s = ldlt.solve(b);
  const VecD c = s.template head<D>();
  const double r2 = s[D] + c.squaredNorm();
  if (!(r2 > 0.0) || !s.allFinite()) return out;
  out.centre = mean + c;
  out.radius = std::sqrt(r2);
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double e = (coords(i) - out.centre).norm() - out.radius;
    sum += e * e;
  }
  out.rms = std::sqrt(sum / static_cast<double>(n));
  out.ok = true;
  return out;
}

/// The sphere through the points.
RoundFit<3> fitSphere(std::span<const Vec3> points) {
  return algebraicFit<3>(points.size(), [&](std::size_t i) { return points[i]; });
}

/// The cylinder along `axis` through the points: the circle of their projections across it (its centre
/// the point of the axis in the plane through the origin across it).
RoundFit<3> fitCylinder(std::span<const Vec3> points, const Vec3& axis) {
  const Vec3 u = axis.unitOrthogonal(), v = axis.cross(u);
  const RoundFit<2> circle =
      algebraicFit<2>(points.size(), [&](std::size_t i) { return Eigen::Vector2d(points[i].dot(u), points[i].dot(v)); });
  return {circle.ok, circle.centre.x() * u + circle.centre.y() * v, circle.radius, circle.rms};
}

/// The axis near `axis` whose cylinder fits the points best (a pattern search over its tilt), and that fit.
RoundFit<3> searchAxis(std::span<const Vec3> points, Vec3& axis) {
  RoundFit<3> best = fitCylinder(points, axis);
  if (!best.ok) return best;
  int moves = 0;
  for (double step = kFirstTurn; step >= kLastTurn && moves < kMostMoves;) {
    const Vec3 u = axis.unitOrthogonal(), v = axis.cross(u);
    bool moved = false;
    for (const auto& [du, dv] : std::array<std::array<double, 2>, 8>{
             {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}}}) {
      const Vec3 tried = (axis + step * (du * u + dv * v)).normalized();
      const RoundFit<3> c = fitCylinder(points, tried);
      if (c.ok && c.rms < best.rms) {
        best = c;
        axis = tried;
        moved = true;
      }
    }
    if (moved) {
      ++moves;
    } else {
      step *= 0.5;
    }
  }
  return best;
}

/// A half-sphere about a point of the line (centre + t axis) whose radius is the side's within `slack`:
/// the t whose sphere the points lie nearest (a scan from `from` to `to`, then a golden-section search
/// about the best), and their root mean square distance from it.
double fitCap(std::span<const Vec3> points, const Vec3& centre, const Vec3& axis, double radius, double slack, double from,
              double to, double& t) {
  const double count = static_cast<double>(points.size());
  // (the sphere's own radius at each t: the points' mean distance, within `slack` of the side's)
  const auto own = [&](double at) {
    double sum = 0.0;
    for (const Vec3& x : points) sum += (x - centre - at * axis).norm();
    return std::clamp(sum / count, radius - slack, radius + slack);
  };
  const auto cost = [&](double at) {
    const double r = own(at);
    double sum = 0.0;
    for (const Vec3& x : points) {
      const double e = (x - centre - at * axis).norm() - r;
      sum += e * e;
    }
    return sum;
  };
  constexpr int kScan = 64;
  double best = std::numeric_limits<double>::infinity();
  const double step = (to - from) / kScan;
  for (int k = 0; k <= kScan; ++k)
    if (const double c = cost(from + k * step); c < best) {
      best = c;
      t = from + k * step;
    }
  double lo = t - step, hi = t + step;
  const double golden = 0.5 * (std::sqrt(5.0) - 1.0);
  for (int it = 0; it < 60; ++it) {
    const double x1 = hi - golden * (hi - lo), x2 = lo + golden * (hi - lo);
    if (cost(x1) < cost(x2)) {
      hi = x2;
    } else {
      lo = x1;
    }
  }
  t = 0.5 * (lo + hi);
  return std::sqrt(cost(t) / count);
}

}  // namespace

double RoundedCore::distance(const Vec3& x) const {
  const Vec3 y = x - centre;
  if (kind == Kind::Point) return y.norm() - radius;
  return (y - std::clamp(y.dot(axis), lo, hi) * axis).norm() - radius;
}

Vec3 RoundedCore::normalAt(const Vec3& x) const {
  const Vec3 y = x - centre;
  if (kind == Kind::Point) return y.normalized();
  const double t = std::clamp(y.dot(axis), lo, hi);
  return (y - t * axis).normalized();
}

RoundedCore fitRoundedCore(std::span<const Vec3> points, std::span<const Vec3> normals, double tolerance) {
  RoundedCore out;
  if (points.size() < 2 * kFewest || normals.size() != points.size()) return out;
  // a sphere about one point
  const RoundFit<3> sphere = fitSphere(points);
  if (sphere.ok && sphere.rms <= tolerance) {
    out.kind = RoundedCore::Kind::Point;
    out.centre = sphere.centre;
    out.radius = sphere.radius;
    out.rms = sphere.rms;
  }
  // a cylinder's side, along the direction the normals spread least in (a fan across it), the particles
  // whose normals lean little along it; each end's remaining particles a half-sphere about the axis
  Mat3 spread = Mat3::Zero();
  for (const Vec3& n : normals) spread += n * n.transpose();
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(spread, Eigen::ComputeEigenvectors);
  Vec3 axis = eig.eigenvectors().col(0);
  std::vector<Vec3> side, rest;
  const auto split = [&] {
    side.clear();
    rest.clear();
    for (std::size_t i = 0; i < points.size(); ++i) (std::abs(normals[i].dot(axis)) < kSideLean ? side : rest).push_back(points[i]);
  };
  split();
  RoundFit<3> cylinder = searchAxis(side, axis);
  if (cylinder.ok) {
    split();  // (the side again about the fitted axis)
    cylinder = searchAxis(side, axis);
  }
  if (!cylinder.ok) return out;
  RoundedCore line;
  line.kind = RoundedCore::Kind::Line;
  line.centre = cylinder.centre;
  line.axis = axis;
  double sideLo = std::numeric_limits<double>::infinity(), sideHi = -sideLo;
  for (const Vec3& x : side) {
    sideLo = std::min(sideLo, (x - line.centre).dot(axis));
    sideHi = std::max(sideHi, (x - line.centre).dot(axis));
  }
  std::vector<Vec3> below, above;
  for (const Vec3& x : rest) ((x - line.centre).dot(axis) < 0.5 * (sideLo + sideHi) ? below : above).push_back(x);
  // each end's remaining particles: a half-sphere of the side's radius about a point of the axis, where
  // they lie within the tolerance of one (a sphere's band between its caps has both about its centre: a
  // segment of no length); where they do not (a flat end the faces left out), they are no part of the core
  const double span = sideHi - sideLo + 2.0 * cylinder.radius;
  double t = 0.0;
  if (below.size() >= kFewest &&
      fitCap(below, line.centre, axis, cylinder.radius, kCapSlack * tolerance, sideLo - cylinder.radius, sideLo + span, t) <= tolerance)
    line.lo = t;
  if (above.size() >= kFewest &&
      fitCap(above, line.centre, axis, cylinder.radius, kCapSlack * tolerance, sideHi - span, sideHi + cylinder.radius, t) <= tolerance)
    line.hi = t;
  if (line.lo > line.hi + tolerance) return out;
  if (line.lo > line.hi) line.lo = line.hi = 0.5 * (line.lo + line.hi);
  if (std::isfinite(line.lo) || std::isfinite(line.hi)) line.kind = RoundedCore::Kind::Segment;
  line.radius = cylinder.radius;
  // the fit over the particles it takes: the side, and each end that is a half-sphere
  double sum = 0.0;
  std::size_t taken = 0;
  const auto take = [&](std::span<const Vec3> part) {
    for (const Vec3& x : part) {
      const double e = line.distance(x);
      sum += e * e;
      ++taken;
    }
  };
  take(side);
  if (std::isfinite(line.lo)) take(below);
  if (std::isfinite(line.hi)) take(above);
  line.rms = std::sqrt(sum / static_cast<double>(taken));
  if (2 * taken < points.size()) return out;
  if (line.rms <= tolerance && (out.kind == RoundedCore::Kind::None || line.rms < out.rms)) out = line;
  return out;
}

}  // namespace volpar
