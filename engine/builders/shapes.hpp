#pragma once
// Solid shapes that builders fill with particles. Primitives are centred at the origin of their shape
// frame; meshes keep their file's coordinates. signedDistance is negative inside; featureNormals gives the
// exact outward normals of the surface features (faces, the curved side) within `band` of the nearest
// one, from which the builder picks those facing a missing lattice neighbour (fill.hpp).

#include <memory>
#include <string>
#include <vector>

#include "volpar/engine/builders/solid_mass.hpp"
#include "volpar/engine/builders/triangle_mesh.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

class SolidShape {
 public:
  virtual ~SolidShape() = default;
  /// Signed distance to the surface [m], negative inside.
  [[nodiscard]] virtual double signedDistance(const Vec3& p) const = 0;
  /// Unit outward normals of the features within `band` [m] of the nearest one to p, nearest first.
  /// Smooth shapes give one normal (none where it is undefined, e.g. a sphere's centre).
  virtual void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const = 0;
  /// Axis-aligned bounds in the shape frame [m].
  [[nodiscard]] virtual Eigen::AlignedBox3d bounds() const = 0;
  /// Exact volume [m^3].
  [[nodiscard]] virtual double volume() const = 0;
  /// Exact mass properties at unit density.
  [[nodiscard]] virtual SolidMass massProperties() const = 0;
  /// Short description for messages, e.g. "box 0.3 x 0.3 x 0.3 m".
  [[nodiscard]] virtual std::string describe() const = 0;
};

/// Box of full side lengths `size` [m].
class BoxShape final : public SolidShape {
 public:
  explicit BoxShape(const Vec3& size) : half_(0.5 * size) {}
  double signedDistance(const Vec3& p) const override;
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const override;
  Eigen::AlignedBox3d bounds() const override { return {-half_, half_}; }
  double volume() const override { return 8.0 * half_.prod(); }
  SolidMass massProperties() const override;
  std::string describe() const override;

 private:
  Vec3 half_;
};

/// Sphere of radius `radius` [m].
class SphereShape final : public SolidShape {
 public:
  explicit SphereShape(double radius) : radius_(radius) {}
  double signedDistance(const Vec3& p) const override { return p.norm() - radius_; }
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const override;
  Eigen::AlignedBox3d bounds() const override { return {Vec3::Constant(-radius_), Vec3::Constant(radius_)}; }
  double volume() const override;
  SolidMass massProperties() const override;
  std::string describe() const override;

 private:
  double radius_;
};

/// Cylinder of radius `radius` and total height `height` [m], axis along shape z.
class CylinderShape final : public SolidShape {
 public:
  CylinderShape(double radius, double height) : radius_(radius), halfHeight_(0.5 * height) {}
  double signedDistance(const Vec3& p) const override;
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const override;
  Eigen::AlignedBox3d bounds() const override {
    return {Vec3(-radius_, -radius_, -halfHeight_), Vec3(radius_, radius_, halfHeight_)};
  }
  double volume() const override;
  SolidMass massProperties() const override;
  std::string describe() const override;

 private:
  double radius_;
  double halfHeight_;
};

/// Capsule: the points within `radius` of a segment of length `length` along shape z [m].
/// Total length is length + 2 radius (the FCL convention).
class CapsuleShape final : public SolidShape {
 public:
  CapsuleShape(double radius, double length) : radius_(radius), halfLength_(0.5 * length) {}
  double signedDistance(const Vec3& p) const override;
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const override;
  Eigen::AlignedBox3d bounds() const override {
    return {Vec3(-radius_, -radius_, -halfLength_ - radius_), Vec3(radius_, radius_, halfLength_ + radius_)};
  }
  double volume() const override;
  SolidMass massProperties() const override;
  std::string describe() const override;

 private:
  double radius_;
  double halfLength_;
};

/// A closed, consistently oriented triangle mesh (see TriangleMesh::validate).
class MeshShape final : public SolidShape {
 public:
  explicit MeshShape(std::shared_ptr<const TriangleMesh> mesh) : mesh_(std::move(mesh)) {}
  double signedDistance(const Vec3& p) const override;
  void featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const override;
  Eigen::AlignedBox3d bounds() const override { return mesh_->bounds(); }
  double volume() const override { return mesh_->volume(); }
  SolidMass massProperties() const override;
  std::string describe() const override;

 private:
  std::shared_ptr<const TriangleMesh> mesh_;
};

}  // namespace volpar
