#include "dynamics/deformable_integrator.hpp"

#include <cmath>

namespace volpar {

void integrateDeformables(ParticleStore& p, const ConnectorStore& c, const DeformableStepInput& in,
                          std::vector<Vec3>& scratch) {
  if (in.particles.empty()) return;
  const int substeps = std::max(1, in.substeps);
  const double h = in.dt / substeps;
  scratch.resize(p.size());
  if (!in.shift.empty())
    for (const ParticleId id : in.particles) p.position[id.index()] += in.shift[id.index()];
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
    }
    // update velocities
    for (const ParticleId id : in.particles) {
      const std::size_t i = id.index();
      if (p.invMass[i] == 0.0) continue;
      p.velocity[i] = (p.position[i] - scratch[i]) / h;
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
