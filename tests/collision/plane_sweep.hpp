#pragma once
// Random-pose sweeps of separating planes against the exact reference (tests/collision/plane_accuracy_test.cpp).
//
// Two bodies filled from convex solids are placed in random relative poses whose rounded solids (core plus
// particle radius, source_shape.hpp) overlap by between `minOverlap` and `maxOverlap` times the sum of the
// particle radii, and each pose's patches are compared with FCL's closest-point direction between the cores.
// With VOLPAR_SWEEP_DUMP=DEG in the environment, each pose whose largest patch is more than DEG degrees off is
// printed to stderr: its case, source and contact count, and the closest points, the normal and the reference
// in each body's own frame.

#include <array>
#include <map>
#include <string>
#include <vector>

#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/core/source_shape.hpp"
#include "volpar/engine/world.hpp"
#include "tests/support/test_support.hpp"

namespace volpar::test {

/// A body to sweep: its filled cloud and the solid it came from.
struct SweepShape {
  std::string name;
  SourceShape source;
  ParticleCloud cloud;
};

/// The solids of the sweep (each at least six particles across, the plate one particle thick), filled with
/// `lattice` at the given radius scale (1 = the defaults), with the builder's exact normals or, with
/// `estimated`, normals estimated from the particles alone.
[[nodiscard]] SweepShape sweepBox(Lattice lattice, bool estimated);
[[nodiscard]] SweepShape sweepSphere(Lattice lattice, bool estimated);
[[nodiscard]] SweepShape sweepCapsule(Lattice lattice, bool estimated);
[[nodiscard]] SweepShape sweepCylinder(Lattice lattice, bool estimated);
[[nodiscard]] SweepShape sweepMesh(Lattice lattice, bool estimated);   ///< a box mesh tilted against the lattice
[[nodiscard]] SweepShape sweepPlate(Lattice lattice, bool estimated);  ///< one particle thick

struct SweepSettings {
  int poses = 2000;
  unsigned seed = 7;
  double minOverlap = 0.05;  ///< [-] x (r_a + r_b)
  double maxOverlap = 0.75;
};

struct SweepStats {
  std::vector<double> all;                                    ///< angle of the largest patch [deg], per pose
  std::array<std::vector<double>, kPlaneCaseCount> byCase;    ///< the same, by that patch's case
  std::size_t patches = 0, unvalidated = 0, noContact = 0;
  std::size_t lookAheadDecided = 0;
  std::size_t convexViolations = 0;  ///< validated patches whose plane does not separate all particle centres
  std::size_t noReference = 0;
};

[[nodiscard]] SweepStats sweepPlanes(const SweepShape& a, const SweepShape& b, const SweepSettings& settings);
/// "n ... median ... p95 ... max ... deg"
[[nodiscard]] std::string summary(const std::vector<double>& v);
void printSweep(const std::string& name, const SweepStats& s);

}  // namespace volpar::test
