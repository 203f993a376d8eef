#include "volpar/engine/builders/shapes.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>

namespace volpar {

namespace {

std::string format(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

double BoxShape::signedDistance(const Vec3& p) const {
  const Vec3 q = p.cwiseAbs() - half_;
  const double outside = q.cwiseMax(0.0).norm();
  const double inside = std::min(q.maxCoeff(), 0.0);
  return outside + inside;
}

void BoxShape::featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const {
  // the six faces by distance; keep those within band of the nearest
  std::array<std::pair<double, int>, 6> faces;
  for (int k = 0; k < 3; ++k) {
    faces[static_cast<std::size_t>(2 * k)] = {half_[k] - p[k], 2 * k};          // +k face
    faces[static_cast<std::size_t>(2 * k + 1)] = {half_[k] + p[k], 2 * k + 1};  // -k face
  }
  std::sort(faces.begin(), faces.end());
  out.clear();
  for (const auto& [d, f] : faces)
    if (d <= faces[0].first + band) out.push_back((f % 2 == 0 ? 1.0 : -1.0) * Vec3::Unit(f / 2));
}

std::string BoxShape::describe() const {
  return "box " + format(2 * half_.x()) + " x " + format(2 * half_.y()) + " x " + format(2 * half_.z()) + " m";
}

void SphereShape::featureNormals(const Vec3& p, double /*band*/, std::vector<Vec3>& out) const {
  out.clear();
  if (p.norm() > 1e-12 * radius_) out.push_back(p.normalized());
}

SolidMass BoxShape::massProperties() const {
  SolidMass m;
  m.volume = volume();
  const Vec3 sq = (2.0 * half_).cwiseAbs2();
  m.inertia.diagonal() = m.volume / 12.0 * Vec3(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
  return m;
}

double SphereShape::volume() const { return 4.0 / 3.0 * std::numbers::pi * radius_ * radius_ * radius_; }

SolidMass SphereShape::massProperties() const {
  SolidMass m;
  m.volume = volume();
  m.inertia.diagonal().setConstant(0.4 * m.volume * radius_ * radius_);
  return m;
}

std::string SphereShape::describe() const { return "sphere of radius " + format(radius_) + " m"; }

double CylinderShape::signedDistance(const Vec3& p) const {
  const double dr = std::hypot(p.x(), p.y()) - radius_;
  const double dz = std::abs(p.z()) - halfHeight_;
  const double outside = std::hypot(std::max(dr, 0.0), std::max(dz, 0.0));
  return outside + std::min(std::max(dr, dz), 0.0);
}

void CylinderShape::featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const {
  // side, top cap, bottom cap by distance; keep those within band of the nearest
  const double rho = std::hypot(p.x(), p.y());
  std::array<std::pair<double, int>, 3> features{{{radius_ - rho, 0}, {halfHeight_ - p.z(), 1}, {halfHeight_ + p.z(), 2}}};
  std::sort(features.begin(), features.end());
  out.clear();
  for (const auto& [d, f] : features) {
    if (d > features[0].first + band) continue;
    if (f == 0 && rho > 1e-12 * radius_) out.emplace_back(p.x() / rho, p.y() / rho, 0.0);
    if (f == 1) out.push_back(Vec3::UnitZ());
    if (f == 2) out.push_back(-Vec3::UnitZ());
  }
}

double CylinderShape::volume() const { return std::numbers::pi * radius_ * radius_ * 2.0 * halfHeight_; }

SolidMass CylinderShape::massProperties() const {
  SolidMass m;
  m.volume = volume();
  const double r2 = radius_ * radius_, h = 2.0 * halfHeight_;
  const double across = m.volume * (3.0 * r2 + h * h) / 12.0;
  m.inertia.diagonal() = Vec3(across, across, 0.5 * m.volume * r2);
  return m;
}

std::string CylinderShape::describe() const {
  return "cylinder of radius " + format(radius_) + " m and height " + format(2 * halfHeight_) + " m";
}

double CapsuleShape::signedDistance(const Vec3& p) const {
  const Vec3 axisPoint(0.0, 0.0, std::clamp(p.z(), -halfLength_, halfLength_));
  return (p - axisPoint).norm() - radius_;
}

void CapsuleShape::featureNormals(const Vec3& p, double /*band*/, std::vector<Vec3>& out) const {
  out.clear();
  const Vec3 axisPoint(0.0, 0.0, std::clamp(p.z(), -halfLength_, halfLength_));
  if ((p - axisPoint).norm() > 1e-12 * radius_) out.push_back((p - axisPoint).normalized());
}

double CapsuleShape::volume() const {
  const double r = radius_;
  return std::numbers::pi * r * r * (2.0 * halfLength_ + 4.0 / 3.0 * r);
}

SolidMass CapsuleShape::massProperties() const {
  // the cylinder between the caps, and two hemispheres whose own centroids lie 3 r / 8 beyond its ends
  SolidMass m;
  m.volume = volume();
  const double r = radius_, r2 = r * r, l = 2.0 * halfLength_;
  const double cylinder = std::numbers::pi * r2 * l;
  const double hemisphere = 2.0 / 3.0 * std::numbers::pi * r2 * r;
  const double offset = halfLength_ + 0.375 * r;
  const double across =
      cylinder * (3.0 * r2 + l * l) / 12.0 + 2.0 * hemisphere * (83.0 / 320.0 * r2 + offset * offset);
  const double along = 0.5 * cylinder * r2 + 2.0 * 0.4 * hemisphere * r2;
  m.inertia.diagonal() = Vec3(across, across, along);
  return m;
}

std::string CapsuleShape::describe() const {
  return "capsule of radius " + format(radius_) + " m and segment length " + format(2 * halfLength_) + " m";
}

SolidMass MeshShape::massProperties() const {
  // tetrahedra from the origin to each triangle: sum of their volumes, first and second moments
  SolidMass m;
  Vec3 first = Vec3::Zero();
  Mat3 second = Mat3::Zero();  // integral of x x^T
  for (const auto& tr : mesh_->triangles) {
    const Vec3& a = mesh_->vertices[tr[0]];
    const Vec3& b = mesh_->vertices[tr[1]];
    const Vec3& c = mesh_->vertices[tr[2]];
    const double v = a.dot(b.cross(c)) / 6.0;
    const Vec3 sum = a + b + c;
    m.volume += v;
    first += v / 4.0 * sum;
    second += v / 20.0 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + sum * sum.transpose());
  }
  if (!(m.volume > 0.0)) return m;
  m.centroid = first / m.volume;
  const Mat3 central = second - m.volume * m.centroid * m.centroid.transpose();
  m.inertia = central.trace() * Mat3::Identity() - central;
  return m;
}

double MeshShape::signedDistance(const Vec3& p) const {
  const double d = mesh_->distance(p);
  return mesh_->contains(p) ? -d : d;
}

void MeshShape::featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const {
  mesh_->featureNormals(p, band, out);
}

std::string MeshShape::describe() const {
  return "mesh with " + std::to_string(mesh_->triangles.size()) + " triangles";
}

}  // namespace volpar
