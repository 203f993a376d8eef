#include "volpar/engine/builders/elastic_calibration.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

namespace volpar {

namespace {

using Voigt = Eigen::Matrix<double, 6, 6>;

/// A bulk particle's neighbours within reach x spacing (vectors to them) [m].
std::vector<Vec3> bulkNeighbours(Lattice lattice, double spacing, double reach) {
  std::vector<Vec3> out;
  const Vec3 origin = latticeSite(lattice, spacing, {0, 0, 0});
  const long n = static_cast<long>(std::ceil(reach)) + 2;
  for (long i = -n; i <= n; ++i)
    for (long j = -n; j <= n; ++j)
      for (long k = -n; k <= n; ++k) {
        const Vec3 d = latticeSite(lattice, spacing, {i, j, k}) - origin;
        const double l = d.norm();
        if (l > 1e-9 * spacing && l < reach * spacing) out.push_back(d);
      }
  return out;
}

bool nearestShell(const Vec3& d, double spacing) { return d.norm() < (1.0 + 1e-6) * spacing; }

/// The elastic constants (Voigt notation) of the bulk lattice with stiffness `near` and `far`.
Voigt elasticConstants(std::span<const Vec3> neighbours, double spacing, double volume, double near, double far) {
  static constexpr std::array<std::array<int, 2>, 6> kPairs{{{0, 0}, {1, 1}, {2, 2}, {1, 2}, {0, 2}, {0, 1}}};
  Voigt c = Voigt::Zero();
  for (const Vec3& d : neighbours) {
    const double l = d.norm();
    const Vec3 e = d / l;
    const double k = nearestShell(d, spacing) ? near : far;
    for (int a = 0; a < 6; ++a)
      for (int b = 0; b < 6; ++b)
        c(a, b) += 0.5 * k * l * l * e[kPairs[a][0]] * e[kPairs[a][1]] * e[kPairs[b][0]] * e[kPairs[b][1]] / volume;
  }
  return c;
}

/// Young's modulus along x and Poisson's ratio (x stretched, y contracting) of constants c.
std::pair<double, double> axialModuli(const Voigt& c) {
  const Eigen::FullPivLU<Voigt> lu(c);
  if (!lu.isInvertible()) return {0.0, 0.0};
  const Voigt s = lu.inverse();
  return {1.0 / s(0, 0), -s(0, 1) / s(0, 0)};
}

}  // namespace

SpringCalibration calibrateSprings(Lattice lattice, double spacing, double reach, double modulus, double poisson) {
  const std::vector<Vec3> neighbours = bulkNeighbours(lattice, spacing, reach);
  const double volume = latticeCellVolume(lattice, spacing);
  const bool twoShells = std::any_of(neighbours.begin(), neighbours.end(), [&](const Vec3& d) { return !nearestShell(d, spacing); });
  // the ratio far / near for the Poisson's ratio: bisection over the ratios that leave the lattice stable
  auto ratioOf = [&](double ratio) { return axialModuli(elasticConstants(neighbours, spacing, volume, 1.0, ratio)); };
  double ratio = 1.0;
  if (twoShells) {
    double lo = 1e-3, hi = 1e3;
    const double nuLo = ratioOf(lo).second, nuHi = ratioOf(hi).second;
    const bool rising = nuHi > nuLo;
    if (poisson <= std::min(nuLo, nuHi)) ratio = rising ? lo : hi;
    else if (poisson >= std::max(nuLo, nuHi)) ratio = rising ? hi : lo;
    else {
      for (int it = 0; it < 200; ++it) {
        const double mid = std::sqrt(lo * hi);
        const bool above = ratioOf(mid).second > poisson;
        if (above == rising) hi = mid;
        else lo = mid;
      }
      ratio = std::sqrt(lo * hi);
    }
  }
  const auto [unitModulus, nu] = ratioOf(ratio);
  SpringCalibration out;
  out.nearest = unitModulus > 0.0 ? modulus / unitModulus : 0.0;
  out.farther = out.nearest * ratio;
  out.poissonRatio = nu;
  out.youngsModulus = modulus;
  return out;
}

std::vector<double> calibratedStiffness(const ParticleCloud& cloud, const SpringCalibration& springs, Lattice lattice,
                                        double spacing, double reach) {
  // each particle's energy under a unit uniaxial stress along each axis (stretch 1 along it, -nu across):
  // sum over its springs of k (e . eps e)^2 L^2
  const double nu = springs.poissonRatio;
  auto energy = [&](const Vec3& d, double k) {
    const double l2 = d.squaredNorm();
    const Vec3 e2 = d.cwiseProduct(d) / l2;
    Vec3 w;
    for (int a = 0; a < 3; ++a) {
      const double stretch = e2[a] - nu * (1.0 - e2[a]);
      w[a] = k * stretch * stretch * l2;
    }
    return w;
  };
  auto stiffness = [&](const Vec3& d) { return nearestShell(d, spacing) ? springs.nearest : springs.farther; };
  Vec3 bulk = Vec3::Zero();
  for (const Vec3& d : bulkNeighbours(lattice, spacing, reach)) bulk += energy(d, stiffness(d));
  std::vector<Vec3> own(cloud.size(), Vec3::Zero());
  for (const auto& [a, b] : cloud.connectors) {
    const Vec3 d = cloud.positions[b] - cloud.positions[a];
    const Vec3 w = energy(d, stiffness(d));
    own[a] += w;
    own[b] += w;
  }
  const double cell = latticeCellVolume(lattice, spacing);
  std::vector<double> out;
  out.reserve(cloud.connectors.size());
  for (const auto& [a, b] : cloud.connectors) {
    const Vec3 d = cloud.positions[b] - cloud.positions[a];
    const Vec3 e = d.normalized();
    // the two particles' factors per axis, and the spring's over its direction (an ellipsoid through them)
    Vec3 g;
    for (int k = 0; k < 3; ++k)
      g[k] = 0.5 * (bulk[k] / std::max(own[a][k], 1e-300 * bulk[k]) + bulk[k] / std::max(own[b][k], 1e-300 * bulk[k]));
    const double scale = 1.0 / e.cwiseQuotient(g).norm();
    // a particle that stands for more volume than a lattice cell (a shape the lattice does not fill to its
    // faces) is stiffer in proportion, so that the particles carry the whole solid's load at its modulus (and
    // waves run at sqrt(E / rho) with its mass)
    const double share = cloud.volumes.empty() ? 1.0 : 0.5 * (cloud.volumes[a] + cloud.volumes[b]) / cell;
    out.push_back(stiffness(d) * scale * share);
  }
  return out;
}

}  // namespace volpar
