#pragma once
// Per-particle surface normals (docs/narrow-phase.md, Surface normals). Each surface particle holds an index
// (ParticleStore::normalIndex) into this list; interior particles hold -1. Normals are stored in the body
// frame, so moving a body costs nothing: the principal frame of rigid and static bodies, and for deformable
// bodies the frame of their rest shape, which follows the body's best-fit rotation (shape matching); where
// a deformable region bends or strains, its normals are recomputed. An entry also holds the faces the
// particle lies on (an edge's two, a corner's three, a sheet's two sides and its rim): the builders' exact
// face normals, or estimated ones (normal_estimation.hpp). How to read an entry depends on the particle's
// flags (ParticleFlag): see facingNormal().
//
// Entries are recycled: a particle keeps its entry while it is on the surface, rewritten when its normal is
// recomputed or its body splits, and gives it back when it becomes interior. The list never holds more
// entries than the most surface particles there have been at once.
//
// Entries are shared. The particles of rigid and static bodies take an entry equal to theirs where one is in
// use (the particles of one face of a box; every crate of a pile built from one shape), so the cache holds a
// shape's normals once however many bodies have it, and the narrow phase reads them from the cache instead
// of from memory. An entry counts its particles: rewriting a shared entry gives the particle an entry of its
// own (or another equal one), and the entry is free once no particle holds it. Sharing changes which entry a
// particle reads, never what it reads.

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "volpar/collision/normal_estimation.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/state_archive.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

class ContactFinder;

class NormalCache {
 public:
  /// Stores a normal and the faces behind it (up to three) in a free entry; returns its index.
  std::int32_t add(const Vec3& normal, std::span<const Vec3> faces = {}) {
    std::int32_t index;
    if (!free_.empty()) {
      index = free_.back();
      free_.pop_back();
    } else {
      index = static_cast<std::int32_t>(normals_.size());
      normals_.emplace_back();
      faces_.emplace_back();
      users_.push_back(0);
    }
    write(index, normal, faces);
    users_[static_cast<std::size_t>(index)] = 1;
    return index;
  }
  /// As add(), but returns an entry in use that holds exactly this normal and these faces where there is one
  /// (the entry then has one more particle).
  std::int32_t addShared(const Vec3& normal, std::span<const Vec3> faces = {});
  /// The entry particle's entry `index` becomes when its normal and faces are rewritten: `index` itself,
  /// rewritten in place, where the particle alone holds it; otherwise an equal entry in use or a new one.
  [[nodiscard]] std::int32_t rewrite(std::int32_t index, const Vec3& normal, std::span<const Vec3> faces = {});
  /// Gives a particle's hold on entry `index` back (its particle became interior); the entry is free once no
  /// particle holds it.
  void release(std::int32_t index) {
    if (--users_[static_cast<std::size_t>(index)] == 0) free_.push_back(index);
  }
  /// Counts each entry's particles anew from their indices (after restore()); false where a particle points
  /// past the list or to a free entry.
  bool countUsers(std::span<const std::int32_t> normalIndex);

  [[nodiscard]] const Vec3& operator[](std::int32_t index) const { return normals_[static_cast<std::size_t>(index)]; }
  /// The face normals behind entry `index` (possibly none).
  [[nodiscard]] std::span<const Vec3> faces(std::int32_t index) const {
    const Faces& f = faces_[static_cast<std::size_t>(index)];
    return {f.normal.data(), f.count};
  }
  /// Entries allocated (in use or free).
  [[nodiscard]] std::size_t size() const { return normals_.size(); }
  /// Entries in use.
  [[nodiscard]] std::size_t used() const { return normals_.size() - free_.size(); }
  /// The particles that hold entry `index`.
  [[nodiscard]] std::uint32_t users(std::int32_t index) const { return users_[static_cast<std::size_t>(index)]; }

  /// Puts the entries (in use and free) under "normals/..." (collision_state.cpp).
  void save(StateArchive& archive) const;
  /// Takes the entries back; false (with the reason in `reader`) where they do not fit together.
  bool restore(StateReader& reader);

 private:
  struct Faces {
    std::array<Vec3, 3> normal;
    std::uint8_t count = 0;
  };
  void write(std::int32_t index, const Vec3& normal, std::span<const Vec3> faces) {
    normals_[static_cast<std::size_t>(index)] = normal;
    Faces& f = faces_[static_cast<std::size_t>(index)];
    f.count = static_cast<std::uint8_t>(std::min<std::size_t>(faces.size(), 3));
    for (std::size_t k = 0; k < f.count; ++k) f.normal[k] = faces[k];
  }
  /// Whether entry `index` is in use and holds exactly this normal and these faces (bit for bit).
  [[nodiscard]] bool holds(std::int32_t index, const Vec3& normal, std::span<const Vec3> faces) const;
  std::vector<Vec3> normals_;
  std::vector<Faces> faces_;
  std::vector<std::uint32_t> users_;  // by entry: the particles that hold it (0: free)
  std::vector<std::int32_t> free_;
  // (entries to share: by a hash of their contents, an entry that held them when it was made; checked
  // with holds() before it is shared)
  std::unordered_map<std::uint64_t, std::int32_t> shared_;
};

/// World-frame outward normal of a surface particle from the cache (zero for interior particles).
[[nodiscard]] inline Vec3 cachedWorldNormal(const ParticleStore& particles, const BodyStore& bodies,
                                            const NormalCache& normals, ParticleId p) {
  const std::int32_t k = particles.normalIndex[p.index()];
  if (k < 0) return Vec3::Zero();
  return bodies.state[particles.body[p.index()].index()].orientation * normals[k];
}

/// The outward normal of a surface particle as seen from direction `towards` (unit, from the particle
/// towards what it touches), in the frame of `normal` and `faces`: a sheet shows the side (or rim) facing
/// that way, a chain the direction across it, a lone particle `towards` itself; every other particle its
/// normal. Zero for interior particles (flags without kParticleSurface).
[[nodiscard]] inline Vec3 facingNormal(std::uint8_t flags, const Vec3& normal, std::span<const Vec3> faces,
                                       const Vec3& towards) {
  if (!(flags & kParticleSurface)) return Vec3::Zero();
  if (flags & kParticleSheet) {
    Vec3 best = normal;
    double top = -2.0;
    for (const Vec3& f : faces)
      if (const double d = f.dot(towards); d > top) {
        top = d;
        best = f;
      }
    return best;
  }
  if (flags & kParticleLine) {
    const Vec3 across = towards - towards.dot(normal) * normal;
    const double n = across.norm();
    return n > 1e-12 ? Vec3(across / n) : towards;
  }
  if (normal.isZero()) return towards;
  return normal;
}

/// Partial recomputation (docs/narrow-phase.md, Updates), for breakage and deformation: re-estimates exactly the listed
/// particles from their current connector neighbourhood (normal_estimation.hpp), in the frame the cache
/// keeps for their body (principal frame for rigid and static bodies; for deformable ones, the world
/// frame turned into their rest frame by the body's orientation), and sets their flags. `opened` marks the
/// particles that lost a connector (they lie on a crack face). A particle that became a surface particle
/// gets an entry (a recycled one where there is one); one that became interior gives its entry back. The
/// caller chooses the particles (e.g. those within two connectors of a break), so the cost is bounded by
/// that neighbourhood, never by the body. Keeps its scratch: once grown, recomputing allocates nothing.
class NormalUpdater {
 public:
  /// Recomputes `ids`; returns how many.
  std::size_t recompute(std::span<const ParticleId> ids, ParticleStore& particles, const BodyStore& bodies,
                        const ContactFinder& adjacency, std::span<const std::uint8_t> opened, NormalCache& cache);

 private:
  SurfaceEstimator estimator_;
  std::vector<ParticleId> rigid_, deformable_;
  std::vector<SurfaceEstimate> out_;
  std::vector<std::uint8_t> kinds_;
};

}  // namespace volpar
