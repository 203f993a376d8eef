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

}  // namespace

namespace {

/// (particle id, node) of `nodes`, sorted: a node's lookup by its particle (a fragment's ids are few and
/// scattered, so no world-sized table).
std::vector<std::pair<std::uint32_t, std::uint32_t>> nodesByParticle(std::span<const std::uint32_t> nodes) {
  std::vector<std::pair<std::uint32_t, std::uint32_t>> sorted(nodes.size());
  for (std::size_t i = 0; i < nodes.size(); ++i) sorted[i] = {nodes[i], static_cast<std::uint32_t>(i)};
  std::sort(sorted.begin(), sorted.end());
  return sorted;
}

/// The node of particle `q` in a list made by nodesByParticle, or false where it is none.
bool findNode(const std::vector<std::pair<std::uint32_t, std::uint32_t>>& sorted, std::size_t q, std::uint32_t& node) {
  const auto it = std::lower_bound(sorted.begin(), sorted.end(), std::pair{static_cast<std::uint32_t>(q), 0u});
  if (it == sorted.end() || it->first != q) return false;
  node = it->second;
  return true;
}

}  // namespace

bool BondLoads::build(const BodyInfo& body, const ParticleStore& p, const ConnectorStore& c,
                      std::span<const ConnectorId> bonds) {
  const std::size_t n = body.particles.size();
  std::vector<std::uint32_t> nodes(n);
  std::vector<Vec3> positions(n);
  for (std::size_t i = 0; i < n; ++i) {
    nodes[i] = static_cast<std::uint32_t>(body.particles[i].index());
    positions[i] = p.local[body.particles[i].index()];
  }
  if (!buildFrame(nodes, positions, c, bonds)) return false;
  bodyNode_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) bodyNode_[i] = i;
  toFrame_ = Mat3::Identity();
  return true;
}

bool BondLoads::buildFrame(std::span<const std::uint32_t> nodes, std::span<const Vec3> positions, const ConnectorStore& c,
                           std::span<const ConnectorId> bonds) {
  bonds_.assign(bonds.begin(), bonds.end());
  beams_.clear();
  removed_.clear();
  iterations_ = 0;
  nodeParticle_.assign(nodes.begin(), nodes.end());
  nodePosition_.assign(positions.begin(), positions.end());
  if (bonds_.empty()) return false;
  const std::size_t n = nodes.size();
  const auto byParticle = nodesByParticle(nodes);
  beams_.reserve(bonds_.size());
  for (const ConnectorId id : bonds_) {
    const std::size_t k = id.index();
    Beam beam;
    if (!findNode(byParticle, c.a[k].index(), beam.a) || !findNode(byParticle, c.b[k].index(), beam.b)) return false;
    const Vec3 d = positions[beam.b] - positions[beam.a];
    beam.length = d.norm();
    beam.e = d / beam.length;
    const double r = c.bondRadius[k], e = c.youngsModulus[k];
    const double area = std::numbers::pi * r * r, inertia = 0.25 * area * r * r;
    const double shearModulus = e / (2.0 * (1.0 + c.poissonRatio[k]));
    beam.axial = e * area / beam.length;
    beam.torsion = shearModulus * 2.0 * inertia / beam.length;
    beam.bending = e * inertia / beam.length;
    beams_.push_back(beam);
  }
  // the pattern: each particle's bonded neighbours
  std::vector<std::uint32_t> neighbourStart(n + 1, 0), neighbours;
  {
    for (const Beam& b : beams_) ++neighbourStart[b.a + 1], ++neighbourStart[b.b + 1];
    for (std::size_t i = 0; i < n; ++i) neighbourStart[i + 1] += neighbourStart[i];
    neighbours.resize(neighbourStart[n]);
    std::vector<std::uint32_t> fill(neighbourStart.begin(), neighbourStart.end() - 1);
    for (const Beam& b : beams_) neighbours[fill[b.a]++] = b.b, neighbours[fill[b.b]++] = b.a;
    // sorted, without duplicates (two bonds between the same particles share their blocks)
    std::uint32_t out = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const auto first = neighbours.begin() + neighbourStart[i], last = neighbours.begin() + neighbourStart[i + 1];
      std::sort(first, last);
      const auto unique = std::unique(first, last);
      const std::uint32_t begin = out;
      for (auto it = first; it != unique; ++it) neighbours[out++] = *it;
      neighbourStart[i] = begin;
    }
    neighbourStart[n] = out;
    neighbours.resize(out);
  }
  k_.setPattern(neighbourStart, neighbours);
  for (const Beam& beam : beams_) {
    const Eigen::Matrix<double, 12, 12> ke = beamStiffness(beam.e, beam.length, beam.axial, beam.torsion, beam.bending);
    k_.diagonalBlock[beam.a] += ke.block<6, 6>(0, 0);
    k_.diagonalBlock[beam.b] += ke.block<6, 6>(6, 6);
    k_.addCoupling(beam.a, beam.b, beam.e, beam.length, beam.axial, beam.torsion, beam.bending, 1.0);
  }
  // the six rigid-body modes make K singular; a tiny regularisation (per kind of freedom, which differ in
  // units) picks the solution without rigid motion and leaves a self-equilibrated load's deformations as they are
  double maxMove = 0.0, maxTurn = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      maxMove = std::max(maxMove, k_.diagonalBlock[i](k, k));
      maxTurn = std::max(maxTurn, k_.diagonalBlock[i](3 + k, 3 + k));
    }
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 6; ++k) k_.diagonalBlock[i](k, k) += 1e-9 * (k < 3 ? maxMove : maxTurn);
  multigrid_.build(k_, nodePosition_);
  // the beams at each node, for solveAround()
  beamStart_.assign(n + 1, 0);
  for (const Beam& b : beams_) ++beamStart_[b.a + 1], ++beamStart_[b.b + 1];
  for (std::size_t i = 0; i < n; ++i) beamStart_[i + 1] += beamStart_[i];
  nodeBeams_.resize(beamStart_[n]);
  {
    std::vector<std::uint32_t> fill(beamStart_.begin(), beamStart_.end() - 1);
    for (std::uint32_t k = 0; k < beams_.size(); ++k) nodeBeams_[fill[beams_[k].a]++] = k, nodeBeams_[fill[beams_[k].b]++] = k;
  }
  mark_.assign(n, 0);
  regionStamp_ = 0;
  region_.clear();
  region_.reserve(n);
  const auto dofs = static_cast<Eigen::Index>(6 * n);
  f_.setZero(dofs);
  u_.setZero(dofs);
  r_.setZero(dofs);
  z_.resize(dofs);
  p_.resize(dofs);
  q_.resize(dofs);
  return true;
}

void BondLoads::remove(std::span<const std::size_t> entries) {
  for (const std::size_t k : entries) {
    Beam& beam = beams_[k];
    if (!beam.active) continue;
    const Eigen::Matrix<double, 12, 12> ke = -beamStiffness(beam.e, beam.length, beam.axial, beam.torsion, beam.bending);
    k_.diagonalBlock[beam.a] += ke.block<6, 6>(0, 0);
    k_.diagonalBlock[beam.b] += ke.block<6, 6>(6, 6);
    k_.addCoupling(beam.a, beam.b, beam.e, beam.length, beam.axial, beam.torsion, beam.bending, -1.0);
    multigrid_.change(k_, beam.a, beam.a, ke.block<6, 6>(0, 0));
    multigrid_.change(k_, beam.b, beam.b, ke.block<6, 6>(6, 6));
    multigrid_.change(k_, beam.a, beam.b, ke.block<6, 6>(0, 6));
    // the residual f - K u loses the beam's forces (-ke is its stiffness)
    Vec12 ends;
    ends << u_.segment<6>(6 * static_cast<Eigen::Index>(beam.a)), u_.segment<6>(6 * static_cast<Eigen::Index>(beam.b));
    const Vec12 forces = -ke * ends;
    residualSquared_ -= r_.segment<6>(6 * static_cast<Eigen::Index>(beam.a)).squaredNorm() +
                        r_.segment<6>(6 * static_cast<Eigen::Index>(beam.b)).squaredNorm();
    r_.segment<6>(6 * static_cast<Eigen::Index>(beam.a)) += forces.head<6>();
    r_.segment<6>(6 * static_cast<Eigen::Index>(beam.b)) += forces.tail<6>();
    residualSquared_ += r_.segment<6>(6 * static_cast<Eigen::Index>(beam.a)).squaredNorm() +
                        r_.segment<6>(6 * static_cast<Eigen::Index>(beam.b)).squaredNorm();
    beam.active = false;
    removed_.push_back(static_cast<std::uint32_t>(k));
  }
}

bool BondLoads::replay(const BodyInfo& body, const ConnectorStore& connectors, std::span<const std::uint32_t> nodes,
                       std::span<const Vec3> positions, const Mat3& axes, std::span<const ConnectorId> bonds,
                       std::span<const std::uint32_t> removed, std::span<const double> displacements) {
  if (positions.size() != nodes.size() || displacements.size() != 6 * nodes.size()) return false;
  for (const Vec3& x : positions)
    if (!x.allFinite()) return false;
  if (!buildFrame(nodes, positions, connectors, bonds)) return false;
  for (const std::uint32_t entry : removed) {
    if (entry >= beams_.size() || !beams_[entry].active) return false;
    const std::size_t k = entry;
    remove(std::span<const std::size_t>(&k, 1));
  }
  // the body's particles, each a node
  const auto byParticle = nodesByParticle(nodes);
  bodyNode_.resize(body.particles.size());
  for (std::size_t i = 0; i < body.particles.size(); ++i)
    if (!findNode(byParticle, body.particles[i].index(), bodyNode_[i])) return false;
  toFrame_ = axes;
  u_ = Eigen::Map<const Eigen::VectorXd>(displacements.data(), u_.size());
  return true;
}

void BondLoads::keepFor(std::span<const std::uint32_t> parentIndex, const Mat3& turn) {
  std::vector<std::uint32_t> kept(parentIndex.size());
  for (std::size_t i = 0; i < parentIndex.size(); ++i) kept[i] = bodyNode_[parentIndex[i]];
  bodyNode_.swap(kept);
  // vectors in the piece's axes turn back into the parent's (turn^T), and from there into the frame's
  toFrame_ = toFrame_ * turn.transpose();
  std::vector<std::uint8_t> live(nodeParticle_.size(), 0);
  for (const std::uint32_t node : bodyNode_) live[node] = 1;
  // the other pieces' bonds leave the frame (every bond between the pieces is broken already), and their
  // nodes rest: no load, no displacement
  std::vector<std::size_t> leaving;
  for (std::size_t k = 0; k < beams_.size(); ++k)
    if (beams_[k].active && (!live[beams_[k].a] || !live[beams_[k].b])) leaving.push_back(k);
  remove(leaving);
  for (std::size_t node = 0; node < live.size(); ++node)
    if (!live[node]) {
      u_.segment<6>(6 * static_cast<Eigen::Index>(node)).setZero();
      f_.segment<6>(6 * static_cast<Eigen::Index>(node)).setZero();
    }
}

void BondLoads::startFrom(const BondLoads& parent, std::span<const std::uint32_t> parentIndex, const Mat3& turn) {
  // the parent's displacements are in its frame's axes: back into its body's, then into this body's
  const Mat3 toHere = toFrame_ * turn * parent.toFrame_.transpose();
  for (std::size_t i = 0; i < parentIndex.size() && i < bodyNode_.size(); ++i) {
    const auto from = 6 * static_cast<Eigen::Index>(parent.bodyNode_[parentIndex[i]]);
    const auto to = 6 * static_cast<Eigen::Index>(bodyNode_[i]);
    u_.segment<3>(to) = toHere * parent.u_.segment<3>(from);
    u_.segment<3>(to + 3) = toHere * parent.u_.segment<3>(from + 3);
  }
}

std::size_t BondLoads::bytes() const {
  return bonds_.size() * sizeof(ConnectorId) + beams_.size() * sizeof(Beam) + removed_.size() * 4 +
         (nodeParticle_.size() + bodyNode_.size()) * 4 + nodePosition_.size() * sizeof(Vec3) +
         k_.bytes() + multigrid_.bytes() +
         6 * static_cast<std::size_t>(u_.size()) * sizeof(double) +
         (beamStart_.size() + nodeBeams_.size() + mark_.size() + region_.capacity()) * 4;
}

void BondLoads::solve(const BodyState& s, const BodyInfo& body, const ParticleStore& p, std::span<const Vec3> loads,
                      std::vector<BondLoad>& out, ThreadPool* pool) {
  const std::size_t n = body.particles.size();
  const Mat3 r = s.orientation.toRotationMatrix();
  const RigidAcceleration motion = rigidAcceleration(s, body, p, loads);
  const Vec3 alphaLocal = r.transpose() * motion.angular;
  const Vec3 residualMoment = body.inertiaResidual * alphaLocal;  // shared by mass
  // self-equilibrated loads in the body frame: forces on the particles less their d'Alembert forces, and
  // the d'Alembert moments of what each particle adds to the body's inertia beyond its point mass
  // (in the frame's axes; the nodes of pieces split off a kept frame carry none)
  const Mat3 toFrame = toFrame_ * r.transpose();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t q = body.particles[i].index();
    const auto node = 6 * static_cast<Eigen::Index>(bodyNode_[i]);
    const Vec3 inertial = motion.inertialForce(s, p.mass[q], p.position[q] - s.position);
    f_.segment<3>(node) = toFrame * (loads[q] - inertial);
    f_.segment<3>(node + 3) = -(toFrame_ * (p.ownInertia[q] * alphaLocal + (p.mass[q] / body.mass) * residualMoment));
  }
  // flexible conjugate gradients preconditioned by the multigrid, from the last displacements (every sum in
  // fixed chunks: the same bits for any number of threads)
  iterations_ = 0;
  const auto dot = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& y) { return chunkedDot(x, y, pool, partial_); };
  loadSquared_ = dot(f_, f_);
  const double target = kTolerance * kTolerance * loadSquared_;
  k_.multiply(u_, q_, pool);
  r_ = f_ - q_;
  if (dot(r_, r_) > target) {
    multigrid_.apply(k_, r_, z_, pool);
    p_ = z_;
    double rz = dot(r_, z_);
    for (; iterations_ < kMaxIterations && dot(r_, r_) > target; ++iterations_) {
      k_.multiply(p_, q_, pool);
      const double step = rz / dot(p_, q_);
      u_ += step * p_;
      r_ -= step * q_;
      multigrid_.apply(k_, r_, z_, pool);
      // (flexible: Polak-Ribiere's beta, z_new . (r_new - r_old) / (z_old . r_old), r_new - r_old = -step q)
      const double beta = -step * dot(z_, q_) / rz;
      rz = dot(r_, z_);
      p_ = z_ + beta * p_;
    }
  }
  residualSquared_ = dot(r_, r_);
  out.resize(beams_.size());
  for (std::size_t k = 0; k < beams_.size(); ++k) out[k] = beams_[k].active ? beamLoad(beams_[k]) : BondLoad{};
}

BondLoad BondLoads::beamLoad(const Beam& beam) const {
  // the strains of strainMap(), term by term
  const auto a = static_cast<Eigen::Index>(6 * beam.a), b = static_cast<Eigen::Index>(6 * beam.b);
  const Vec3 du = u_.segment<3>(b) - u_.segment<3>(a);
  const Vec3 ta = u_.segment<3>(a + 3), tb = u_.segment<3>(b + 3);
  const Vec3 chord = beam.e.cross(du) / beam.length;
  const double stretch = beam.e.dot(du), twist = beam.e.dot(tb - ta);
  const Vec3 psiA = ta - beam.e * beam.e.dot(ta) - chord, psiB = tb - beam.e * beam.e.dot(tb) - chord;
  const Vec3 ma = beam.bending * (4.0 * psiA + 2.0 * psiB), mb = beam.bending * (2.0 * psiA + 4.0 * psiB);
  BondLoad l;
  l.axial = beam.axial * stretch;
  l.torsion = std::abs(beam.torsion * twist);
  l.bending = std::max(ma.norm(), mb.norm());
  l.shear = (ma + mb).norm() / beam.length;
  l.energy = 0.5 * (beam.axial * stretch * stretch + beam.torsion * twist * twist + psiA.dot(ma) + psiB.dot(mb));
  return l;
}

std::uint32_t BondLoads::nextStamp() {
  if (regionStamp_ > 0xfffffff0u) {  // (before it wraps: every mark cleared once)
    std::fill(mark_.begin(), mark_.end(), 0u);
    regionStamp_ = 0;
  }
  regionStamp_ += 2;
  return regionStamp_;
}

bool BondLoads::endsJoined(std::span<const std::size_t> entries) {
  for (const std::size_t e : entries) {
    const std::uint32_t from = beams_[e].a, to = beams_[e].b;
    const std::uint32_t stamp = nextStamp();
    region_.clear();
    region_.push_back(from);
    mark_[from] = stamp;
    bool found = false;
    // breadth first from `from` over the active beams, until `to`, the budget, or the end of its piece
    for (std::size_t head = 0; head < region_.size() && !found && region_.size() < kJoinSearch; ++head)
      for (std::uint32_t j = beamStart_[region_[head]]; j < beamStart_[region_[head] + 1]; ++j) {
        const Beam& beam = beams_[nodeBeams_[j]];
        if (!beam.active) continue;
        const std::uint32_t next = beam.a == region_[head] ? beam.b : beam.a;
        if (next == to) {
          found = true;
          break;
        }
        if (mark_[next] == stamp) continue;
        mark_[next] = stamp;
        region_.push_back(next);
      }
    if (!found) return false;
  }
  return true;
}

void BondLoads::solveAround(std::span<const std::size_t> entries, const BodyState& s, const BodyInfo& body,
                            const ParticleStore& p, std::span<const Vec3> loads, std::vector<BondLoad>& out,
                            std::vector<std::uint32_t>& changed, ThreadPool* pool) {
  const std::size_t n = nodeParticle_.size();
  const auto whole = [&] {
    solve(s, body, p, loads, out, pool);
    changed.resize(beams_.size());
    for (std::uint32_t k = 0; k < beams_.size(); ++k) changed[k] = k;
  };
  if (multigrid_.levels() < 2) return whole();
  const auto node = [](std::uint32_t i) { return 6 * static_cast<Eigen::Index>(i); };
  const auto squared = [&](std::size_t from, std::size_t to) {  // sum of r_i . r_i over region_[from, to)
    double sum = 0.0;
    for (std::size_t i = from; i < to; ++i) sum += r_.segment<6>(node(region_[i])).squaredNorm();
    return sum;
  };
  // the residual the removed bonds left (their forces, on their ends)
  double changeSquared = 0.0;
  for (const std::size_t e : entries)
    changeSquared += r_.segment<6>(node(beams_[e].a)).squaredNorm() + r_.segment<6>(node(beams_[e].b)).squaredNorm();
  // solved where the whole frame's residual is within solve()'s tolerance or kPassTolerance of that
  const double target = std::max(kTolerance * kTolerance * loadSquared_, kPassTolerance * kPassTolerance * changeSquared);
  std::size_t interior = 0;  // region_[0, interior): the region; the rest, its rim
  std::uint32_t inside = 0;
  for (int rings = kRegionRings;; rings *= 2) {
    // the region: the removed bonds' ends and the nodes within `rings` bonds of them (the stiffness's pattern),
    // then its rim (the nodes one bond further), whose residual the region's change reaches
    inside = nextStamp();
    const std::uint32_t rim = inside + 1;
    region_.clear();
    const auto reach = [&](std::uint32_t i, std::uint32_t stamp) {
      if (mark_[i] == inside || mark_[i] == rim) return;
      mark_[i] = stamp;
      region_.push_back(i);
    };
    for (const std::size_t e : entries) {
      reach(beams_[e].a, inside);
      reach(beams_[e].b, inside);
    }
    std::size_t frontier = 0;
    for (int ring = 0; ring <= rings; ++ring) {
      const std::size_t end = region_.size();
      if (4 * end >= n) return whole();  // (from the displacements so far)
      for (std::size_t i = frontier; i < end; ++i)
        for (std::uint32_t k = k_.start[region_[i]]; k < k_.start[region_[i] + 1]; ++k)
          reach(k_.column[k], ring < rings ? inside : rim);
      frontier = end;
    }
    interior = frontier;
    // conjugate gradients on the region, block Jacobi, the rim's and the rest's displacements held; r_ stays
    // f - K u everywhere (the rim's rows take the region's change too), and the whole frame's residual is
    // what it was outside the region and its rim plus what it is on them now
    const double outside = std::max(0.0, residualSquared_ - squared(0, region_.size()));
    double regionPart = squared(0, interior), total = outside + regionPart + squared(interior, region_.size());
    const auto regionDot = [&](const Eigen::VectorXd& x, const Eigen::VectorXd& y) {
      double sum = 0.0;
      for (std::size_t i = 0; i < interior; ++i) sum += x.segment<6>(node(region_[i])).dot(y.segment<6>(node(region_[i])));
      return sum;
    };
    if (total > target && regionPart > 0.25 * target) {
      for (std::size_t i = 0; i < interior; ++i)
        p_.segment<6>(node(region_[i])) = z_.segment<6>(node(region_[i])) =
            multigrid_.fineDiagonalInverse(region_[i]) * r_.segment<6>(node(region_[i]));
      double rz = regionDot(r_, z_);
      for (int iteration = 0; iteration < kMaxIterations && total > target && regionPart > 0.25 * target; ++iteration) {
        // q = K p over the region's and the rim's rows, from the region's columns
        for (const std::uint32_t i : region_) {
          Vec6 sum = Vec6::Zero();  // (-q: the entries' products subtract)
          if (mark_[i] == inside) sum = -(k_.diagonalBlock[i] * p_.segment<6>(node(i)));
          for (std::uint32_t k = k_.start[i]; k < k_.start[i + 1]; ++k)
            if (k != k_.diagonal[i] && mark_[k_.column[k]] == inside) k_.subtractProduct(k, p_.data() + node(k_.column[k]), sum);
          q_.segment<6>(node(i)) = -sum;
        }
        const double step = rz / regionDot(p_, q_);
        for (std::size_t i = 0; i < interior; ++i) u_.segment<6>(node(region_[i])) += step * p_.segment<6>(node(region_[i]));
        for (const std::uint32_t i : region_) r_.segment<6>(node(i)) -= step * q_.segment<6>(node(i));
        for (std::size_t i = 0; i < interior; ++i)
          z_.segment<6>(node(region_[i])) = multigrid_.fineDiagonalInverse(region_[i]) * r_.segment<6>(node(region_[i]));
        const double rzNew = regionDot(r_, z_);
        const double beta = rzNew / rz;
        rz = rzNew;
        for (std::size_t i = 0; i < interior; ++i)
          p_.segment<6>(node(region_[i])) = z_.segment<6>(node(region_[i])) + beta * p_.segment<6>(node(region_[i]));
        regionPart = squared(0, interior);
        total = outside + regionPart + squared(interior, region_.size());
      }
    }
    residualSquared_ = total;
    // solved where the whole frame's residual is within the tolerance; else what is left lies on the rim (or
    // the iterations ran out): a region twice as wide takes it on
    if (total <= target) break;
  }
  // the loads of the bonds with an end in the region, each once
  changed.clear();
  out.resize(beams_.size());
  for (std::size_t i = 0; i < interior; ++i)
    for (std::uint32_t j = beamStart_[region_[i]]; j < beamStart_[region_[i] + 1]; ++j) {
      const std::uint32_t k = nodeBeams_[j];
      const Beam& beam = beams_[k];
      const std::uint32_t other = beam.a == region_[i] ? beam.b : beam.a;
      if (mark_[other] == inside && other < region_[i]) continue;  // (counted from its other end)
      changed.push_back(k);
      out[k] = beam.active ? beamLoad(beam) : BondLoad{};
    }
}
}  // namespace volpar
