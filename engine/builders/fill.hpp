#pragma once
// Builders: fill a solid shape with particles on a lattice, or take an explicit particle list.
//
// Lattice fill: sites of a cubic or hexagonal close-packed lattice whose spheres lie inside the shape
// (signed distance of the centre <= -radius). The cubic lattice is placed symmetrically in the shape's
// bounding box, with the outermost sites as far out as they fit, so a box whose sides are multiples of
// the spacing is filled exactly; the HCP lattice has a site at the shape's centre. A site is on the
// surface when one of its nearest lattice neighbours does not fit. Its normal is the shape's exact outward
// normal: the mean of the normals of the surface features within half a spacing of the nearest one that
// face one of its missing neighbours (n . direction > 1/2). So a particle on a face gets the face normal,
// one on a convex edge or corner the mean of the faces it is outermost on, and one beside a concave edge
// only the face it actually lies under. Particles closer than `reach` x spacing are joined by connectors.
// Each particle stands for an equal share of the shape's exact volume, so a body filled at a given
// density has exactly density x volume of mass (for a box whose sides are multiples of the spacing the
// share is the lattice cell, s^3).

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/engine/builders/particle_cloud.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/core/status.hpp"

namespace volpar {

enum class Lattice : std::uint8_t { Cubic, Hcp };

struct FillSettings {
  Lattice lattice = Lattice::Cubic;
  double radius = 0.05;  ///< particle radius [m]
  double spacing = 0.0;  ///< distance between nearest sites [m]; 0 means 2 x radius (touching)
  double reach = 1.5;    ///< connect particles closer than reach x spacing [-]
};

/// Site (i, j, k) of a lattice with nearest-neighbour distance s, relative to its anchor. HCP follows the
/// standard construction with sphere radius r = s/2: ((2i + (j + k) mod 2) r, sqrt(3) (j + (k mod 2) / 3) r,
/// (2 sqrt(6) / 3) k r): close-packed layers in the xy plane, a close-packed row along x.
[[nodiscard]] Vec3 latticeSite(Lattice lattice, double s, const std::array<long, 3>& ijk);

/// Volume of one lattice cell [m^3]: s^3 (cubic), s^3 / sqrt(2) (HCP). Used to estimate particle counts.
[[nodiscard]] double latticeCellVolume(Lattice lattice, double spacing);

/// Fills `shape`; fails when no particle fits.
[[nodiscard]] Result<ParticleCloud> fillShape(const SolidShape& shape, const FillSettings& settings);

/// An explicit particle list. `radii` has one entry per position, or one for all. With `connectors`
/// given, exactly those are used (checked: indices in range, no self or duplicate pairs); otherwise
/// particles closer than `reach` [m] are joined. Normals are estimated from the connector neighbourhood.
/// Each particle stands for the volume of its sphere.
struct ParticleListSettings {
  std::vector<Vec3> positions;
  std::vector<double> radii;
  std::vector<std::array<std::uint32_t, 2>> connectors;
  bool explicitConnectors = false;
  double reach = 0.0;  ///< [m]; 0 means 1.5 x the largest diameter
};
[[nodiscard]] Result<ParticleCloud> buildParticleList(const ParticleListSettings& settings);

/// Replaces a cloud's surface flags, normals and features by those estimated from its particles and
/// connectors alone (collision/normal_estimation.hpp), as an explicit particle list gets them.
void useEstimatedNormals(ParticleCloud& cloud);

/// Pairs (i < j) of points closer than `reach`, ascending; uses a grid, never all pairs.
[[nodiscard]] std::vector<std::array<std::uint32_t, 2>> connectWithin(std::span<const Vec3> points, double reach);

}  // namespace volpar
