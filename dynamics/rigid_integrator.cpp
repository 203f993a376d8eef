#include "volpar/dynamics/rigid_integrator.hpp"

#include <cmath>

namespace volpar {

namespace {

// rotation by angle about principal axis k
Quat axisRotation(int k, double angle) {
  const double h = 0.5 * angle;
  Quat q(std::cos(h), 0.0, 0.0, 0.0);
  q.coeffs()[k] = std::sin(h);  // coeffs() is (x, y, z, w)
  return q;
}

}  // namespace

void integrateRigidVelocity(BodyState& s, const Vec3& gravity, double dt) {
  if (s.invMass == 0.0) return;
  s.linearVelocity += gravity * dt;
}

void updateWorldInertia(BodyState& s) {
  const Mat3 r = s.orientation.toRotationMatrix();
  s.invInertiaWorld = r * s.invInertiaLocal.asDiagonal() * r.transpose();
}

void integrateRigidPose(BodyState& s, double dt, const Vec3& pseudoLinear, const Vec3& pseudoAngular) {
  if (s.invMass == 0.0) return;
  s.position += (s.linearVelocity + pseudoLinear) * dt;
  const double pseudoAngle = pseudoAngular.norm() * dt;
  if (pseudoAngle > 0.0) {
    // the correction's rotation, about the world axis of the pseudo angular velocity
    const Vec3 wBody = s.orientation.conjugate() * s.angularVelocity;
    s.orientation = (Quat(Eigen::AngleAxisd(pseudoAngle, pseudoAngular.normalized())) * s.orientation).normalized();
    s.angularVelocity = s.orientation * wBody;  // the body keeps spinning about the same body axis
  }

  const Vec3& invI = s.invInertiaLocal;
  if (invI.maxCoeff() - invI.minCoeff() <= 1e-12 * invI.maxCoeff()) {
    // a spherical top (equal moments, to rounding): without torque it turns about its constant angular
    // velocity, exactly
    const double angle = s.angularVelocity.norm() * dt;
    if (angle > 0.0) s.orientation = (Quat(Eigen::AngleAxisd(angle, s.angularVelocity / (angle / dt))) * s.orientation).normalized();
    updateWorldInertia(s);
    return;
  }

  // body-frame angular momentum L_b = I_b w_b (moments are 1 / invInertiaLocal)
  const Vec3 wBody = s.orientation.conjugate() * s.angularVelocity;
  Vec3 lBody(wBody.x() / invI.x(), wBody.y() / invI.y(), wBody.z() / invI.z());

  // symmetric composition of the three exact principal-axis flows
  constexpr int kAxis[5] = {0, 1, 2, 1, 0};
  const double kFraction[5] = {0.5, 0.5, 1.0, 0.5, 0.5};
  Quat q = s.orientation;
  for (int i = 0; i < 5; ++i) {
    const int k = kAxis[i];
    const double angle = kFraction[i] * dt * lBody[k] * invI[k];
    q = q * axisRotation(k, angle);
    lBody = axisRotation(k, -angle) * lBody;
  }
  s.orientation = q.normalized();

  updateWorldInertia(s);
  s.angularVelocity = s.orientation * lBody.cwiseProduct(invI);
}

double rotationalEnergy(const BodyState& s, const Vec3& inertiaLocal) {
  const Vec3 wBody = s.orientation.conjugate() * s.angularVelocity;
  return 0.5 * wBody.dot(inertiaLocal.cwiseProduct(wBody));
}

Vec3 angularMomentum(const BodyState& s, const Vec3& inertiaLocal) {
  const Vec3 wBody = s.orientation.conjugate() * s.angularVelocity;
  return s.orientation * inertiaLocal.cwiseProduct(wBody);
}

}  // namespace volpar
