// The iterative solve of a bonded body's frame (BondLoads: multigrid-preconditioned conjugate gradients,
// warm started) against a direct solve of the same frame assembled here from the textbook stiffness of a
// three-dimensional Euler-Bernoulli beam element (local axes, then rotated), on random self-equilibrated load
// cases of bodies from 100 to 20 000 particles.
//
// Stated tolerance: every displacement and rotation within 1e-3 of the largest (per kind), and every bond's
// axial force within 1e-3 of the largest axial force, in at most 12 iterations from rest whatever the size;
// after bonds are removed and the frame is solved around them only (BondLoads::solveAround), within 1e-2.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <Eigen/SparseCholesky>

#include "tests/support/test_support.hpp"
#include "volpar/dynamics/bond_loads.hpp"

namespace volpar {
namespace {

constexpr double kAgreement = 1e-3;
constexpr double kPassAgreement = 1e-2;  // a pass solved around its breaks (BondLoads::solveAround)
constexpr int kIterations = 12;  // at most, from rest, for any size

/// The 12 x 12 stiffness of a beam from a to b (unit direction e, length L) in the world axes, from the
/// local element matrix (x along the beam; bending about local y and z alike: a circular section).
Eigen::Matrix<double, 12, 12> textbookBeam(const Vec3& e, double L, double ea, double gj, double ei) {
  Eigen::Matrix<double, 12, 12> k = Eigen::Matrix<double, 12, 12>::Zero();
  const double a = ea / L, t = gj / L, b12 = 12.0 * ei / (L * L * L), b6 = 6.0 * ei / (L * L), b4 = 4.0 * ei / L, b2 = 2.0 * ei / L;
  // freedoms: u_a (0-2), theta_a (3-5), u_b (6-8), theta_b (9-11)
  k(0, 0) = k(6, 6) = a;
  k(0, 6) = k(6, 0) = -a;
  k(3, 3) = k(9, 9) = t;
  k(3, 9) = k(9, 3) = -t;
  // bending in the x-y plane (v = u_y, theta_z)
  const int v[4] = {1, 5, 7, 11};
  const double kv[4][4] = {{b12, b6, -b12, b6}, {b6, b4, -b6, b2}, {-b12, -b6, b12, -b6}, {b6, b2, -b6, b4}};
  // bending in the x-z plane (w = u_z, theta_y): the rotation's sign flips
  const int w[4] = {2, 4, 8, 10};
  const double kw[4][4] = {{b12, -b6, -b12, -b6}, {-b6, b4, b6, b2}, {-b12, b6, b12, b6}, {-b6, b2, b6, b4}};
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j) {
      k(v[i], v[j]) += kv[i][j];
      k(w[i], w[j]) += kw[i][j];
    }
  // local axes: x = e, y and z any two unit vectors across it
  const Vec3 helper = std::abs(e.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  const Vec3 y = e.cross(helper).normalized(), z = e.cross(y);
  Mat3 r;
  r.row(0) = e.transpose();
  r.row(1) = y.transpose();
  r.row(2) = z.transpose();
  Eigen::Matrix<double, 12, 12> t12 = Eigen::Matrix<double, 12, 12>::Zero();
  for (int i = 0; i < 4; ++i) t12.block<3, 3>(3 * i, 3 * i) = r;
  return t12.transpose() * k * t12;
}

struct Case {
  std::string size;  // the box's sizes [m]
  double radius;
};

void checkAgainstDirectSolve(const Case& c, std::uint32_t seed, bool breaks = false) {
  World w = test::worldFromString("dt: 0.004\nsteps: 1\nmaterials:\n  rock: {youngs_modulus: 1.0e9, poisson_ratio: 0.25}\n"
                                  "bodies:\n  - name: block\n    shape: {box: {size: " + c.size + "}}\n"
                                  "    fill: {radius: " + std::to_string(c.radius) + "}\n    connectors: bonds\n    material: rock\n");
  const BodyInfo& info = w.bodies().info[0];
  BodyState state = w.bodies().state[0];
  state.orientation = Quat::Identity();  // the body frame is the world's: the loads go in as they are
  state.linearVelocity.setZero();
  state.angularVelocity.setZero();
  const std::span<const ConnectorId> ids = w.bodyConnectors(BodyId(0u));
  const std::vector<ConnectorId> bonds(ids.begin(), ids.end());
  const ParticleStore& p = w.particles();
  const ConnectorStore& con = w.connectors();
  const std::size_t n = info.particles.size();
  double maxMove = 0.0, maxTurn = 0.0;
  std::vector<std::size_t> localOf(p.size(), 0);
  for (std::size_t i = 0; i < n; ++i) localOf[info.particles[i].index()] = i;

  // loads: equal and opposite forces along the lines between random pairs of particles (self-equilibrated)
  std::mt19937 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  std::normal_distribution<double> size(0.0, 100.0);
  std::vector<Vec3> loads(p.size(), Vec3::Zero());
  for (std::size_t k = 0; k < std::max<std::size_t>(4, n / 20); ++k) {
    const std::size_t i = info.particles[pick(rng)].index(), j = info.particles[pick(rng)].index();
    if (i == j) continue;
    const Vec3 f = size(rng) * (p.local[j] - p.local[i]).normalized();
    loads[i] += f;
    loads[j] -= f;
  }

  // the direct solve of the frame without the bonds `removed` (entries of bonds)
  const auto directSolve = [&](const std::vector<std::uint8_t>& removed) {
    std::vector<Eigen::Triplet<double>> t;
    Eigen::VectorXd diag = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(6 * n));
    for (std::size_t r = 0; r < bonds.size(); ++r) {
      if (removed[r]) continue;
      const std::size_t k = bonds[r].index(), a = localOf[con.a[k].index()], b = localOf[con.b[k].index()];
      const Vec3 d = p.local[con.b[k].index()] - p.local[con.a[k].index()];
      const double r0 = con.bondRadius[k], e = con.youngsModulus[k], g = e / (2.0 * (1.0 + con.poissonRatio[k]));
      const double area = std::numbers::pi * r0 * r0, inertia = 0.25 * area * r0 * r0;
      const Eigen::Matrix<double, 12, 12> ke = textbookBeam(d.normalized(), d.norm(), e * area, g * 2.0 * inertia, e * inertia);
      const std::size_t node[2] = {a, b};
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j) {
          const auto row = static_cast<int>(6 * node[i / 6] + static_cast<std::size_t>(i % 6));
          const auto col = static_cast<int>(6 * node[j / 6] + static_cast<std::size_t>(j % 6));
          t.emplace_back(row, col, ke(i, j));
          if (row == col) diag[row] += ke(i, j);
        }
    }
    // the model's regularisation of the rigid modes (bond_loads.cpp), from the frame as it was built
    if (maxMove == 0.0)
      for (std::size_t i = 0; i < n; ++i)
        for (int k = 0; k < 3; ++k) {
          maxMove = std::max(maxMove, diag[static_cast<Eigen::Index>(6 * i) + k]);
          maxTurn = std::max(maxTurn, diag[static_cast<Eigen::Index>(6 * i) + 3 + k]);
        }
    for (std::size_t i = 0; i < n; ++i)
      for (int k = 0; k < 6; ++k) t.emplace_back(static_cast<int>(6 * i) + k, static_cast<int>(6 * i) + k, 1e-9 * (k < 3 ? maxMove : maxTurn));
    Eigen::SparseMatrix<double> stiffness(static_cast<Eigen::Index>(6 * n), static_cast<Eigen::Index>(6 * n));
    stiffness.setFromTriplets(t.begin(), t.end());
    Eigen::VectorXd f = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(6 * n));
    for (std::size_t i = 0; i < n; ++i) f.segment<3>(static_cast<Eigen::Index>(6 * i)) = loads[info.particles[i].index()];
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> direct(stiffness);
    EXPECT_EQ(direct.info(), Eigen::Success);
    return Eigen::VectorXd(direct.solve(f));
  };
  // the frame's displacements, rotations and axial forces against `reference`'s, within kAgreement of the largest
  const auto agree = [&](const BondLoads& frame, const std::vector<BondLoad>& out, const Eigen::VectorXd& reference,
                         const std::vector<std::uint8_t>& removed, const char* what, double agreement) {
    const std::span<const double> u = frame.displacements();
    ASSERT_EQ(u.size(), static_cast<std::size_t>(reference.size()));
    double largest[2] = {0.0, 0.0}, worst[2] = {0.0, 0.0};
    for (std::size_t k = 0; k < u.size(); ++k) {
      const int kind = (k % 6) < 3 ? 0 : 1;
      largest[kind] = std::max(largest[kind], std::abs(reference[static_cast<Eigen::Index>(k)]));
      worst[kind] = std::max(worst[kind], std::abs(u[k] - reference[static_cast<Eigen::Index>(k)]));
    }
    double largestAxial = 0.0, worstAxial = 0.0;
    for (std::size_t r = 0; r < bonds.size(); ++r) {
      const std::size_t k = bonds[r].index(), a = localOf[con.a[k].index()], b = localOf[con.b[k].index()];
      const Vec3 d = p.local[con.b[k].index()] - p.local[con.a[k].index()];
      const double r0 = con.bondRadius[k];
      const double axial = removed[r] ? 0.0 : con.youngsModulus[k] * std::numbers::pi * r0 * r0 / d.norm() * d.normalized().dot(
          reference.segment<3>(static_cast<Eigen::Index>(6 * b)) - reference.segment<3>(static_cast<Eigen::Index>(6 * a)));
      largestAxial = std::max(largestAxial, std::abs(axial));
      worstAxial = std::max(worstAxial, std::abs(axial - out[r].axial));
    }
    std::printf("%zu particles, %zu bonds, %s: %d iterations; displacement %.2e, rotation %.2e, axial force %.2e of the largest\n",
                n, bonds.size(), what, frame.iterations(), worst[0] / largest[0], worst[1] / largest[1], worstAxial / largestAxial);
    EXPECT_LE(worst[0], agreement * largest[0]) << n << " particles, " << what;
    EXPECT_LE(worst[1], agreement * largest[1]) << n << " particles, " << what;
    EXPECT_LE(worstAxial, agreement * largestAxial) << n << " particles, " << what;
  };

  std::vector<std::uint8_t> removed(bonds.size(), 0);
  BondLoads frame;
  ASSERT_TRUE(frame.build(info, p, con, bonds));
  std::vector<BondLoad> out;
  frame.solve(state, info, p, loads, out);
  agree(frame, out, directSolve(removed), removed, "from rest", kAgreement);
  EXPECT_GT(frame.iterations(), 0);
  // the multigrid keeps the iterations from growing with the size (6 to 8 from rest, to BondLoads::kTolerance)
  EXPECT_LE(frame.iterations(), kIterations) << n << " particles";

  // passes of breaks: the most loaded bonds leave, and the frame is solved again around them only, three
  // times over; what it gives agrees with the direct solve of the frame without them
  if (!breaks) return;
  std::vector<std::uint32_t> changed;
  int localPasses = 0;
  for (int pass = 0; pass < 3; ++pass) {
    std::vector<std::size_t> order(bonds.size());
    for (std::size_t r = 0; r < bonds.size(); ++r) order[r] = r;
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) { return std::abs(out[x].axial) > std::abs(out[y].axial); });
    std::vector<std::size_t> entries(order.begin(), order.begin() + 4);
    for (const std::size_t r : entries) removed[r] = 1;
    frame.remove(entries);
    const std::vector<BondLoad> before = out;
    frame.solveAround(entries, state, info, p, loads, out, changed);
    // the bonds it did not list kept their loads
    std::vector<std::uint8_t> listed(bonds.size(), 0);
    for (const std::uint32_t r : changed) listed[r] = 1;
    for (std::size_t r = 0; r < bonds.size(); ++r) {
      if (!listed[r]) { EXPECT_EQ(out[r].axial, before[r].axial) << r; }
    }
    for (const std::size_t r : entries) EXPECT_TRUE(listed[r]) << r;
    // a pass solved around its breaks resolves what they change to BondLoads::kPassTolerance; one that
    // reached a quarter of the frame solved all of it
    const bool around = changed.size() < bonds.size();
    localPasses += around ? 1 : 0;
    agree(frame, out, directSolve(removed), removed, around ? "solved around the removed bonds" : "solved whole",
          around ? kPassAgreement : kAgreement);
  }
  EXPECT_GT(localPasses, 0) << "no pass was solved around its breaks";
}

TEST(BondLoadsAccuracy, AgreesWithADirectSolveFrom100To20000Particles) {
  const Case cases[] = {
      {"[0.5, 0.5, 0.4]", 0.05},      // 5 x 5 x 4 = 100
      {"[1.0, 1.0, 1.0]", 0.05},      // 1 000
      {"[1.0, 2.0, 2.5]", 0.05},      // 5 000
      {"[14.1, 14.1, 0.1]", 0.05},    // a plate of one layer, 141 x 141 = 19 881 (bending: the hardest case)
  };
  std::uint32_t seed = 1;
  for (const Case& c : cases) checkAgainstDirectSolve(c, seed++);
  checkAgainstDirectSolve(cases[1], seed);
}

TEST(BondLoadsAccuracy, SolvingAroundBrokenBondsAgreesWithADirectSolveWithoutThem) {
  // a plate of one layer (bending spreads the furthest): 71 x 71 = 5 041 particles
  checkAgainstDirectSolve({"[7.1, 7.1, 0.1]", 0.05}, 7, true);
}

}  // namespace
}  // namespace volpar
