#include "volpar/dynamics/bond_loads.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "volpar/dynamics/breakage.hpp"

namespace volpar {

namespace {

using Mat8x12 = Eigen::Matrix<double, 8, 12>;
using Vec8 = Eigen::Matrix<double, 8, 1>;
using Vec12 = Eigen::Matrix<double, 12, 1>;

Mat3 cross(const Vec3& v) {
  Mat3 m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

/// The beam's deformations from its ends' displacements and rotations (u_a, theta_a, u_b, theta_b):
/// stretch, twist, and the two ends' rotations across the bond relative to its chord.
Mat8x12 strainMap(const Vec3& e, double length) {
  Mat8x12 b = Mat8x12::Zero();
  const Mat3 p = Mat3::Identity() - e * e.transpose();
  const Mat3 chord = cross(e) / length;  // the chord's rotation per unit of (u_b - u_a)
  b.block<1, 3>(0, 0) = -e.transpose();
  b.block<1, 3>(0, 6) = e.transpose();
  b.block<1, 3>(1, 3) = -e.transpose();
  b.block<1, 3>(1, 9) = e.transpose();
  b.block<3, 3>(2, 0) = chord;
  b.block<3, 3>(2, 3) = p;
  b.block<3, 3>(2, 6) = -chord;
  b.block<3, 3>(5, 0) = chord;
  b.block<3, 3>(5, 6) = -chord;
  b.block<3, 3>(5, 9) = p;
  return b;
}

}  // namespace

BondStress bondStress(const BondLoad& load, double radius) {
  const double area = std::numbers::pi * radius * radius;
  const double inertia = 0.25 * area * radius * radius;  // I = pi R^4 / 4, J = 2 I
  const double bendingStress = load.bending * radius / inertia;
  const double normal = std::abs(load.axial) / area + bendingStress;
  const double shear = load.shear / area + load.torsion * radius / (2.0 * inertia);
  return {load.axial / area + bendingStress, std::sqrt(0.25 * normal * normal + shear * shear)};
}

BondFailure bondFailure(const BondStress& stress, double tensileStrength, double shearStrength) {
  if (stress.tensile > tensileStrength) return BondFailure::Tension;
  if (stress.shear > shearStrength) return BondFailure::Shear;
  return BondFailure::None;
}

namespace {

/// K_e = B^T D B of one beam, D = diag(EA/L, GJ/L, (EI/L) [4 2; 2 4] (x) I3).
Eigen::Matrix<double, 12, 12> beamStiffness(const Vec3& e, double length, double axial, double torsion, double bending) {
  const Mat8x12 b = strainMap(e, length);
  Eigen::Matrix<double, 8, 8> dm = Eigen::Matrix<double, 8, 8>::Zero();
  dm(0, 0) = axial;
  dm(1, 1) = torsion;
  dm.block<3, 3>(2, 2) = 4.0 * bending * Mat3::Identity();
  dm.block<3, 3>(5, 5) = 4.0 * bending * Mat3::Identity();
  dm.block<3, 3>(2, 5) = 2.0 * bending * Mat3::Identity();
  dm.block<3, 3>(5, 2) = 2.0 * bending * Mat3::Identity();
  return b.transpose() * dm * b;
}

/// Calls f(row, column, value) for each entry of a beam's stiffness in the frame's matrix, its two ends'
/// six freedoms each (zeros too: the pattern keeps them, so that removing the beam changes values only).
template <class F>
void forEachEntry(std::uint32_t a, std::uint32_t b, const Eigen::Matrix<double, 12, 12>& ke, F&& f) {
  const std::uint32_t node[2] = {a, b};
  for (int bi = 0; bi < 2; ++bi)
    for (int bj = 0; bj < 2; ++bj)
      for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j)
          f(static_cast<Eigen::Index>(6 * node[bi]) + i, static_cast<Eigen::Index>(6 * node[bj]) + j, ke(6 * bi + i, 6 * bj + j));
}

}  // namespace

bool BondLoads::build(const BodyInfo& body, const ParticleStore& p, const ConnectorStore& c,
                      std::span<const ConnectorId> bonds) {
  bonds_.assign(bonds.begin(), bonds.end());
  beams_.clear();
  stale_ = false;
  removed_.clear();
  factorisedAt_ = 0;
  if (bonds_.empty()) return false;
  const std::size_t n = body.particles.size();
  std::size_t maxId = 0;
  for (const ParticleId q : body.particles) maxId = std::max(maxId, q.index());
  local_.assign(maxId + 1, 0);
  for (std::size_t i = 0; i < n; ++i) local_[body.particles[i].index()] = static_cast<std::uint32_t>(i);
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(bonds_.size() * 144 + 6 * n);
  Eigen::VectorXd diag = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(6 * n));
  for (const ConnectorId id : bonds_) {
    const std::size_t k = id.index();
    Beam beam;
    beam.a = local_[c.a[k].index()];
    beam.b = local_[c.b[k].index()];
    const Vec3 d = p.local[c.b[k].index()] - p.local[c.a[k].index()];
    beam.length = d.norm();
    beam.e = d / beam.length;
    const double r = c.bondRadius[k], e = c.youngsModulus[k];
    const double area = std::numbers::pi * r * r, inertia = 0.25 * area * r * r;
    const double shearModulus = e / (2.0 * (1.0 + c.poissonRatio[k]));
    beam.axial = e * area / beam.length;
    beam.torsion = shearModulus * 2.0 * inertia / beam.length;
    beam.bending = e * inertia / beam.length;
    beams_.push_back(beam);
    forEachEntry(beam.a, beam.b, beamStiffness(beam.e, beam.length, beam.axial, beam.torsion, beam.bending),
                 [&](Eigen::Index row, Eigen::Index col, double v) {
                   t.emplace_back(static_cast<int>(row), static_cast<int>(col), v);
                   if (row == col) diag[row] += v;
                 });
  }
  // the six rigid-body modes make K singular; a tiny regularisation (per kind of freedom, which differ in
  // units) picks the solution without rigid motion and leaves a self-equilibrated load's deformations as they are
  double maxMove = 0.0, maxTurn = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      maxMove = std::max(maxMove, diag[static_cast<Eigen::Index>(6 * i) + k]);
      maxTurn = std::max(maxTurn, diag[static_cast<Eigen::Index>(6 * i) + 3 + k]);
    }
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 6; ++k)
      t.emplace_back(static_cast<int>(6 * i) + k, static_cast<int>(6 * i) + k, 1e-9 * (k < 3 ? maxMove : maxTurn));
  k_.resize(static_cast<Eigen::Index>(6 * n), static_cast<Eigen::Index>(6 * n));
  k_.setFromTriplets(t.begin(), t.end());
  k_.makeCompressed();
  ldlt_.analyzePattern(k_);
  f_.resize(static_cast<Eigen::Index>(6 * n));
  return factorise();
}

bool BondLoads::factorise() {
  ldlt_.factorize(k_);
  stale_ = false;
  factorisedAt_ = removed_.size();
  return ldlt_.info() == Eigen::Success;
}

void BondLoads::remove(std::span<const std::size_t> entries) {
  for (const std::size_t k : entries) {
    const Beam& beam = beams_[k];
    if (!beam.active) continue;
    forEachEntry(beam.a, beam.b, beamStiffness(beam.e, beam.length, beam.axial, beam.torsion, beam.bending),
                 [&](Eigen::Index row, Eigen::Index col, double v) { k_.coeffRef(row, col) -= v; });
    beams_[k].active = false;
    stale_ = true;
    removed_.push_back(static_cast<std::uint32_t>(k));
  }
}

bool BondLoads::replay(const BodyInfo& body, const ParticleStore& particles, const ConnectorStore& connectors,
                       std::span<const ConnectorId> bonds, std::span<const std::uint32_t> removed, std::size_t factorisedAt) {
  if (!build(body, particles, connectors, bonds) || factorisedAt > removed.size()) return false;
  for (std::size_t i = 0; i < removed.size(); ++i) {
    if (removed[i] >= beams_.size() || !beams_[removed[i]].active) return false;
    const std::size_t entry = removed[i];
    remove(std::span<const std::size_t>(&entry, 1));
    if (i + 1 == factorisedAt && !factorise()) return false;
  }
  return true;
}

void BondLoads::solve(const BodyState& s, const BodyInfo& body, const ParticleStore& p, std::span<const Vec3> loads,
                      std::vector<BondLoad>& out) {
  const std::size_t n = body.particles.size();
  const Mat3 r = s.orientation.toRotationMatrix();
  const RigidAcceleration motion = rigidAcceleration(s, body, p, loads);
  const Vec3 alphaLocal = r.transpose() * motion.angular;
  const Vec3 residualMoment = body.inertiaResidual * alphaLocal;  // shared by mass
  // self-equilibrated loads in the body frame: forces on the particles less their d'Alembert forces, and
  // the d'Alembert moments of what each particle adds to the body's inertia beyond its point mass
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t q = body.particles[i].index();
    const Vec3 inertial = motion.inertialForce(s, p.mass[q], p.position[q] - s.position);
    f_.segment<3>(static_cast<Eigen::Index>(6 * i)) = r.transpose() * (loads[q] - inertial);
    f_.segment<3>(static_cast<Eigen::Index>(6 * i + 3)) =
        -(p.ownInertia[q] * alphaLocal + (p.mass[q] / body.mass) * residualMoment);
  }
  if (!stale_) {
    u_ = ldlt_.solve(f_);
  } else {
    // conjugate gradients on the frame as it is now, preconditioned by the factorisation of the frame it was
    // (which differs by the bonds removed since): a few iterations, or a new factorisation where they do not do
    constexpr int kIterations = 40;
    constexpr double kTolerance = 1e-10;
    u_ = ldlt_.solve(f_);
    r_ = f_ - k_ * u_;
    const double target = kTolerance * kTolerance * f_.squaredNorm();
    z_ = ldlt_.solve(r_);
    p_ = z_;
    double rz = r_.dot(z_);
    int it = 0;
    for (; it < kIterations && r_.squaredNorm() > target; ++it) {
      q_ = k_ * p_;
      const double step = rz / p_.dot(q_);
      u_ += step * p_;
      r_ -= step * q_;
      z_ = ldlt_.solve(r_);
      const double next = r_.dot(z_);
      p_ = z_ + (next / rz) * p_;
      rz = next;
    }
    if (r_.squaredNorm() > target) {
      factorise();
      u_ = ldlt_.solve(f_);
    }
  }
  out.resize(beams_.size());
  for (std::size_t k = 0; k < beams_.size(); ++k) {
    const Beam& beam = beams_[k];
    if (!beam.active) {
      out[k] = BondLoad{};
      continue;
    }
    Vec12 d;
    d.segment<6>(0) = u_.segment<6>(static_cast<Eigen::Index>(6 * beam.a));
    d.segment<6>(6) = u_.segment<6>(static_cast<Eigen::Index>(6 * beam.b));
    const Vec8 strain = strainMap(beam.e, beam.length) * d;
    const Vec3 psiA = strain.segment<3>(2), psiB = strain.segment<3>(5);
    const Vec3 ma = beam.bending * (4.0 * psiA + 2.0 * psiB), mb = beam.bending * (2.0 * psiA + 4.0 * psiB);
    BondLoad& l = out[k];
    l.axial = beam.axial * strain[0];
    l.torsion = std::abs(beam.torsion * strain[1]);
    l.bending = std::max(ma.norm(), mb.norm());
    l.shear = (ma + mb).norm() / beam.length;
    l.energy = 0.5 * (beam.axial * strain[0] * strain[0] + beam.torsion * strain[1] * strain[1] + psiA.dot(ma) + psiB.dot(mb));
  }
}

}  // namespace volpar
