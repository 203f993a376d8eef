#pragma once
// A rigid body's particles at the body's pose: each particle's world centre and velocity from its centre in
// the body's frame, and the box of their spheres, once per body and step.

#include <span>

#include "volpar/engine/core/body_store.hpp"

namespace volpar {

/// The box of a body's particles' spheres [m] (lo = +inf, hi = -inf for a body without particles).
struct ParticleBounds {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
};

/// Places the particles `ids` of a rigid body of state `s`: with R its rotation and c its centre, each
/// particle's arm a = R local, its position c + a and its velocity v + w x a; returns the box of the spheres
/// (position -+ radius). Each particle's arithmetic is, in this order: the products of each row of R summed
/// from the left in the first two rows and from the right in the third, then the sums above, without fused
/// multiply-adds. Four particles at a time in the lanes of AVX registers where `wide` is true and the
/// processor has AVX (processorHasAvx()), otherwise two at a time (one at a time without SSE2):
/// every lane does the same arithmetic, so the result is the same bit for bit, however the particles are
/// numbered (a run of four consecutive ids is read and written four at a time).
ParticleBounds placeRigidParticles(const BodyState& s, std::span<const ParticleId> ids, const Vec3* local,
                                   const double* radius, Vec3* position, Vec3* velocity, bool wide = true);
/// The same for the particles of a run of consecutive ids (`run.consecutive`), placed as their list would be.
ParticleBounds placeRigidParticles(const BodyState& s, ParticleRun run, const Vec3* local, const double* radius,
                                   Vec3* position, Vec3* velocity, bool wide = true);

}  // namespace volpar
