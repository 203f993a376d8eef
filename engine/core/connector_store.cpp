#include "engine/core/connector_store.hpp"

#include <limits>

namespace volpar {

ConnectorId ConnectorStore::add(ParticleId pa, ParticleId pb, double rest, const ConnectorParams& params) {
  const ConnectorId id(size());
  a.push_back(pa);
  b.push_back(pb);
  kind.push_back(params.kind);
  restLength.push_back(rest);
  stiffness.push_back(params.stiffness);
  damping.push_back(params.damping);
  breakLimit.push_back(params.breakLimit);
  compressionLimit.push_back(params.kind == ConnectorKind::Rod ? params.compressionLimit : std::numeric_limits<double>::infinity());
  broken.push_back(0);
  return id;
}

void ConnectorStore::reserve(std::size_t count) {
  a.reserve(count);
  b.reserve(count);
  kind.reserve(count);
  restLength.reserve(count);
  stiffness.reserve(count);
  damping.reserve(count);
  breakLimit.reserve(count);
  compressionLimit.reserve(count);
  broken.reserve(count);
}

}  // namespace volpar
