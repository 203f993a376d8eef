#include "dynamics/deformable_integrator.hpp"

#include <algorithm>
#include <cmath>

namespace volpar {

void integrateDeformables(ParticleStore& p, const ConnectorStore& c, const DeformableStepInput& in,
                          DeformableScratch& work) {
  std::vector<Vec3>& scratch = work.previous;
  std::vector<Vec3>& push_ = work.push;
  std::vector<Vec3>& pushNormal_ = work.pushNormal;
  if (in.particles.empty()) return;
  const int substeps = std::max(1, in.substeps);
  const double h = in.dt / substeps;
  scratch.resize(p.size());
  // per particle: the position correction of this substep's contacts (left out of the velocity) and the
  // direction of its last active contact (along which inward velocity is removed)
  std::vector<std::int32_t>& pushContact_ = work.pushContact;
  push_.resize(p.size());
  pushNormal_.resize(p.size());
  pushContact_.resize(p.size());
  for (const ParticleId id : in.particles) {
    push_[id.index()] = Vec3::Zero();
    pushNormal_[id.index()] = Vec3::Zero();
    pushContact_[id.index()] = -1;
  }
  for (Vec3& j : in.contactImpulses) j = Vec3::Zero();
  if (!in.shift.empty())
    for (const ParticleId id : in.particles) p.position[id.index()] += in.shift[id.index()];
  if (!in.forces.empty())
    for (const ConnectorId cid : in.connectors) in.forces[cid.index()] = 0.0;
  for (int sub = 0; sub < substeps; ++sub) {
    // predict
    for (const ParticleId id : in.particles) {
      const std::size_t i = id.index();
      scratch[i] = p.position[i];
      if (p.invMass[i] == 0.0) continue;
      if (!in.gravity.isZero()) p.velocity[i] += in.gravity * h;
      p.position[i] += p.velocity[i] * h;
    }
    // project each connector once (Gauss-Seidel, fixed order)
    for (const ConnectorId cid : in.connectors) {
      const std::size_t k = cid.index();
      if (c.broken[k]) continue;
      const std::size_t a = c.a[k].index();
      const std::size_t b = c.b[k].index();
      const double wa = p.invMass[a];
      const double wb = p.invMass[b];
      if (wa + wb == 0.0) continue;
      const Vec3 d = p.position[b] - p.position[a];
      const double len = d.norm();
      if (len < 1e-15) continue;
      const Vec3 n = d / len;
      const double constraint = len - c.restLength[k];
      double alphaTilde = 0.0;
      double gamma = 0.0;
      if (c.kind[k] == ConnectorKind::Spring && c.stiffness[k] > 0.0) {
        const double alpha = 1.0 / c.stiffness[k];
        alphaTilde = alpha / (h * h);
        gamma = alpha * c.damping[k] / h;  // alpha~ * beta~ / h with beta~ = h^2 * damping
      }
      // dC/dt * h along the connector, from this substep's displacement
      const double approach = n.dot((p.position[b] - scratch[b]) - (p.position[a] - scratch[a]));
      const double dLambda = (-constraint - gamma * approach) / ((1.0 + gamma) * (wa + wb) + alphaTilde);
      p.position[a] -= wa * dLambda * n;
      p.position[b] += wb * dLambda * n;
      if (!in.forces.empty()) {
        // XPBD's multiplier is an impulse per substep times h: the force is lambda / h^2
        const double f = c.kind[k] == ConnectorKind::Rod ? std::abs(dLambda) / (h * h) : c.stiffness[k] * std::abs(constraint);
        in.forces[k] = std::max(in.forces[k], f);
      }
    }
    // contacts: push particles out. The correction is left out of the velocity (it must not bounce the
    // particle off), and the velocity into the contact is removed (a particle held up must not keep falling)
    for (std::size_t k = 0; k < in.contacts.size(); ++k) {
      const DeformableContact& ct = in.contacts[k];
      const std::size_t i = ct.p.index();
      const double wp = p.invMass[i];
      const double wo = ct.other.valid() && !ct.otherFixed ? p.invMass[ct.other.index()] : 0.0;
      if (wp + wo == 0.0) continue;
      Vec3 n = ct.normal;
      double deficit;
      if (ct.other.valid() && ct.centreLine) {
        // the sphere-sphere constraint along the current centre line
        const Vec3 d = p.position[i] - p.position[ct.other.index()];
        const double len = d.norm();
        if (len > 1e-12) n = d / len;
        deficit = ct.separation - len;
      } else if (ct.other.valid()) {
        // along the patch's plane, but never by more than the pair's actual overlap: a pair that has slid
        // sideways in the substeps (its offset no longer along the normal) must not be thrown across
        const Vec3 d = p.position[i] - p.position[ct.other.index()];
        deficit = std::min(ct.separation - n.dot(d), ct.separation - d.norm());
      } else {
        deficit = ct.separation - n.dot(p.position[i]);
      }
      if (deficit <= 0.0) continue;
      const Vec3 dp = n * (deficit * wp / (wp + wo));
      p.position[i] += dp;
      push_[i] += dp;
      pushNormal_[i] = n;
      pushContact_[i] = ct.otherFixed ? static_cast<std::int32_t>(k) : -1;
      if (ct.other.valid() && wo > 0.0) {
        const Vec3 dq = -n * (deficit * wo / (wp + wo));
        p.position[ct.other.index()] += dq;
        push_[ct.other.index()] += dq;
        pushNormal_[ct.other.index()] = -n;
        pushContact_[ct.other.index()] = -1;
      }
    }
    // update velocities
    for (const ParticleId id : in.particles) {
      const std::size_t i = id.index();
      if (p.invMass[i] == 0.0) continue;
      p.velocity[i] = (p.position[i] - scratch[i] - push_[i]) / h;
      const double vn = p.velocity[i].dot(pushNormal_[i]);
      if (vn < 0.0) {
        p.velocity[i] -= vn * pushNormal_[i];
        if (pushContact_[i] >= 0 && !in.contactImpulses.empty())
          in.contactImpulses[static_cast<std::size_t>(pushContact_[i])] -= p.mass[i] * vn * pushNormal_[i];
      }
      push_[i] = Vec3::Zero();
      pushNormal_[i] = Vec3::Zero();
      pushContact_[i] = -1;
    }
  }
}

double springEnergy(const ParticleStore& p, const ConnectorStore& c, std::span<const ConnectorId> ids) {
  double e = 0.0;
  for (const ConnectorId cid : ids) {
    const std::size_t k = cid.index();
    if (c.kind[k] != ConnectorKind::Spring || c.broken[k]) continue;
    const double stretch = (p.position[c.b[k].index()] - p.position[c.a[k].index()]).norm() - c.restLength[k];
    e += 0.5 * c.stiffness[k] * stretch * stretch;
  }
  return e;
}

}  // namespace volpar
