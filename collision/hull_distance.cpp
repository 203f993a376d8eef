#include "volpar/collision/hull_distance.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace volpar {

namespace {

/// A simplex of the Minkowski difference: vertices w = b[ib] - a[ia] with barycentric weights.
struct Simplex {
  std::array<Vec3, 4> w{Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};
  std::array<std::uint32_t, 4> ia{}, ib{};
  std::array<double, 4> lambda{};
  int n = 0;

  void keep(std::initializer_list<int> which, std::initializer_list<double> weights) {
    Simplex r;
    auto wt = weights.begin();
    for (const int k : which) {
      r.w[static_cast<std::size_t>(r.n)] = w[static_cast<std::size_t>(k)];
      r.ia[static_cast<std::size_t>(r.n)] = ia[static_cast<std::size_t>(k)];
      r.ib[static_cast<std::size_t>(r.n)] = ib[static_cast<std::size_t>(k)];
      r.lambda[static_cast<std::size_t>(r.n)] = *wt++;
      ++r.n;
    }
    *this = r;
  }
  [[nodiscard]] Vec3 point() const {
    Vec3 v = Vec3::Zero();
    for (int k = 0; k < n; ++k) v += lambda[static_cast<std::size_t>(k)] * w[static_cast<std::size_t>(k)];
    return v;
  }
};

/// Closest point to the origin on segment (w[i], w[j]) of s, as (weights, squared distance).
struct Candidate {
  std::array<int, 3> which{};
  std::array<double, 3> weight{};
  int n = 0;
  double dist2 = std::numeric_limits<double>::infinity();
};

Candidate segment(const Simplex& s, int i, int j) {
  const Vec3& p = s.w[static_cast<std::size_t>(i)];
  const Vec3& q = s.w[static_cast<std::size_t>(j)];
  const Vec3 d = q - p;
  const double dd = d.squaredNorm();
  Candidate c;
  const double t = dd > 0.0 ? -p.dot(d) / dd : 0.0;
  if (t <= 0.0) {
    c.which = {i, 0, 0};
    c.weight = {1.0, 0.0, 0.0};
    c.n = 1;
    c.dist2 = p.squaredNorm();
  } else if (t >= 1.0) {
    c.which = {j, 0, 0};
    c.weight = {1.0, 0.0, 0.0};
    c.n = 1;
    c.dist2 = q.squaredNorm();
  } else {
    c.which = {i, j, 0};
    c.weight = {1.0 - t, t, 0.0};
    c.n = 2;
    c.dist2 = (p + t * d).squaredNorm();
  }
  return c;
}

/// Closest point to the origin on triangle (w[i], w[j], w[k]) of s (Ericson 5.1.5); a degenerate
/// (collinear) triangle is treated as its best edge.
Candidate triangle(const Simplex& s, int i, int j, int k) {
  const Vec3& a = s.w[static_cast<std::size_t>(i)];
  const Vec3& b = s.w[static_cast<std::size_t>(j)];
  const Vec3& c = s.w[static_cast<std::size_t>(k)];
  const Vec3 ab = b - a, ac = c - a;
  const double scale = std::max(ab.squaredNorm(), ac.squaredNorm());
  if (!(ab.cross(ac).squaredNorm() > 1e-20 * scale * scale)) {
    Candidate best = segment(s, i, j);
    for (const Candidate& e : {segment(s, j, k), segment(s, i, k)})
      if (e.dist2 < best.dist2) best = e;
    return best;
  }
  Candidate out;
  const auto vertex = [&](int v, const Vec3& x) {
    out.which = {v, 0, 0};
    out.weight = {1.0, 0.0, 0.0};
    out.n = 1;
    out.dist2 = x.squaredNorm();
    return out;
  };
  const auto edge = [&](int u, int v, const Vec3& x, const Vec3& y, double t) {
    out.which = {u, v, 0};
    out.weight = {1.0 - t, t, 0.0};
    out.n = 2;
    out.dist2 = (x + t * (y - x)).squaredNorm();
    return out;
  };
  const Vec3 ap = -a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return vertex(i, a);
  const Vec3 bp = -b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return vertex(j, b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return edge(i, j, a, b, d1 / (d1 - d3));
  const Vec3 cp = -c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return vertex(k, c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return edge(i, k, a, c, d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) return edge(j, k, b, c, (d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  out.which = {i, j, k};
  out.weight = {1.0 - v - w, v, w};
  out.n = 3;
  out.dist2 = (a + v * ab + w * ac).squaredNorm();
  return out;
}

void apply(Simplex& s, const Candidate& c) {
  if (c.n == 1) s.keep({c.which[0]}, {c.weight[0]});
  else if (c.n == 2) s.keep({c.which[0], c.which[1]}, {c.weight[0], c.weight[1]});
  else s.keep({c.which[0], c.which[1], c.which[2]}, {c.weight[0], c.weight[1], c.weight[2]});
}

/// Moves s to the face of least dimension holding its closest point to the origin; false when the origin is
/// inside a (non-degenerate) tetrahedron.
bool reduce(Simplex& s) {
  switch (s.n) {
    case 1: s.lambda[0] = 1.0; return true;
    case 2: apply(s, segment(s, 0, 1)); return true;
    case 3: apply(s, triangle(s, 0, 1, 2)); return true;
    default: break;
  }
  // tetrahedron (Ericson 5.1.6): the faces whose plane has the origin outside; all of them when the
  // tetrahedron is flat
  const Vec3& a = s.w[0];
  const Vec3& b = s.w[1];
  const Vec3& c = s.w[2];
  const Vec3& d = s.w[3];
  const double volume = (b - a).cross(c - a).dot(d - a);
  const double scale = std::max({(b - a).norm(), (c - a).norm(), (d - a).norm()});
  const bool flat = !(std::abs(volume) > 1e-12 * scale * scale * scale);
  const auto outside = [&](const Vec3& p, const Vec3& q, const Vec3& r, const Vec3& opposite) {
    const Vec3 n = (q - p).cross(r - p);
    return flat || n.dot(-p) * n.dot(opposite - p) < 0.0;
  };
  Candidate best;
  bool any = false;
  const auto consider = [&](int i, int j, int k, int opposite) {
    if (!outside(s.w[static_cast<std::size_t>(i)], s.w[static_cast<std::size_t>(j)], s.w[static_cast<std::size_t>(k)],
                 s.w[static_cast<std::size_t>(opposite)]))
      return;
    const Candidate t = triangle(s, i, j, k);
    if (!any || t.dist2 < best.dist2) best = t;
    any = true;
  };
  consider(0, 1, 2, 3);
  consider(0, 2, 3, 1);
  consider(0, 3, 1, 2);
  consider(1, 3, 2, 0);
  if (!any) return false;
  apply(s, best);
  return true;
}

}  // namespace

HullDistance hullDistance(std::span<const Vec3> a, std::span<const Vec3> b) {
  HullDistance out;
  if (a.empty() || b.empty()) return out;
  double scale = 0.0;
  for (const Vec3& x : a) scale = std::max(scale, (x - a[0]).squaredNorm());
  for (const Vec3& x : b) scale = std::max(scale, (x - a[0]).squaredNorm());
  const double tiny = 1e-24 * std::max(scale, 1e-300);

  Simplex s;
  s.n = 1;
  s.w[0] = b[0] - a[0];
  s.lambda[0] = 1.0;
  Vec3 v = s.w[0];
  bool touching = false;
  for (int it = 0; it < 64; ++it) {
    out.iterations = it + 1;
    const double vv = v.squaredNorm();
    if (vv <= tiny) {
      touching = true;
      break;
    }
    // support of B - A in direction -v: B's point least along v, A's point farthest along it
    std::uint32_t ia = 0, ib = 0;
    double bestA = a[0].dot(v), bestB = b[0].dot(v);
    for (std::uint32_t i = 1; i < a.size(); ++i)
      if (const double x = a[i].dot(v); x > bestA) {
        bestA = x;
        ia = i;
      }
    for (std::uint32_t j = 1; j < b.size(); ++j)
      if (const double x = b[j].dot(v); x < bestB) {
        bestB = x;
        ib = j;
      }
    const Vec3 w = b[ib] - a[ia];
    // no point of the difference lies closer along v than v itself: v is the closest point
    if (vv - v.dot(w) <= 1e-13 * vv) break;
    bool seen = false;
    for (int k = 0; k < s.n; ++k)
      seen = seen || (s.ia[static_cast<std::size_t>(k)] == ia && s.ib[static_cast<std::size_t>(k)] == ib);
    if (seen) break;
    const Simplex before = s;
    s.w[static_cast<std::size_t>(s.n)] = w;
    s.ia[static_cast<std::size_t>(s.n)] = ia;
    s.ib[static_cast<std::size_t>(s.n)] = ib;
    ++s.n;
    if (!reduce(s)) {
      touching = true;  // the origin is inside the difference: the hulls overlap
      break;
    }
    const Vec3 next = s.point();
    if (!(next.squaredNorm() < vv)) {  // no progress in floating point: keep what we had
      s = before;
      break;
    }
    v = next;
  }
  out.count = s.n;
  for (int k = 0; k < s.n; ++k) {
    const auto K = static_cast<std::size_t>(k);
    out.indexA[K] = s.ia[K];
    out.indexB[K] = s.ib[K];
    out.weight[K] = s.lambda[K];
    out.pointA += s.lambda[K] * a[s.ia[K]];
    out.pointB += s.lambda[K] * b[s.ib[K]];
  }
  if (touching) return out;
  out.distance = v.norm();
  out.separated = out.distance > 1e-12 * std::sqrt(std::max(scale, 1e-300));
  if (out.separated) out.direction = v / out.distance;
  return out;
}

}  // namespace volpar
