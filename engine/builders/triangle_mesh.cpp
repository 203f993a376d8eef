#include "volpar/engine/builders/triangle_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>

namespace volpar {

namespace {

Error meshError(const TriangleMesh& m, std::size_t tri, const std::string& message) {
  Error e;
  e.file = m.source;
  e.line = tri < m.triangleLine.size() ? m.triangleLine[tri] : 0;
  e.message = message;
  return e;
}

}  // namespace

Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + (d1 / (d1 - d3)) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + (d2 / (d2 - d6)) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) return b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

Status TriangleMesh::makeSolid() {
  if (triangles.empty()) return Error{source, 0, 0, "mesh has no triangles"};
  const double scale = bounds().diagonal().norm();
  auto vname = [&](std::uint32_t v) {
    return std::to_string(v < vertexNumber.size() ? vertexNumber[v] : static_cast<int>(v) + 1);
  };
  // degenerate triangles
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const auto& tr = triangles[t];
    const double area2 = (vertices[tr[1]] - vertices[tr[0]]).cross(vertices[tr[2]] - vertices[tr[0]]).norm();
    if (tr[0] == tr[1] || tr[1] == tr[2] || tr[0] == tr[2] || !(area2 > 1e-14 * scale * scale))
      return meshError(*this, t, "degenerate triangle (zero area); expected a closed surface of proper triangles");
  }
  // every directed edge once, and its reverse once
  std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> edges;
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const std::uint32_t u = triangles[t][k], v = triangles[t][(k + 1) % 3];
      const auto [it, inserted] = edges.emplace(std::make_pair(u, v), t);
      if (!inserted) {
        const int other = it->second < triangleLine.size() ? triangleLine[it->second] : 0;
        return meshError(*this, t,
                         "edge from vertex " + vname(u) + " to vertex " + vname(v) +
                             " is traversed in the same direction by two triangles (the other at line " +
                             std::to_string(other) +
                             "): the mesh is non-manifold or not consistently oriented; expected a closed, "
                             "consistently oriented surface");
      }
    }
  }
  for (const auto& [e, t] : edges) {
    if (!edges.contains({e.second, e.first}))
      return meshError(*this, t,
                       "mesh is not closed: the edge between vertices " + vname(e.first) + " and " +
                           vname(e.second) + " belongs to only one triangle; expected a closed surface");
  }
  const double vol = volume();
  if (std::abs(vol) <= 1e-12 * scale * scale * scale)
    return Error{source, 0, 0, "mesh encloses no volume; expected a closed solid"};
  if (vol < 0.0)
    for (auto& tr : triangles) std::swap(tr[1], tr[2]);
  return okStatus();
}

bool TriangleMesh::contains(const Vec3& p) const {
  // generalised winding number: sum of signed solid angles (Van Oosterom and Strackee, 1983)
  double omega = 0.0;
  for (const auto& tr : triangles) {
    const Vec3 a = vertices[tr[0]] - p, b = vertices[tr[1]] - p, c = vertices[tr[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    omega += 2.0 * std::atan2(num, den);
  }
  return omega / (4.0 * std::numbers::pi) > 0.5;
}

double TriangleMesh::distance(const Vec3& p) const {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& tr : triangles) {
    const Vec3 q = closestPointOnTriangle(p, vertices[tr[0]], vertices[tr[1]], vertices[tr[2]]);
    best = std::min(best, (q - p).squaredNorm());
  }
  return std::sqrt(best);
}

void TriangleMesh::featureNormals(const Vec3& p, double band, std::vector<Vec3>& out) const {
  out.clear();
  std::vector<std::pair<double, std::size_t>> dist(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t) {
    const auto& tr = triangles[t];
    dist[t] = {(closestPointOnTriangle(p, vertices[tr[0]], vertices[tr[1]], vertices[tr[2]]) - p).norm(), t};
  }
  std::sort(dist.begin(), dist.end());
  const double scale = bounds().diagonal().norm();
  std::vector<double> offsets;
  for (const auto& [d, t] : dist) {
    if (d > dist.front().first + band) break;
    const auto& tr = triangles[t];
    const Vec3 n = (vertices[tr[1]] - vertices[tr[0]]).cross(vertices[tr[2]] - vertices[tr[0]]).normalized();
    const double off = n.dot(vertices[tr[0]]);
    bool seen = false;
    for (std::size_t k = 0; k < out.size() && !seen; ++k)
      seen = (out[k] - n).norm() < 1e-6 && std::abs(offsets[k] - off) < 1e-9 * scale;
    if (seen) continue;
    out.push_back(n);
    offsets.push_back(off);
  }
}

std::vector<std::pair<Vec3, double>> TriangleMesh::convexFacePlanes() const {
  std::vector<std::pair<Vec3, double>> planes;
  const double scale = bounds().diagonal().norm();
  for (const auto& tr : triangles) {
    const Vec3 n = (vertices[tr[1]] - vertices[tr[0]]).cross(vertices[tr[2]] - vertices[tr[0]]).normalized();
    const double d = n.dot(vertices[tr[0]]);
    for (const Vec3& v : vertices)
      if (n.dot(v) > d + 1e-9 * scale) return {};
    const bool seen = std::any_of(planes.begin(), planes.end(), [&](const std::pair<Vec3, double>& p) {
      return (p.first - n).norm() < 1e-9 && std::abs(p.second - d) < 1e-9 * scale;
    });
    if (!seen) planes.emplace_back(n, d);
  }
  return planes;
}

Eigen::AlignedBox3d TriangleMesh::bounds() const {
  Eigen::AlignedBox3d box;
  for (const Vec3& v : vertices) box.extend(v);
  return box;
}

double TriangleMesh::volume() const {
  double v = 0.0;
  for (const auto& tr : triangles) v += vertices[tr[0]].dot(vertices[tr[1]].cross(vertices[tr[2]]));
  return v / 6.0;
}

}  // namespace volpar
