#include "volpar/dynamics/rigid_particles.hpp"

#include <algorithm>
#include <array>
#include <limits>

#include "volpar/engine/core/processor.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#define VOLPAR_RIGID_WIDE 1
#else
#define VOLPAR_RIGID_WIDE 0
#endif

namespace volpar {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// The particles to place, as indices: those of a list of ids, or a run of consecutive ones.
struct ListedIds {
  const ParticleId* ids;
  [[nodiscard]] std::size_t operator()(std::size_t k) const { return ids[k].index(); }
};
struct RunOfIds {
  std::size_t first;
  [[nodiscard]] std::size_t operator()(std::size_t k) const { return first + k; }
};
// (a run of particles' centres is one array of doubles: x, y, z of one, then of the next)
static_assert(sizeof(Vec3) == 3 * sizeof(double));

#if VOLPAR_RIGID_WIDE
// Compiled for AVX whatever the build's baseline, and run only where the processor has it.
#define VOLPAR_AVX [[gnu::target("avx"), gnu::always_inline]] inline

/// Four consecutive particles' vectors, read as three registers of (x0 y0 z0 x1), (y1 z1 x2 y2),
/// (z2 x3 y3 z3), as their x, y and z in four lanes.
VOLPAR_AVX void loadRun(const Vec3* at, __m256d& x, __m256d& y, __m256d& z) {
  const __m256d m0 = _mm256_loadu_pd(at->data()), m1 = _mm256_loadu_pd(at->data() + 4), m2 = _mm256_loadu_pd(at->data() + 8);
  const __m256d m03 = _mm256_permute2f128_pd(m0, m2, 0x30);  // x0 y0 y3 z3
  const __m256d m12 = _mm256_permute2f128_pd(m0, m2, 0x21);  // z0 x1 z2 x3
  x = _mm256_blend_pd(_mm256_blend_pd(m03, m12, 0b1010), m1, 0b0100);
  y = _mm256_permute_pd(_mm256_blend_pd(m03, m1, 0b1001), 0b0101);
  z = _mm256_blend_pd(_mm256_blend_pd(m12, m1, 0b0010), m03, 0b1000);
}

/// loadRun()'s inverse: x, y and z of four consecutive particles written as their vectors.
VOLPAR_AVX void storeRun(Vec3* at, __m256d x, __m256d y, __m256d z) {
  const __m256d p = _mm256_unpacklo_pd(x, y);       // x0 y0 x2 y2
  const __m256d s = _mm256_shuffle_pd(z, x, 0b1010);  // z0 x1 z2 x3
  const __m256d u = _mm256_shuffle_pd(y, z, 0b1111);  // y1 z1 y3 z3
  _mm256_storeu_pd(at->data(), _mm256_permute2f128_pd(p, s, 0x20));
  _mm256_storeu_pd(at->data() + 4, _mm256_permute2f128_pd(u, p, 0x30));
  _mm256_storeu_pd(at->data() + 8, _mm256_permute2f128_pd(s, u, 0x31));
}

/// The particles ids(0) to ids(n - 1), four at a time (a last group of fewer repeats its last particle in the lanes
/// left over, as two lanes repeat a last one alone); their spheres' box into lo and hi.
template <class Index>
[[gnu::target("avx")]] void placeFours(const Mat3& r, const BodyState& s, const Index& ids, std::size_t n,
                                       const Vec3* local, const double* radius, Vec3* position, Vec3* velocity,
                                       std::array<double, 3>& lo, std::array<double, 3>& hi) {
  const __m256d r00 = _mm256_set1_pd(r(0, 0)), r01 = _mm256_set1_pd(r(0, 1)), r02 = _mm256_set1_pd(r(0, 2));
  const __m256d r10 = _mm256_set1_pd(r(1, 0)), r11 = _mm256_set1_pd(r(1, 1)), r12 = _mm256_set1_pd(r(1, 2));
  const __m256d r20 = _mm256_set1_pd(r(2, 0)), r21 = _mm256_set1_pd(r(2, 1)), r22 = _mm256_set1_pd(r(2, 2));
  const __m256d c0 = _mm256_set1_pd(s.position.x()), c1 = _mm256_set1_pd(s.position.y()), c2 = _mm256_set1_pd(s.position.z());
  const __m256d v0 = _mm256_set1_pd(s.linearVelocity.x()), v1 = _mm256_set1_pd(s.linearVelocity.y()),
                v2 = _mm256_set1_pd(s.linearVelocity.z());
  const __m256d w0 = _mm256_set1_pd(s.angularVelocity.x()), w1 = _mm256_set1_pd(s.angularVelocity.y()),
                w2 = _mm256_set1_pd(s.angularVelocity.z());
  __m256d lo0 = _mm256_set1_pd(kInf), lo1 = lo0, lo2 = lo0, hi0 = _mm256_set1_pd(-kInf), hi1 = hi0, hi2 = hi0;
  for (std::size_t k = 0; k < n; k += 4) {
    const std::size_t i0 = ids(k), i1 = ids(std::min(k + 1, n - 1)), i2 = ids(std::min(k + 2, n - 1)),
                      i3 = ids(std::min(k + 3, n - 1));
    const bool run = i1 == i0 + 1 && i2 == i0 + 2 && i3 == i0 + 3;
    __m256d lx, ly, lz, rad;
    if (run) {
      loadRun(local + i0, lx, ly, lz);
      rad = _mm256_loadu_pd(radius + i0);
    } else {
      lx = _mm256_set_pd(local[i3].x(), local[i2].x(), local[i1].x(), local[i0].x());
      ly = _mm256_set_pd(local[i3].y(), local[i2].y(), local[i1].y(), local[i0].y());
      lz = _mm256_set_pd(local[i3].z(), local[i2].z(), local[i1].z(), local[i0].z());
      rad = _mm256_set_pd(radius[i3], radius[i2], radius[i1], radius[i0]);
    }
    const __m256d ax = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r00, lx), _mm256_mul_pd(r01, ly)), _mm256_mul_pd(r02, lz));
    const __m256d ay = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(r10, lx), _mm256_mul_pd(r11, ly)), _mm256_mul_pd(r12, lz));
    const __m256d az = _mm256_add_pd(_mm256_mul_pd(r20, lx), _mm256_add_pd(_mm256_mul_pd(r21, ly), _mm256_mul_pd(r22, lz)));
    const __m256d x0 = _mm256_add_pd(c0, ax), x1 = _mm256_add_pd(c1, ay), x2 = _mm256_add_pd(c2, az);
    const __m256d u0 = _mm256_add_pd(v0, _mm256_sub_pd(_mm256_mul_pd(w1, az), _mm256_mul_pd(w2, ay)));
    const __m256d u1 = _mm256_add_pd(v1, _mm256_sub_pd(_mm256_mul_pd(w2, ax), _mm256_mul_pd(w0, az)));
    const __m256d u2 = _mm256_add_pd(v2, _mm256_sub_pd(_mm256_mul_pd(w0, ay), _mm256_mul_pd(w1, ax)));
    if (run) {
      storeRun(position + i0, x0, x1, x2);
      storeRun(velocity + i0, u0, u1, u2);
    } else {
      alignas(32) std::array<double, 4> t[6];
      _mm256_store_pd(t[0].data(), x0), _mm256_store_pd(t[1].data(), x1), _mm256_store_pd(t[2].data(), x2);
      _mm256_store_pd(t[3].data(), u0), _mm256_store_pd(t[4].data(), u1), _mm256_store_pd(t[5].data(), u2);
      const std::array<std::size_t, 4> at{i0, i1, i2, i3};
      for (std::size_t l = 0; l < 4; ++l) {
        position[at[l]] = Vec3(t[0][l], t[1][l], t[2][l]);
        velocity[at[l]] = Vec3(t[3][l], t[4][l], t[5][l]);
      }
    }
    lo0 = _mm256_min_pd(lo0, _mm256_sub_pd(x0, rad)), lo1 = _mm256_min_pd(lo1, _mm256_sub_pd(x1, rad)),
    lo2 = _mm256_min_pd(lo2, _mm256_sub_pd(x2, rad));
    hi0 = _mm256_max_pd(hi0, _mm256_add_pd(x0, rad)), hi1 = _mm256_max_pd(hi1, _mm256_add_pd(x1, rad)),
    hi2 = _mm256_max_pd(hi2, _mm256_add_pd(x2, rad));
  }
  alignas(32) std::array<double, 4> t[6];
  _mm256_store_pd(t[0].data(), lo0), _mm256_store_pd(t[1].data(), lo1), _mm256_store_pd(t[2].data(), lo2);
  _mm256_store_pd(t[3].data(), hi0), _mm256_store_pd(t[4].data(), hi1), _mm256_store_pd(t[5].data(), hi2);
  for (std::size_t c = 0; c < 3; ++c) {
    lo[c] = std::min(std::min(t[c][0], t[c][1]), std::min(t[c][2], t[c][3]));
    hi[c] = std::max(std::max(t[3 + c][0], t[3 + c][1]), std::max(t[3 + c][2], t[3 + c][3]));
  }
}
#undef VOLPAR_AVX
#endif

template <class Index>
ParticleBounds place(const BodyState& s, const Index& ids, std::size_t n, const Vec3* local, const double* radius,
                     Vec3* position, Vec3* velocity, [[maybe_unused]] bool wide) {
  const Mat3 r = s.orientation.toRotationMatrix();
  std::array<double, 3> lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
#if VOLPAR_RIGID_WIDE
  if (wide && processorHasAvx()) {
    placeFours(r, s, ids, n, local, radius, position, velocity, lo, hi);
    return {Vec3(lo[0], lo[1], lo[2]), Vec3(hi[0], hi[1], hi[2])};
  }
#endif
#if defined(__SSE2__)
  // (two particles at a time, one in each lane of a pair of doubles)
  const auto all = [](double x) { return _mm_set1_pd(x); };
  const __m128d r00 = all(r(0, 0)), r01 = all(r(0, 1)), r02 = all(r(0, 2));
  const __m128d r10 = all(r(1, 0)), r11 = all(r(1, 1)), r12 = all(r(1, 2));
  const __m128d r20 = all(r(2, 0)), r21 = all(r(2, 1)), r22 = all(r(2, 2));
  const __m128d c0 = all(s.position.x()), c1 = all(s.position.y()), c2 = all(s.position.z());
  const __m128d v0 = all(s.linearVelocity.x()), v1 = all(s.linearVelocity.y()), v2 = all(s.linearVelocity.z());
  const __m128d w0 = all(s.angularVelocity.x()), w1 = all(s.angularVelocity.y()), w2 = all(s.angularVelocity.z());
  __m128d lo0 = all(kInf), lo1 = lo0, lo2 = lo0, hi0 = all(-kInf), hi1 = hi0, hi2 = hi0;
  const auto left = [](__m128d a, __m128d b, __m128d c, __m128d x, __m128d y, __m128d z) {
    return _mm_add_pd(_mm_add_pd(_mm_mul_pd(a, x), _mm_mul_pd(b, y)), _mm_mul_pd(c, z));
  };
  const auto right = [](__m128d a, __m128d b, __m128d c, __m128d x, __m128d y, __m128d z) {
    return _mm_add_pd(_mm_mul_pd(a, x), _mm_add_pd(_mm_mul_pd(b, y), _mm_mul_pd(c, z)));
  };
  const auto place = [&](std::size_t i, std::size_t j) {  // (particles i and j; j == i for a last one alone)
    const __m128d lx = _mm_set_pd(local[j].x(), local[i].x()), ly = _mm_set_pd(local[j].y(), local[i].y()),
                  lz = _mm_set_pd(local[j].z(), local[i].z());
    const __m128d ax = left(r00, r01, r02, lx, ly, lz), ay = left(r10, r11, r12, lx, ly, lz), az = right(r20, r21, r22, lx, ly, lz);
    const __m128d x0 = _mm_add_pd(c0, ax), x1 = _mm_add_pd(c1, ay), x2 = _mm_add_pd(c2, az);
    const __m128d u0 = _mm_add_pd(v0, _mm_sub_pd(_mm_mul_pd(w1, az), _mm_mul_pd(w2, ay)));
    const __m128d u1 = _mm_add_pd(v1, _mm_sub_pd(_mm_mul_pd(w2, ax), _mm_mul_pd(w0, az)));
    const __m128d u2 = _mm_add_pd(v2, _mm_sub_pd(_mm_mul_pd(w0, ay), _mm_mul_pd(w1, ax)));
    _mm_storel_pd(&position[i].x(), x0), _mm_storel_pd(&position[i].y(), x1), _mm_storel_pd(&position[i].z(), x2);
    _mm_storel_pd(&velocity[i].x(), u0), _mm_storel_pd(&velocity[i].y(), u1), _mm_storel_pd(&velocity[i].z(), u2);
    _mm_storeh_pd(&position[j].x(), x0), _mm_storeh_pd(&position[j].y(), x1), _mm_storeh_pd(&position[j].z(), x2);
    _mm_storeh_pd(&velocity[j].x(), u0), _mm_storeh_pd(&velocity[j].y(), u1), _mm_storeh_pd(&velocity[j].z(), u2);
    const __m128d rad = _mm_set_pd(radius[j], radius[i]);
    lo0 = _mm_min_pd(lo0, _mm_sub_pd(x0, rad)), lo1 = _mm_min_pd(lo1, _mm_sub_pd(x1, rad)), lo2 = _mm_min_pd(lo2, _mm_sub_pd(x2, rad));
    hi0 = _mm_max_pd(hi0, _mm_add_pd(x0, rad)), hi1 = _mm_max_pd(hi1, _mm_add_pd(x1, rad)), hi2 = _mm_max_pd(hi2, _mm_add_pd(x2, rad));
  };
  std::size_t k = 0;
  for (; k + 1 < n; k += 2) place(ids(k), ids(k + 1));
  if (k < n) place(ids(k), ids(k));
  const auto low = [](__m128d m) { return std::min(_mm_cvtsd_f64(m), _mm_cvtsd_f64(_mm_unpackhi_pd(m, m))); };
  const auto high = [](__m128d m) { return std::max(_mm_cvtsd_f64(m), _mm_cvtsd_f64(_mm_unpackhi_pd(m, m))); };
  lo = {low(lo0), low(lo1), low(lo2)};
  hi = {high(hi0), high(hi1), high(hi2)};
#else
  const Vec3 c = s.position, v = s.linearVelocity, w = s.angularVelocity;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = ids(k);
    const Vec3& l = local[i];
    const double ax = (r(0, 0) * l.x() + r(0, 1) * l.y()) + r(0, 2) * l.z();
    const double ay = (r(1, 0) * l.x() + r(1, 1) * l.y()) + r(1, 2) * l.z();
    const double az = r(2, 0) * l.x() + (r(2, 1) * l.y() + r(2, 2) * l.z());
    const Vec3 x(c.x() + ax, c.y() + ay, c.z() + az);
    position[i] = x;
    velocity[i] = Vec3(v.x() + (w.y() * az - w.z() * ay), v.y() + (w.z() * ax - w.x() * az), v.z() + (w.x() * ay - w.y() * ax));
    const double rad = radius[i];
    lo = {std::min(lo[0], x.x() - rad), std::min(lo[1], x.y() - rad), std::min(lo[2], x.z() - rad)};
    hi = {std::max(hi[0], x.x() + rad), std::max(hi[1], x.y() + rad), std::max(hi[2], x.z() + rad)};
  }
#endif
  return {Vec3(lo[0], lo[1], lo[2]), Vec3(hi[0], hi[1], hi[2])};
}

}  // namespace

ParticleBounds placeRigidParticles(const BodyState& s, std::span<const ParticleId> ids, const Vec3* local,
                                   const double* radius, Vec3* position, Vec3* velocity, bool wide) {
  return place(s, ListedIds{ids.data()}, ids.size(), local, radius, position, velocity, wide);
}

ParticleBounds placeRigidParticles(const BodyState& s, ParticleRun run, const Vec3* local, const double* radius,
                                   Vec3* position, Vec3* velocity, bool wide) {
  return place(s, RunOfIds{run.first}, run.count, local, radius, position, velocity, wide);
}

}  // namespace volpar
