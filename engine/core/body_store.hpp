#pragma once
// Bodies by index: a hot BodyState touched every step, and a cold BodyInfo for bookkeeping.
//
// A rigid body's frame is its *principal frame*: origin at the centre of mass, axes along the
// principal axes of inertia, so the body-frame inertia is diagonal. Particle offsets (ParticleStore::local)
// and cached normals live in that frame. The frame the user built the shape in (the *shape frame*) is
// recovered with BodyInfo::principalInShape and BodyInfo::comInShape.

#include <cstdint>
#include <string>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/ids.hpp"
#include "volpar/engine/core/source_shape.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

enum class BodyKind : std::uint8_t {
  Rigid,       ///< particles joined by rods, moves as one rigid body
  Deformable,  ///< particles are point masses joined by springs and rods
  Static,      ///< never moves, infinite mass
};

/// Hot per-body state, read and written by the integrators and the solver.
struct BodyState {
  Vec3 position = Vec3::Zero();         ///< centre of mass, world [m]
  Quat orientation = Quat::Identity();  ///< principal frame -> world (unit)
  Vec3 linearVelocity = Vec3::Zero();   ///< of the centre of mass, world [m/s]
  Vec3 angularVelocity = Vec3::Zero();  ///< world [rad/s]
  Vec3 invInertiaLocal = Vec3::Zero();  ///< inverse principal moments [1/(kg m^2)]; 0 for static and deformable
  double invMass = 0.0;                 ///< [1/kg]; 0 for static
  Mat3 invInertiaWorld = Mat3::Zero();  ///< R diag(invInertiaLocal) R^T [1/(kg m^2)]
};
static_assert(sizeof(BodyState) <= 224, "BodyState is hot: keep it within 3.5 cache lines");

/// Cold per-body data.
/// Where a rigid body's mass properties come from.
enum class MassModel : std::uint8_t {
  Solid,      ///< the solid it was filled from: its inertia, about the particles' centre of mass
  Particles,  ///< its particles, each standing for its lattice cell (or, in a particle list, its sphere)
};

struct BodyInfo {
  std::string name;
  BodyKind kind = BodyKind::Rigid;
  MaterialId material;
  double mass = 0.0;                           ///< [kg]
  Vec3 inertiaLocal = Vec3::Zero();            ///< principal moments about the centre of mass [kg m^2]
  Quat principalInShape = Quat::Identity();    ///< rotation from principal-frame to shape-frame coordinates
  Vec3 comInShape = Vec3::Zero();              ///< centre of mass in shape-frame coordinates [m]
  /// What the inertia adds to that of its particles (their own moments and parallel-axis terms) so that it is
  /// the filled solid's (MassModel::Solid), in the principal frame [kg m^2]; fragments inherit their share
  Mat3 inertiaResidual = Mat3::Zero();
  std::vector<ParticleId> particles;           ///< the body's particles, ascending (empty once retired)
  SourceShape source;                          ///< the solid it was filled from, if any
  SourceShape core;                            ///< that solid fitted to the particle centres (source_shape.hpp)
  bool alive = true;                           ///< false once the body broke apart into new bodies
  std::int64_t createdStep = 0;                ///< the first step after which it exists (0: from the start)
  std::int64_t retiredStep = -1;               ///< the step (1 = the first) in which it broke apart, -1 while alive
  BodyId parent;                               ///< the body it broke off from, if any
  BodyId gluedInto;                            ///< the body it was glued into (World::glue), if any
  /// It has connectors that can break, or broke off a body that had: a fragment, or what may become one
  bool breakable = false;
};

/// A body's particles as a run of consecutive ids where they are one (the particles of a body as built are;
/// a fragment's need not be): hot loops read the run instead of the body's list.
struct ParticleRun {
  std::uint32_t first = 0, count = 0;
  bool consecutive = false;  ///< the ids are first, first + 1, ..., first + count - 1
};

/// The run of a body's list of particles (ascending).
[[nodiscard]] inline ParticleRun runOf(const std::vector<ParticleId>& particles) {
  ParticleRun r;
  r.count = static_cast<std::uint32_t>(particles.size());
  r.first = particles.empty() ? 0 : particles.front().value;
  r.consecutive = particles.empty() || particles.back().value - particles.front().value + 1 == r.count;
  return r;
}

struct BodyStore {
  LargeVector<BodyState> state;  ///< [B]
  LargeVector<BodyInfo> info;    ///< [B]

  [[nodiscard]] std::size_t size() const { return state.size(); }

  BodyId add(BodyState s, BodyInfo i) {
    state.push_back(std::move(s));
    info.push_back(std::move(i));
    return BodyId(state.size() - 1);
  }

  /// Orientation of the body's shape frame in the world.
  [[nodiscard]] Quat shapeOrientation(BodyId id) const {
    return state[id.index()].orientation * info[id.index()].principalInShape.conjugate();
  }
  /// Origin of the body's shape frame in the world [m].
  [[nodiscard]] Vec3 shapeOrigin(BodyId id) const {
    return state[id.index()].position - shapeOrientation(id) * info[id.index()].comInShape;
  }
};

}  // namespace volpar
