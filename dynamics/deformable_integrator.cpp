#include "volpar/dynamics/deformable_integrator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace volpar {

namespace {
/// A contact counts as touching while its particles are less than this fraction of their separation apart
/// beyond it.
constexpr double kTouchBand = 0.02;
/// How far beyond the centre-line overlap (a fraction of the separation) the plane model may push a pair:
/// enough for a particle resting in the groove between two or three particles of a cubic or hexagonal
/// lattice face (at most 0.155 there).
constexpr double kPlaneAllowance = 0.25;
}  // namespace

void integrateDeformables(ParticleStore& p, const ConnectorStore& c, const DeformableStepInput& in,
                          DeformableScratch& work) {
  std::vector<Vec3>& scratch = work.previous;
  std::vector<Vec3>& push_ = work.push;
  if (in.particles.empty()) return;
  const int substeps = std::max(1, in.substeps);
  const double h = in.dt / substeps;
  scratch.resize(p.size());
  // per particle: the position correction of this substep's contacts (left out of the velocity); per
  // contact: whether it touches in this substep, and along which normal
  std::vector<std::uint8_t>& touching_ = work.touching;
  std::vector<Vec3>& touchNormal_ = work.touchNormal;
  push_.resize(p.size());
  touching_.resize(in.contacts.size());
  touchNormal_.resize(in.contacts.size());
  for (const ParticleId id : in.particles) push_[id.index()] = Vec3::Zero();
  for (Vec3& j : in.contactImpulses) j = Vec3::Zero();
  for (Vec3& m : in.contactMoments) m = Vec3::Zero();
  const bool moments = !in.contactMoments.empty();
  std::vector<Vec3>& pushed = work.pushed;  // per contact: this substep's position correction of its particle
  pushed.resize(in.contacts.size());
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
      // (projected along the connector as it lay at the start of the substep: the correction, an impulse
      // m dx / h acting where the particles were then, is then central and keeps the angular momentum
      // exactly)
      const Vec3 before = scratch[b] - scratch[a];
      const double beforeLen = before.norm();
      if (len < 1e-15 || beforeLen < 1e-15) continue;
      const Vec3 n = before / beforeLen;
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
        // XPBD's multiplier is an impulse per substep times h: the force is lambda / h^2 (a positive
        // multiplier pushes the ends apart: compression); the largest in magnitude, tension positive
        const double f = c.kind[k] == ConnectorKind::Rod ? -dLambda / (h * h) : c.stiffness[k] * constraint;
        if (std::abs(f) > std::abs(in.forces[k])) in.forces[k] = f;
      }
    }
    // contacts: push particles out. The correction is left out of the velocity (it must not bounce the
    // particle off); instead every touching contact then removes the relative velocity into it
    for (std::size_t k = 0; k < in.contacts.size(); ++k) {
      const DeformableContact& ct = in.contacts[k];
      touching_[k] = 0;
      pushed[k] = Vec3::Zero();
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
        // along the patch's plane (a particle rests on the tops of a lattice face, as in the contact
        // solver), but never by much more than the pair's actual overlap: a pair that has slid sideways in
        // the substeps (its offset no longer along the normal) must not be thrown across
        const Vec3 d = p.position[i] - p.position[ct.other.index()];
        deficit = std::min(ct.separation - n.dot(d), ct.separation * (1.0 + kPlaneAllowance) - d.norm());
      } else {
        deficit = ct.separation - n.dot(p.position[i]);
      }
      // resting within a small band outside the contact still counts as touching (its velocity into the
      // contact is removed below), so a particle at rest on another does not chatter in and out
      if (deficit <= -kTouchBand * ct.separation) continue;
      touching_[k] = 1;
      touchNormal_[k] = n;
      if (deficit <= 0.0) continue;
      const Vec3 dp = n * (deficit * wp / (wp + wo));
      p.position[i] += dp;
      push_[i] += dp;
      pushed[k] = dp;
      if (wo > 0.0) {
        const Vec3 dq = -n * (deficit * wo / (wp + wo));
        p.position[ct.other.index()] += dq;
        push_[ct.other.index()] += dq;
      }
      if (ct.friction <= 0.0) continue;
      // Coulomb friction on this substep's sliding (position-based: the pair's tangential displacement is
      // undone up to friction x the normal correction); it counts towards the velocity, and what it takes
      // from a particle against a rigid body is that body's
      Vec3 moved = p.position[i] - scratch[i];
      if (ct.other.valid()) {
        const std::size_t o = ct.other.index();
        moved -= wo > 0.0 ? Vec3(p.position[o] - scratch[o]) : Vec3(p.velocity[o] * h);
      }
      const Vec3 slide = moved - moved.dot(n) * n;
      const double length = slide.norm();
      if (length < 1e-15) continue;
      const Vec3 undo = slide * std::min(1.0, ct.friction * deficit / length);
      const Vec3 di = -undo * (wp / (wp + wo));
      p.position[i] += di;
      if (wo > 0.0) p.position[ct.other.index()] += undo * (wo / (wp + wo));
      else if (ct.otherFixed && !in.contactImpulses.empty()) {
        // (a position change that counts towards the velocity is an impulse m dx / h where the particle was
        // at the start of the substep)
        in.contactImpulses[k] += p.mass[i] * di / h;
        if (moments) in.contactMoments[k] += scratch[i].cross(p.mass[i] * di / h);
      }
    }
    // update velocities
    for (const ParticleId id : in.particles) {
      const std::size_t i = id.index();
      if (p.invMass[i] == 0.0) continue;
      p.velocity[i] = (p.position[i] - scratch[i] - push_[i]) / h;
      push_[i] = Vec3::Zero();
    }
    // (the moment of momentum the position corrections carried: m dx x v)
    if (moments)
      for (std::size_t k = 0; k < in.contacts.size(); ++k) {
        const DeformableContact& ct = in.contacts[k];
        if (!ct.otherFixed || pushed[k].isZero()) continue;
        const std::size_t i = ct.p.index();
        in.contactMoments[k] += p.mass[i] * pushed[k].cross(p.velocity[i]);
      }
    // touching contacts stop the relative motion into them (inelastic, momentum-conserving; what a rigid
    // body's particle takes is reported so that the body can be given it)
    for (std::size_t k = 0; k < in.contacts.size(); ++k) {
      if (!touching_[k]) continue;
      const DeformableContact& ct = in.contacts[k];
      const std::size_t i = ct.p.index();
      const Vec3& n = touchNormal_[k];
      const double wp = p.invMass[i];
      const bool otherMoves = ct.other.valid() && !ct.otherFixed && p.invMass[ct.other.index()] > 0.0;
      const double wo = otherMoves ? p.invMass[ct.other.index()] : 0.0;
      const Vec3 vo = ct.other.valid() ? p.velocity[ct.other.index()] : Vec3::Zero();
      const double vn = (p.velocity[i] - vo).dot(n);
      if (vn >= 0.0) continue;
      // impulse along n on particle p (and its opposite on the other)
      const double j = -vn / (wp + wo);
      p.velocity[i] += wp * j * n;
      if (otherMoves) p.velocity[ct.other.index()] -= wo * j * n;
      else if (ct.otherFixed && !in.contactImpulses.empty()) {
        in.contactImpulses[k] += j * n;
        if (moments) in.contactMoments[k] += p.position[i].cross(j * n);
      }
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
