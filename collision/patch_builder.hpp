#pragma once
// Contact patches (docs/narrow-phase.md): the contacts of one contact group (a body pair, a body and a plane, or a
// deformable body touching itself) grouped into local regions, each of which gets one separating plane.
//
// A patch grows from its deepest unassigned contact. A contact joins when it touches the patch through
// connectors (its particle on side A is one of the patch's contacts' A particles or a connector neighbour
// of one, and likewise on side B; against a plane side A alone), its centre line is within 78 degrees of
// that contact's (a lattice face tilts a contact's centre line by up to 35 degrees; a wall and a floor
// differ by 90), and its *direction* is within `spread` of the patch's (its first contact's that has one).
// A contact's direction is the normal of the surface it touches: the mean of the two particles' facing
// surface normals, or the one side's where the other particle sits on an edge or corner; a contact between
// two edge or corner particles has none and is not judged by it. So a patch
// never grows without bound: on a curved or folded surface (cloth over a ball) it stops where the surface
// has turned, and a peg touching both walls of a slot makes one patch per wall.
//
// A deformable body touching itself has no given sides: the seed's particles name them (its a on side A, b
// on side B), and each joining contact takes the orientation that keeps every particle on one side (a
// contact that cannot is left for another patch). PatchSet::flipped marks contacts whose b is on side A.

#include <cstdint>
#include <span>
#include <vector>

#include "volpar/collision/contact_patch.hpp"

namespace volpar {

class PatchBuilder {
 public:
  /// Largest angle between a contact's direction and its patch seed's [rad].
  double spread = 0.7;  // 40 degrees
  /// The same where a side is deformable [rad]: such a patch's contacts are each resolved on their own, and
  /// its plane stands for a surface that may be curved or folded under it.
  double deformableSpread = 0.25;  // 14 degrees

  /// Groups the contacts of `g` into patches: `order` receives the contacts (indices into set.contacts),
  /// patch by patch, and `sizes` each patch's count; `flipped` (per contact of the set) is written for them.
  void build(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, std::span<std::uint8_t> flipped,
             std::vector<std::uint32_t>& order, std::vector<std::uint32_t>& sizes);

  /// Splits the contacts `idx` of a patch in two (along the widest spread of their directions, or of their
  /// points where the directions agree): reorders them in place and returns the size of the first part
  /// (between 1 and idx.size() - 1).
  std::size_t split(const NarrowPhaseInput& in, const ContactSet& set, std::span<std::uint32_t> idx,
                    std::span<const std::uint8_t> flipped);

 private:
  /// The direction of contact `c` (from its side A to its side B, before any flip); false when neither of
  /// its particles has a surface normal there (both on edges or corners): its centre line, which the
  /// spread bound does not judge.
  static bool direction(const NarrowPhaseInput& in, const ParticleContact& c, Vec3& out);

  std::vector<std::uint32_t> seeds_, queue_, patchOf_;
  std::vector<Vec3> directions_;
  std::vector<std::uint8_t> surface_;  // per contact: its direction is a surface's
  std::vector<std::pair<ParticleId, std::uint32_t>> byParticle_;  // self-contact: each contact under both particles
  std::vector<std::uint32_t> side_;   // [P] stamp * 2 + side of a particle in the patch being grown
  std::uint32_t stamp_ = 0;
  std::vector<std::uint32_t> scratch_;
  std::vector<double> keys_;
};

}  // namespace volpar
