#include "volpar/engine/core/connector_store.hpp"

#include <limits>

namespace volpar {

ConnectorId ConnectorStore::add(ParticleId pa, ParticleId pb, double rest, const ConnectorParams& params,
                                double radius, double strengthFactor) {
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
  const bool bond = params.kind == ConnectorKind::Bond;
  constexpr double kNever = std::numeric_limits<double>::infinity();
  bondRadius.push_back(bond ? radius : 0.0);
  youngsModulus.push_back(bond ? params.bond.youngsModulus : 0.0);
  poissonRatio.push_back(bond ? params.bond.poissonRatio : 0.0);
  tensileStrength.push_back(bond ? strengthFactor * params.bond.tensileStrength : kNever);
  shearStrength.push_back(bond ? strengthFactor * params.bond.shearStrength : kNever);
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
  bondRadius.reserve(count);
  youngsModulus.reserve(count);
  poissonRatio.reserve(count);
  tensileStrength.reserve(count);
  shearStrength.reserve(count);
}

}  // namespace volpar
