#pragma once
// Surface normals from the particle neighbourhood alone: for explicit particle lists,
// for bodies built with `normals: estimated`, for the faces a crack opens and for bodies that deform.
//
// For each particle, from its connector neighbours:
//  - the *missing vector* m = sum over neighbours of (x_p - x_j), which points away from where the
//    neighbours are (on a lattice it is the sum of the missing neighbour directions);
//  - the shape of the neighbourhood: neighbours in a plane through the particle make it part of a *sheet*
//    (a layer one particle thick: both sides are surface; with a clear in-plane m it is on the sheet's rim),
//    neighbours on a line make it part of a *line* (a chain), no neighbours a lone *point*; otherwise the
//    particle is in a volume, and on its surface when it has fewer than four neighbours, when |m| exceeds
//    15 % of the sum of its neighbour distances (0.15 x count x mean distance), or when a connector of it
//    broke (it lies on a crack face).
// A volume surface particle's normal is fitted to the surface particles reached through others within four
// connector hops whose missing vectors lie within 60 degrees of its own: their best-fit plane (oriented
// along m) where they lie within 0.3 spacings of it (rms) and a quadric height field over it does not halve
// its squared residual (a lattice face exactly, a staircase oblique to the lattice averaged); else the
// surface is curved, and the normal is that of the best-fit algebraic sphere (where the quadric bends both
// ways) or of the circle across the quadric's straight direction (where it bends one way: a cylinder), at
// the particle, which goes round the flat runs of the lattice's outline to the curve.
// Where the particles are not close to a plane the particle may sit on an edge or a corner: its faces are
// the normals of the planar surface particles within two hops that face its way, clustered within 20
// degrees; two clusters make an edge, three or more a corner (the three largest are kept), and its normal
// is the mean of its faces, as the builders give a shape's edges.
// Over a whole body (joinFaces), flat faces are grown from the particles whose fit is planar over the
// surface particles within 0.6 spacings of their plane, refitted until they settle, and kept unless they
// are lattice facets of a curved surface (narrow strips past which the surface turns by under 60 degrees);
// a particle on one such face takes its plane, on two it lies on an edge, on three or more on a corner.
// The curved surface particles left between the faces, each connected set of them, are then fitted whole
// as one rounded core (a sphere, a cylinder's side or a capsule; rounded_core.hpp) where one fits them
// within 0.35 spacings (rms): a particle on it takes the direction from the core, where a local fit follows
// the flat runs of steps a lattice outlines a curve with.
// A crack face is made of the particles that lost a connector: a crack particle's plane is fitted to them
// alone, within four connectors along them on its side (a staircase across the lattice counts as a plane
// within 0.3 spacings rms), and where the crack meets older faces their tight clusters join it as the
// faces of an edge or a corner.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/engine/core/ids.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

/// Connector hops along the surface over which a particle's surface is fitted: for bodies at rest in their
/// frame, and for bodies that deform (re-estimated in the step, where the wider fit's cost shows).
inline constexpr int kSurfaceReach = 4;
inline constexpr int kDeformingSurfaceReach = 2;

/// The estimated surface at one particle.
struct SurfaceEstimate {
  std::uint8_t flags = 0;            ///< ParticleFlag bits; 0 for an interior particle
  Vec3 normal = Vec3::Zero();        ///< unit outward normal (sheet: one side; rim: in-plane outwards; line:
                                     ///< the chain's direction; zero for a lone point or an interior particle)
  std::array<Vec3, 3> faces{Vec3::Zero(), Vec3::Zero(), Vec3::Zero()};  ///< the faces it lies on (sheets: both sides)
  std::uint8_t faceCount = 0;
};

/// The particles and their connector adjacency, over one index space.
struct Neighbourhood {
  std::span<const Vec3> positions;         ///< [N], any frame
  std::span<const std::uint32_t> start;    ///< [N + 1], CSR offsets into `neighbours`
  std::span<const ParticleId> neighbours;  ///< the neighbours of i are neighbours[start[i] .. start[i + 1])
  std::span<const std::uint8_t> opened;    ///< [N] or empty: non-zero where a particle lost a connector
};

/// Estimates particles' surfaces (see the file notes). Keeps scratch between calls: estimating a few
/// particles costs their four-hop surface patches, never the whole index space.
class SurfaceEstimator {
 public:
  /// The estimates of `targets` (indices into the neighbourhood), in their order. With `kinds` (ParticleFlag
  /// bits per target, e.g. those a deformable body had at rest), a sheet or a chain stays one however it is
  /// bent: only its normal (or direction) follows the current positions.
  /// `reach`: how many connector hops along the surface a particle's plane or quadric is fitted over (four
  /// averages a staircase across the lattice best; bodies that deform, estimated every few steps, use two).
  void estimate(const Neighbourhood& nb, std::span<const ParticleId> targets, std::vector<SurfaceEstimate>& out,
                std::span<const std::uint8_t> kinds = {}, int reach = kSurfaceReach);
  /// After `estimate` over every particle of a body (`out` in index order): the body's flat faces, grown
  /// over its surface particles from those whose own fit is planar, replace the local estimates of the
  /// particles on them (one face: its plane; two: an edge; three or more: a corner).
  void joinFaces(const Neighbourhood& nb, std::vector<SurfaceEstimate>& out);

 private:
  struct Raw {
    Vec3 missing = Vec3::Zero();
    Vec3 axis = Vec3::Zero();  // sheet: its normal; line: its direction
    double meanDistance = 0.0;
    double spacing = 0.0;      // the nearest neighbour's distance
    std::uint8_t kind = 0;     // kInterior, kVolume, kSheet, kRim, kLine, kPoint
  };
  struct Fit {
    bool planar = false;
    Vec3 normal = Vec3::Zero();
  };
  const Raw& raw(const Neighbourhood& nb, std::uint32_t i);
  /// The principal axes of i's neighbour offsets: [0] the normal of their best-fit plane through i, [2] the
  /// direction of their best-fit line.
  [[nodiscard]] static Mat3 neighbourAxes(const Neighbourhood& nb, std::uint32_t i);
  const Fit& fit(const Neighbourhood& nb, std::uint32_t i);
  /// i and the particles within `hops` connectors of it (with `crack`, only through particles that lost a
  /// connector).
  void ring(const Neighbourhood& nb, std::uint32_t i, int hops, bool crack, std::vector<std::uint32_t>& out,
            bool surface = false);
  void grow(std::size_t n);

  void nextMark();
  /// Grows the face through `seed` whose plane starts along `normal`; true (members_ its particles, `normal`
  /// its plane) where it is one, false where the particles are no face (too few, not flat, a lattice facet
  /// of a curved surface).
  bool growFace(const Neighbourhood& nb, std::uint32_t seed, Vec3& normal);
  /// After the flat faces: each connected curved surface that is one rounded core (a sphere, a cylinder's
  /// side, a capsule) takes its normals from the core fitted to the whole of it.
  void joinCurved(const Neighbourhood& nb, std::vector<SurfaceEstimate>& out);

  std::vector<Vec3> curvedPoints_, curvedNormals_;

  std::vector<std::uint32_t> regionOf_, members_, beyond_, beyondMark_;
  std::vector<std::uint8_t> regionCount_;
  std::vector<Vec3> faceNormals_;
  std::vector<std::uint32_t> faceSizes_;
  std::vector<double> turns_;

  std::vector<Raw> raw_;
  std::vector<Fit> fit_;
  std::vector<std::uint32_t> rawStamp_, fitStamp_, mark_;
  std::uint32_t stamp_ = 0, markStamp_ = 0;
  int reach_ = kSurfaceReach;

  std::vector<std::uint32_t> ring_, fitRing_, wideRing_;
  std::vector<Vec3> points_;
};

/// Estimates every particle of a cloud given by positions and connector pairs (i, j).
[[nodiscard]] std::vector<SurfaceEstimate> estimateSurface(std::span<const Vec3> positions,
                                                           std::span<const std::array<std::uint32_t, 2>> connectors);

}  // namespace volpar
