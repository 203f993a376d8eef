#pragma once
// Per-particle surface normals (DESIGN section 5). Each surface particle holds an index
// (ParticleStore::normalIndex) into this list; interior particles hold -1. Normals are stored in the body
// frame, so moving a body costs nothing: the principal frame of rigid and static bodies, and for deformable
// bodies the frame of their rest shape, which follows the body's best-fit rotation (shape matching); where
// a deformable region strains, its normals are recomputed. A zero normal means the particle is on the
// surface but has no preferred direction (a lone particle).

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "engine/core/body_store.hpp"
#include "engine/core/particle_store.hpp"
#include "engine/core/types.hpp"

namespace volpar {

class ContactFinder;

class NormalCache {
 public:
  /// Appends a normal, and the exact normals of the shape's faces it averages (an edge particle's two
  /// faces, a corner's three; none for estimated normals), and returns its index.
  std::int32_t add(const Vec3& normal, std::span<const Vec3> faces = {}) {
    normals_.push_back(normal);
    Faces f{};
    f.count = static_cast<std::uint8_t>(std::min<std::size_t>(faces.size(), 3));
    for (std::size_t k = 0; k < f.count; ++k) f.normal[k] = faces[k];
    faces_.push_back(f);
    return static_cast<std::int32_t>(normals_.size() - 1);
  }
  [[nodiscard]] const Vec3& operator[](std::int32_t index) const { return normals_[static_cast<std::size_t>(index)]; }
  /// The face normals behind entry `index` (possibly none).
  [[nodiscard]] std::span<const Vec3> faces(std::int32_t index) const {
    const Faces& f = faces_[static_cast<std::size_t>(index)];
    return {f.normal.data(), f.count};
  }
  void set(std::int32_t index, const Vec3& normal) {
    normals_[static_cast<std::size_t>(index)] = normal;
    faces_[static_cast<std::size_t>(index)].count = 0;  // recomputed normals are estimates
  }
  [[nodiscard]] std::size_t size() const { return normals_.size(); }

 private:
  struct Faces {
    std::array<Vec3, 3> normal;
    std::uint8_t count = 0;
  };
  std::vector<Vec3> normals_;
  std::vector<Faces> faces_;
};

/// Outward normals estimated from the connector neighbourhood: for particle i, the unit vector from the
/// mean of its neighbours to i. A particle is on the surface when that offset exceeds 15 % of its mean
/// neighbour distance, or when it has fewer than 4 neighbours; interior particles get (surface = 0, zero
/// normal). positions [P], connectors as index pairs.
struct EstimatedNormals {
  std::vector<Vec3> normal;           ///< [P]
  std::vector<std::uint8_t> surface;  ///< [P]
};
[[nodiscard]] EstimatedNormals estimateNormals(std::span<const Vec3> positions,
                                               std::span<const std::array<std::uint32_t, 2>> connectors);

/// Partial recomputation (DESIGN section 5), for breakage and deformation: re-estimates the normals of
/// exactly the listed particles from their current connector neighbourhood (same rule as estimateNormals),
/// in the frame the cache keeps for their body (principal frame for rigid and static bodies, world for
/// deformable ones). A particle that became a surface particle gets a cache entry; one that became interior
/// loses its surface flag. The caller chooses the particles (e.g. the k-ring around broken connectors), so
/// the cost is bounded by that neighbourhood, never by the body. Returns how many were recomputed.
std::size_t recomputeNormals(std::span<const ParticleId> ids, ParticleStore& particles, const BodyStore& bodies,
                             const ContactFinder& adjacency, NormalCache& cache);

}  // namespace volpar
