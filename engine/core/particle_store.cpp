#include "volpar/engine/core/particle_store.hpp"

namespace volpar {

ParticleId ParticleStore::grow(std::size_t count) {
  const std::size_t first = size();
  const std::size_t n = first + count;
  position.resize(n, Vec3::Zero());
  velocity.resize(n, Vec3::Zero());
  local.resize(n, Vec3::Zero());
  radius.resize(n, 0.0);
  mass.resize(n, 0.0);
  invMass.resize(n, 0.0);
  ownInertia.resize(n, 0.0);
  body.resize(n, BodyId{});
  normalIndex.resize(n, -1);
  flags.resize(n, 0);
  return ParticleId(first);
}

void ParticleStore::reserve(std::size_t count) {
  position.reserve(count);
  velocity.reserve(count);
  local.reserve(count);
  radius.reserve(count);
  mass.reserve(count);
  invMass.reserve(count);
  ownInertia.reserve(count);
  body.reserve(count);
  normalIndex.reserve(count);
  flags.reserve(count);
}

}  // namespace volpar
