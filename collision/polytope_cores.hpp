#pragma once
// Whole polytope cores (docs/narrow-phase.md, Whole polytope cores): a rigid or static body whose particle
// centres fill a convex polytope exactly, the polytope its particles' cached face normals bound.
//
// The narrow phase rebuilds the core of a side near each contact from the local particles and their cached
// normals: the planes of the flat faces through the outermost centres. For most bodies that is all there is
// to know: a concave body, a fractured one, a curved one or one whose faces step along the lattice has a
// different core in every place. But where a body's face normals bound a convex polytope and the particle
// centres reach every vertex of it, the local cores are all pieces of that one polytope, and the closest
// points of two such bodies' polytopes give the plane of their contact directly. This class finds which
// bodies qualify and keeps their polytopes (the particle centres at the vertices, in the body frame), from
// the particles alone:
//
//   1. Every surface particle carries flat faces: its cached normal, or the faces of an edge or a corner.
//      Sheets, chains and particles without faces disqualify the body. The distinct face normals (equal to
//      rounding, at most kMaxFaces) are the candidate facets.
//   2. Each facet's plane passes through the outermost centre along its normal, and every particle that
//      carries the face lies on that plane (a concave body's inner faces, a staircase, do not).
//   3. The facets bound a polytope (no direction escapes every plane), whose vertices (at most kMaxVertices)
//      are each a particle centre: the hull of the centres is the polytope.
//
// Built when a body is added, and again when its particles' normals are recomputed (a crack) or it is made
// from fragments; retired and deformable bodies have none.

#include <cstdint>
#include <span>
#include <vector>

#include "volpar/collision/normal_cache.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

class PolytopeCores {
 public:
  static constexpr std::size_t kMaxFaces = 32;     ///< more distinct face normals: a curved body, no polytope
  static constexpr std::size_t kMaxVertices = 64;  ///< more vertices: no polytope kept

  /// Finds body `id`'s polytope core again from its particles (their local positions and cached normals);
  /// none for a deformable or retired body, or where the particles do not fill a convex polytope exactly.
  void update(BodyId id, const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals);
  /// Every body's again (after a restore).
  void updateAll(const ParticleStore& particles, const BodyStore& bodies, const NormalCache& normals);
  /// The vertices of body `id`'s polytope core, body frame [m]: particle centres (empty: none).
  [[nodiscard]] std::span<const Vec3> vertices(BodyId id) const {
    if (id.index() >= count_.size()) return {};
    return {vertices_.data() + first_[id.index()], count_[id.index()]};
  }
  /// Bodies with a polytope core.
  [[nodiscard]] std::size_t bodiesWithCore() const;

  /// Whether the particles `ids` (local positions and cached normals) fill a convex polytope exactly; its
  /// vertices (particle centres, in the order found) into `out`.
  static bool find(std::span<const ParticleId> ids, const ParticleStore& particles, const NormalCache& normals,
                   std::vector<Vec3>& out);

 private:
  std::vector<std::uint32_t> first_, count_, capacity_;  // [B] each body's vertices in vertices_ (and room)
  std::vector<Vec3> vertices_;
  std::vector<Vec3> scratch_;
};

}  // namespace volpar
