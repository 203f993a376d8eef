// Materials given by modulus: springs calibrated from Young's modulus and Poisson's ratio make a deformable
// body respond as the solid it stands for: a slender cantilever bends under its own weight as Euler-Bernoulli
// says (the static equilibrium of its springs, solved directly), and a bar carries waves at sqrt(E / rho)
// (the simulation itself).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/SparseCholesky>

#include "volpar/engine/builders/elastic_calibration.hpp"
#include "tests/support/test_support.hpp"

namespace volpar {
namespace {

constexpr double kModulus = 2.0e6;  // [Pa]
constexpr double kDensity = 1000.0;
constexpr double kSpacing = 0.02;   // particle radius 0.01 m

/// The box a lattice of `rows` x `layers` sites across fills [m]: width along y, height along z.
std::pair<double, double> section(Lattice lattice, int rows, int layers) {
  if (lattice == Lattice::Cubic) return {rows * kSpacing, layers * kSpacing};
  return {rows * std::sqrt(3.0) / 2.0 * kSpacing, layers * std::sqrt(2.0 / 3.0) * kSpacing};
}

constexpr const char* kStatic = "dt: 0.0005\nsteps: 1\ngravity: [0, 0, -9.81]\nsolver: {substeps: 10}\n";

/// A box beam along x of a soft solid, as long as `length` sites and as wide as `rows` x `layers` sites.
World beam(Lattice lattice, int length, int rows, int layers, double poisson, const std::string& head = kStatic) {
  const auto [ly, lz] = section(lattice, rows, layers);
  const double lx = length * kSpacing;
  const std::string box = "[" + test::exactNumber(lx) + ", " + test::exactNumber(ly * 1.0000001) + ", " +
                          test::exactNumber(lz * 1.0000001) + "]";
  return test::worldFromString(
      head + "materials:\n  rubber: {density: 1000, youngs_modulus: " + test::exactNumber(kModulus) +
      ", poisson_ratio: " + test::exactNumber(poisson) + "}\n"
      "bodies:\n  - name: beam\n    kind: deformable\n    material: rubber\n    connectors: {springs: {}}\n"
      "    shape: {box: {size: " + box + "}}\n"
      "    fill: {lattice: " + std::string(lattice == Lattice::Cubic ? "cubic" : "hcp") + ", radius: 0.01}\n");
}

/// Static tip deflection of the cantilever (its first layer held) under its own weight, from the springs'
/// stiffness matrix at rest, over Euler-Bernoulli's w L^4 / (8 E I).
double cantileverRatio(Lattice lattice, int length, int rows, int layers, double poisson) {
  World w = beam(lattice, length, rows, layers, poisson);
  const ParticleStore& p = w.particles();
  // the particles stand for the box's volume, each its share (more than a lattice cell where the lattice does
  // not reach the box's faces): the solid they make is their cells' at the modulus times that share
  const auto [ly, lz] = section(lattice, rows, layers);
  const double share = length * kSpacing * ly * lz / static_cast<double>(p.size()) / latticeCellVolume(lattice, kSpacing);
  const ConnectorStore& c = w.connectors();
  const std::size_t n = p.size();
  double xmin = 1e9, xmax = -1e9;
  for (std::size_t i = 0; i < n; ++i) {
    xmin = std::min(xmin, p.position[i].x());
    xmax = std::max(xmax, p.position[i].x());
  }
  std::vector<int> dof(n, -1);
  int free = 0;
  // held: the first particle of every row (HCP rows start half a spacing apart)
  double clamp = 0.0;
  int held = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (p.position[i].x() > xmin + 0.6 * kSpacing) {
      dof[i] = free++;
    } else {
      clamp += p.position[i].x();
      ++held;
    }
  }
  clamp /= held;
  std::vector<Eigen::Triplet<double>> t;
  for (std::size_t k = 0; k < c.size(); ++k) {
    const std::size_t a = c.a[k].index(), b = c.b[k].index();
    const Vec3 e = (p.position[b] - p.position[a]).normalized();
    const Mat3 m = c.stiffness[k] * e * e.transpose();
    const std::size_t ends[2] = {a, b};
    for (int i = 0; i < 2; ++i)
      for (int j = 0; j < 2; ++j) {
        if (dof[ends[i]] < 0 || dof[ends[j]] < 0) continue;
        for (int r = 0; r < 3; ++r)
          for (int q = 0; q < 3; ++q) t.emplace_back(3 * dof[ends[i]] + r, 3 * dof[ends[j]] + q, (i == j ? 1.0 : -1.0) * m(r, q));
      }
  }
  Eigen::SparseMatrix<double> k(3 * free, 3 * free);
  k.setFromTriplets(t.begin(), t.end());
  Eigen::VectorXd f = Eigen::VectorXd::Zero(3 * free);
  double load = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    if (dof[i] >= 0) {
      f[3 * dof[i] + 2] = -p.mass[i] * 9.81;
      load += p.mass[i] * 9.81;
    }
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(k);
  EXPECT_EQ(ldlt.info(), Eigen::Success);
  const Eigen::VectorXd u = ldlt.solve(f);
  // the free end: the last particle of every row
  double tip = 0.0, end = 0.0;
  int tips = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (p.position[i].x() > xmax - 0.6 * kSpacing) {
      tip += -u[3 * dof[i] + 2];
      end += p.position[i].x();
      ++tips;
    }
  tip /= tips;
  end /= tips;
  // the beam from the held layer's centre to the free end's face, loaded by the weight of what is free; its
  // section's second moment that of the volume its particles stand for (each a cell of the lattice's volume
  // and layer height, about the section's centre), per length
  const double cell = latticeCellVolume(lattice, kSpacing);
  const double layer = (lattice == Lattice::Cubic ? 1.0 : std::sqrt(2.0 / 3.0)) * kSpacing;
  double centre = 0.0;
  for (std::size_t i = 0; i < n; ++i) centre += p.position[i].z() / static_cast<double>(n);
  double inertia = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    inertia += cell * (std::pow(p.position[i].z() - centre, 2) + layer * layer / 12.0) / (length * kSpacing);
  // from the held particles' centres to the free end's face
  const double span = end + 0.5 * kSpacing - clamp;
  const double perLength = load / (span - 0.5 * kSpacing);
  return tip / (perLength * std::pow(span, 4) / (8.0 * kModulus * share * inertia));
}

TEST(ElasticCalibration, BulkLatticeHasTheModulusAndPoissonRatioAskedFor) {
  for (const Lattice lattice : {Lattice::Cubic, Lattice::Hcp}) {
    const SpringCalibration s = calibrateSprings(lattice, kSpacing, 1.5, kModulus, 0.25);
    EXPECT_NEAR(s.poissonRatio, 0.25, 1e-6);
    EXPECT_GT(s.nearest, 0.0);
    EXPECT_GT(s.farther, 0.0);
  }
  // cubic with face diagonals: nu = k2 / (k1 + 3 k2), E = (k1 + 2 k2 - k2) (k1 + 4 k2) / ((k1 + 3 k2) s)
  const SpringCalibration c = calibrateSprings(Lattice::Cubic, kSpacing, 1.5, kModulus, 0.2);
  const double k1 = c.nearest, k2 = c.farther;
  EXPECT_NEAR(k2 / (k1 + 3.0 * k2), 0.2, 1e-9);
  EXPECT_NEAR((k1 + k2) * (k1 + 4.0 * k2) / ((k1 + 3.0 * k2) * kSpacing), kModulus, 1e-9 * kModulus);
  // beyond what central springs reach: the nearest reachable
  EXPECT_LT(calibrateSprings(Lattice::Cubic, kSpacing, 1.5, kModulus, 0.45).poissonRatio, 1.0 / 3.0);
}

TEST(ElasticCalibration, SlenderCantileverDeflectsAsEulerBernoulliUnderItsOwnWeight) {
  struct Case {
    const char* name;
    Lattice lattice;
    int rows, layers;
  };
  // (6 to 11 particles across; 4 across is 8.5 % softer than the solid)
  for (const Case& k : {Case{"cubic 6 x 6", Lattice::Cubic, 6, 6}, Case{"cubic 8 x 8", Lattice::Cubic, 8, 8},
                        Case{"hcp 7 x 8", Lattice::Hcp, 7, 8}, Case{"hcp 10 x 11", Lattice::Hcp, 10, 11}}) {
    const double ratio = cantileverRatio(k.lattice, 60, k.rows, k.layers, 0.25);
    std::printf("%s: tip deflection / Euler-Bernoulli %.4f\n", k.name, ratio);
    EXPECT_NEAR(ratio, 1.0, 0.05) << k.name;
  }
}

/// The speed [m/s] of the longitudinal waves of a free bar (40 sites long, `rows` x `layers` across) in the
/// simulation: it is started in its first mode (velocity v0 cos(pi x / L) along it), and c = 2 L f from the
/// frequency f of its length's oscillation.
double waveSpeed(Lattice lattice, int rows, int layers) {
  constexpr int kLength = 40;
  World w = beam(lattice, kLength, rows, layers, 0.25, "dt: 0.0002\nsteps: 1\ngravity: [0, 0, 0]\nsolver: {substeps: 10}\n");
  ParticleStore& p = w.editParticles();
  const std::size_t n = p.size();
  double xmin = 1e9, xmax = -1e9;
  for (std::size_t i = 0; i < n; ++i) {
    xmin = std::min(xmin, p.position[i].x());
    xmax = std::max(xmax, p.position[i].x());
  }
  const double length = kLength * kSpacing;
  for (std::size_t i = 0; i < n; ++i)
    p.velocity[i] = Vec3(0.01 * std::cos(std::numbers::pi * (p.position[i].x() - xmin + 0.5 * kSpacing) / length), 0.0, 0.0);
  auto stretch = [&]() {
    double first = 0.0, last = 0.0;
    int nf = 0, nl = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (p.position[i].x() < xmin + 0.6 * kSpacing) {
        first += p.position[i].x();
        ++nf;
      }
      if (p.position[i].x() > xmax - 0.6 * kSpacing) {
        last += p.position[i].x();
        ++nl;
      }
    }
    return last / nl - first / nf;
  };
  const double rest = stretch();
  std::vector<double> crossings;
  double before = 0.0;
  const double dt = w.settings().dt;
  for (int k = 1; k <= 600 && crossings.size() < 3; ++k) {
    EXPECT_EQ(w.step(), StepStatus::Ok);
    const double now = stretch() - rest;
    if (k > 1 && (before < 0.0) != (now < 0.0)) crossings.push_back(dt * (k - 1 + before / (before - now)));
    before = now;
  }
  EXPECT_EQ(crossings.size(), 3u);
  if (crossings.size() < 3) return 0.0;
  const double period = crossings[2] - crossings[0];
  return 2.0 * length / period;
}

TEST(ElasticCalibration, BarCarriesLongitudinalWavesAtTheBarSpeed) {
  const double c = std::sqrt(kModulus / kDensity);
  for (const Lattice lattice : {Lattice::Cubic, Lattice::Hcp}) {
    const double speed = waveSpeed(lattice, 4, 4);
    std::printf("%s bar: wave speed %.3f m/s, sqrt(E / rho) %.3f m/s (ratio %.4f)\n",
                lattice == Lattice::Cubic ? "cubic" : "hcp", speed, c, speed / c);
    EXPECT_NEAR(speed / c, 1.0, 0.05);
  }
}

}  // namespace
}  // namespace volpar
