#include "volpar/engine/builders/fill.hpp"

#include <cmath>
#include <numbers>
#include <set>
#include <sstream>

#include "volpar/collision/normal_estimation.hpp"
#include "volpar/collision/particle_grid.hpp"

namespace volpar {

namespace {

using Index3 = std::array<long, 3>;

Vec3 siteOffset(Lattice lattice, double s, const Index3& ijk) { return latticeSite(lattice, s, ijk); }

}  // namespace

Vec3 latticeSite(Lattice lattice, double s, const std::array<long, 3>& ijk) {
  if (lattice == Lattice::Cubic) return Vec3(ijk[0] * s, ijk[1] * s, ijk[2] * s);
  const double r = 0.5 * s;
  const long jk = ((ijk[1] + ijk[2]) % 2 + 2) % 2;
  const long k2 = (ijk[2] % 2 + 2) % 2;
  return Vec3((2.0 * ijk[0] + jk) * r, std::sqrt(3.0) * (ijk[1] + k2 / 3.0) * r, 2.0 * std::sqrt(6.0) / 3.0 * ijk[2] * r);
}

namespace {

std::string format(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace

double latticeCellVolume(Lattice lattice, double spacing) {
  const double s3 = spacing * spacing * spacing;
  return lattice == Lattice::Cubic ? s3 : s3 / std::numbers::sqrt2;
}

std::vector<std::array<std::uint32_t, 2>> connectWithin(std::span<const Vec3> points, double reach) {
  std::vector<std::array<std::uint32_t, 2>> out;
  if (points.empty() || !(reach > 0.0)) return out;
  ParticleGrid grid;
  grid.build(points, reach);
  for (const auto& [i, j] : grid.pairsWithin(reach)) out.push_back({i, j});
  return out;
}

Result<ParticleCloud> fillShape(const SolidShape& shape, const FillSettings& settings) {
  const double r = settings.radius;
  const double s = settings.spacing > 0.0 ? settings.spacing : 2.0 * r;
  const double tol = 1e-9 * s;
  const Eigen::AlignedBox3d box = shape.bounds();
  const Vec3 extent = box.sizes();

  // anchor and index range: cubic symmetric in the bounds, HCP centred on the shape's centre
  Vec3 anchor;
  Index3 lo{}, hi{};
  if (settings.lattice == Lattice::Cubic) {
    for (int k = 0; k < 3; ++k) {
      const double usable = extent[k] - 2.0 * r;
      const long n = usable < -tol ? 0 : static_cast<long>(std::floor(usable / s + 1e-9)) + 1;
      anchor[k] = box.center()[k] - 0.5 * static_cast<double>(n - 1) * s;
      lo[k] = 0;
      hi[k] = n - 1;
    }
  } else {
    anchor = box.center();
    const double dz = 2.0 * std::sqrt(6.0) / 3.0 * 0.5 * s;
    const double dy = std::sqrt(3.0) * 0.5 * s;
    const Vec3 step(s, dy, dz);
    for (int k = 0; k < 3; ++k) {
      const long n = static_cast<long>(std::ceil(0.5 * extent[k] / step[k])) + 1;
      lo[k] = -n;
      hi[k] = n;
    }
  }

  auto fits = [&](const Vec3& p) { return shape.signedDistance(p) <= -r + tol; };

  // keep the sites whose spheres lie inside the shape
  std::vector<Index3> kept;
  std::set<Index3> keptSet;
  for (long k = lo[2]; k <= hi[2]; ++k)
    for (long j = lo[1]; j <= hi[1]; ++j)
      for (long i = lo[0]; i <= hi[0]; ++i) {
        const Index3 ijk{i, j, k};
        if (fits(anchor + siteOffset(settings.lattice, s, ijk))) {
          kept.push_back(ijk);
          keptSet.insert(ijk);
        }
      }
  if (kept.empty())
    return Error{"", 0, 0,
                 "no particle of radius " + format(r) + " m fits inside the " + shape.describe() +
                     "; expected a smaller radius or a larger shape"};

  // nearest-neighbour index offsets of this lattice (for HCP they depend on the layer, so test by distance)
  ParticleCloud cloud;
  cloud.spacing = s;
  // the shape's exact volume, shared evenly: the body gets exactly density x volume
  const double cell = shape.volume() / static_cast<double>(kept.size());
  const double band = 0.5 * s;
  // the second moment of a lattice cell per unit mass: a cube of side s; HCP's cell (a trapezo-rhombic
  // dodecahedron) has that of FCC's rhombic dodecahedron, s^2 / 8
  const double ownInertia = (settings.lattice == Lattice::Cubic ? 1.0 / 6.0 : 1.0 / 8.0) * s * s;
  cloud.solid = shape.massProperties();
  cloud.solidSize = extent;
  std::vector<Vec3> missing, present, features;
  for (const Index3& ijk : kept) {
    const Vec3 p = anchor + siteOffset(settings.lattice, s, ijk);
    missing.clear();
    present.clear();
    for (long dk = -1; dk <= 1; ++dk)
      for (long dj = -2; dj <= 2; ++dj)
        for (long di = -2; di <= 2; ++di) {
          const Index3 nb{ijk[0] + di, ijk[1] + dj, ijk[2] + dk};
          const Vec3 q = anchor + siteOffset(settings.lattice, s, nb);
          const double d = (q - p).norm();
          if (!(d > 0.5 * s && d < 1.01 * s)) continue;
          (keptSet.contains(nb) ? present : missing).push_back((q - p) / d);
        }
    // the features of the shape facing a missing neighbour
    std::uint8_t flags = 0;
    Vec3 normal = Vec3::Zero();
    std::array<Vec3, 3> faces{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
    int used = 0;
    if (!missing.empty()) {
      flags = kParticleSurface;
      std::vector<Vec3> facing;
      shape.featureNormals(p, band, features);
      for (const Vec3& n : features) {
        double top = -1.0;
        for (const Vec3& o : missing) top = std::max(top, n.dot(o));
        if (top > 0.5) facing.push_back(n);
      }
      if (facing.empty() && !features.empty()) facing.push_back(features.front());  // nearest feature
      // two opposite faces both open: a layer one particle thick (a sheet), each side a face of its own
      std::size_t first = facing.size(), second = facing.size();
      for (std::size_t a = 0; a < facing.size() && first == facing.size(); ++a)
        for (std::size_t b = a + 1; b < facing.size(); ++b)
          if (facing[a].dot(facing[b]) < -0.9) {
            first = a;
            second = b;
            break;
          }
      // neighbours on both sides of the site along one line: a chain one particle thick (a site with a single
      // neighbour is the tip of a solid, not of a chain)
      bool line = present.size() >= 2;
      for (const Vec3& d : present) line = line && std::abs(std::abs(d.dot(present.front())) - 1.0) < 1e-9;
      if (present.empty()) {
        // a lone site: surface, no preferred direction
      } else if (line) {
        flags |= kParticleLine;
        normal = present.front();
      } else if (first < facing.size()) {
        flags |= kParticleSheet;
        faces[0] = facing[first];
        faces[1] = facing[second];
        normal = faces[0];
        used = 2;
        for (std::size_t k = 0; k < facing.size() && used < 3; ++k) {
          if (k == first || k == second) continue;
          faces[2] = facing[k];  // the rim of the sheet
          normal = facing[k];
          flags |= kParticleEdge;
          used = 3;
        }
      } else {
        for (const Vec3& n : facing) {
          normal += n;
          if (used < 3) faces[static_cast<std::size_t>(used)] = n;
          ++used;
        }
        if (normal.norm() > 1e-9) normal.normalize();
        if (used == 2) flags |= kParticleEdge;
        if (used >= 3) flags |= kParticleCorner;
      }
    }
    cloud.positions.push_back(p);
    cloud.radii.push_back(r);
    cloud.volumes.push_back(cell);
    cloud.ownInertia.push_back(ownInertia);
    cloud.flags.push_back(flags);
    cloud.normals.push_back(normal);
    cloud.features.push_back(static_cast<std::uint8_t>(std::min(used, 3)));
    cloud.featureNormals.push_back(faces);
  }
  cloud.connectors = connectWithin(cloud.positions, settings.reach * s);
  return cloud;
}

void useEstimatedNormals(ParticleCloud& cloud) {
  const std::vector<SurfaceEstimate> est = estimateSurface(cloud.positions, cloud.connectors);
  const std::size_t n = cloud.size();
  cloud.flags.resize(n);
  cloud.normals.resize(n);
  cloud.features.resize(n);
  cloud.featureNormals.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    cloud.flags[i] = est[i].flags;
    cloud.normals[i] = est[i].normal;
    cloud.features[i] = est[i].faceCount;
    cloud.featureNormals[i] = est[i].faces;
  }
}

Result<ParticleCloud> buildParticleList(const ParticleListSettings& in) {
  ParticleCloud cloud;
  const std::size_t n = in.positions.size();
  if (n == 0) return Error{"", 0, 0, "expected at least one particle"};
  if (in.radii.size() != 1 && in.radii.size() != n)
    return Error{"", 0, 0,
                 "expected one radius for all particles or one per particle (" + std::to_string(n) + "), got " +
                     std::to_string(in.radii.size())};
  double maxRadius = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double r = in.radii.size() == 1 ? in.radii[0] : in.radii[i];
    maxRadius = std::max(maxRadius, r);
    cloud.positions.push_back(in.positions[i]);
    cloud.radii.push_back(r);
    cloud.volumes.push_back(4.0 / 3.0 * std::numbers::pi * r * r * r);
    cloud.ownInertia.push_back(0.4 * r * r);
  }
  if (in.explicitConnectors) {
    std::set<std::array<std::uint32_t, 2>> seen;
    for (std::size_t c = 0; c < in.connectors.size(); ++c) {
      auto [i, j] = in.connectors[c];
      if (i >= n || j >= n)
        return Error{"", 0, 0,
                     "connector " + std::to_string(c) + " refers to particle " + std::to_string(std::max(i, j)) +
                         "; expected indices below " + std::to_string(n)};
      if (i == j) return Error{"", 0, 0, "connector " + std::to_string(c) + " joins particle " + std::to_string(i) + " to itself"};
      if (i > j) std::swap(i, j);
      if (!seen.insert({i, j}).second)
        return Error{"", 0, 0,
                     "connector " + std::to_string(c) + " repeats the pair (" + std::to_string(i) + ", " +
                         std::to_string(j) + ")"};
    }
    cloud.connectors.assign(seen.begin(), seen.end());
  } else {
    const double reach = in.reach > 0.0 ? in.reach : 3.0 * maxRadius;
    cloud.connectors = connectWithin(cloud.positions, reach);
  }
  useEstimatedNormals(cloud);
  return cloud;
}

}  // namespace volpar
