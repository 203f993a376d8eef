#include "volpar/dynamics/breakage.hpp"

#include <algorithm>
#include <numeric>
#include <unordered_map>

namespace volpar {

bool RodForces::build(const BodyInfo& body, const ParticleStore& p, const ConnectorStore& c,
                      std::span<const ConnectorId> rods) {
  rods_.assign(rods.begin(), rods.end());
  if (rods_.empty()) return false;
  const std::size_t n = body.particles.size();
  std::size_t maxId = 0;
  for (const ParticleId q : body.particles) maxId = std::max(maxId, q.index());
  local_.assign(maxId + 1, 0);
  for (std::size_t i = 0; i < n; ++i) local_[body.particles[i].index()] = static_cast<std::uint32_t>(i);
  directions_.clear();
  ends_.clear();
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(rods_.size() * 36 + 3 * n);
  double maxDiag = 0.0;
  Eigen::VectorXd diag = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(3 * n));
  for (const ConnectorId r : rods_) {
    const std::uint32_t a = local_[c.a[r.index()].index()], b = local_[c.b[r.index()].index()];
    const Vec3 e = (p.local[c.b[r.index()].index()] - p.local[c.a[r.index()].index()]).normalized();
    directions_.push_back(e);
    ends_.emplace_back(a, b);
    const Mat3 k = e * e.transpose();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) {
        const auto ai = static_cast<int>(3 * a) + i, aj = static_cast<int>(3 * a) + j;
        const auto bi = static_cast<int>(3 * b) + i, bj = static_cast<int>(3 * b) + j;
        t.emplace_back(ai, aj, k(i, j));
        t.emplace_back(bi, bj, k(i, j));
        t.emplace_back(ai, bj, -k(i, j));
        t.emplace_back(bi, aj, -k(i, j));
      }
    for (int i = 0; i < 3; ++i) {
      diag[3 * a + i] += k(i, i);
      diag[3 * b + i] += k(i, i);
    }
  }
  maxDiag = diag.maxCoeff();
  // the six rigid-body modes (and any mechanism) make K singular; a tiny regularisation picks the solution
  // without rigid motion, and leaves the stretches (hence the forces) of a self-equilibrated load unchanged
  for (std::size_t i = 0; i < 3 * n; ++i) t.emplace_back(static_cast<int>(i), static_cast<int>(i), 1e-9 * maxDiag);
  Eigen::SparseMatrix<double> k(static_cast<Eigen::Index>(3 * n), static_cast<Eigen::Index>(3 * n));
  k.setFromTriplets(t.begin(), t.end());
  ldlt_.compute(k);
  f_.resize(static_cast<Eigen::Index>(3 * n));
  return ldlt_.info() == Eigen::Success;
}

RigidAcceleration rigidAcceleration(const BodyState& s, const BodyInfo& body, const ParticleStore& p,
                                    std::span<const Vec3> loads) {
  Vec3 force = Vec3::Zero(), torque = Vec3::Zero();
  for (const ParticleId q : body.particles) {
    const Vec3 arm = p.position[q.index()] - s.position;
    force += loads[q.index()];
    torque += arm.cross(loads[q.index()]);
  }
  const Mat3 r = s.orientation.toRotationMatrix();
  const Mat3 inertiaWorld = r * body.inertiaLocal.asDiagonal() * r.transpose();
  return {force * s.invMass, s.invInertiaWorld * (torque - s.angularVelocity.cross(inertiaWorld * s.angularVelocity))};
}

void RodForces::solve(const BodyState& s, const BodyInfo& body, const ParticleStore& p, std::span<const Vec3> loads,
                      std::vector<double>& forces) {
  const std::size_t n = body.particles.size();
  const Mat3 r = s.orientation.toRotationMatrix();
  const RigidAcceleration motion = rigidAcceleration(s, body, p, loads);
  // self-equilibrated loads in the body frame
  for (std::size_t i = 0; i < n; ++i) {
    const ParticleId q = body.particles[i];
    const Vec3 inertial = motion.inertialForce(s, p.mass[q.index()], p.position[q.index()] - s.position);
    f_.segment<3>(static_cast<Eigen::Index>(3 * i)) = r.transpose() * (loads[q.index()] - inertial);
  }
  u_ = ldlt_.solve(f_);
  forces.resize(rods_.size());
  for (std::size_t k = 0; k < rods_.size(); ++k) {
    const auto [ia, ib] = ends_[k];
    forces[k] = directions_[k].dot(u_.segment<3>(static_cast<Eigen::Index>(3 * ib)) -
                                   u_.segment<3>(static_cast<Eigen::Index>(3 * ia)));
  }
}

std::size_t connectedComponents(std::span<const ParticleId> particles, const ConnectorStore& c,
                                std::span<const ConnectorId> ids, std::vector<std::uint32_t>& component) {
  const std::size_t n = particles.size();
  std::unordered_map<std::uint32_t, std::uint32_t> local;
  local.reserve(n);
  for (std::size_t i = 0; i < n; ++i) local.emplace(particles[i].value, static_cast<std::uint32_t>(i));
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (const ConnectorId id : ids) {
    if (c.broken[id.index()]) continue;
    const auto ia = local.find(c.a[id.index()].value), ib = local.find(c.b[id.index()].value);
    if (ia == local.end() || ib == local.end()) continue;
    const std::uint32_t x = find(ia->second), y = find(ib->second);
    if (x != y) parent[std::max(x, y)] = std::min(x, y);
  }
  // number the components in order of their first particle
  component.assign(n, 0);
  std::vector<std::uint32_t> number(n, 0xffffffffu);
  std::uint32_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t root = find(static_cast<std::uint32_t>(i));
    if (number[root] == 0xffffffffu) number[root] = count++;
    component[i] = number[root];
  }
  return count;
}

}  // namespace volpar
