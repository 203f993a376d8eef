// pile_bench: the canonical pile-N scene stepped by volpar, by Bullet (Debian's libbullet 3.24, its Bullet 2
// rigid-body API) and, when built with it, by Jolt Physics (5.5.0 from source) in the same run, interleaved, with
// the quality of the end state next to the speed.
//
// pile-N (scenes/bench/pile-1000.yaml is pile-1000):
//   - N rigid bodies, each a 3 x 3 x 3 cubic lattice of spheres: radius 0.05 m, centre spacing 0.1 m, 0.1 kg
//     per sphere (2.7 kg per body); inertia of the solid 0.3 m cube the 27 lattice cells tile (0.0405 kg m^2
//     about every axis)
//   - at rest; body i turned about the world z axis by 0.37 i rad, then about the world x axis by 0.11 i rad
//     (q = Rx(0.11 i) Rz(0.37 i)); with k = ceil(cbrt(N)) its centre is
//     x = (i mod k - (k-1)/2) 0.45, y = ((i div k) mod k - (k-1)/2) 0.45, z = 0.5 + (i div k^2) 0.45 [m]
//   - a ground plane z = 0 and four walls x, y = +-(0.45 k / 2 + 0.3) m, normals inward
//   - gravity (0, 0, -9.81) m/s^2, dt = 1/240 s, 10 solver iterations, restitution 0.1 and friction 0.5
//     everywhere, no sleeping
// (the constants and the layout: pile_spec.hpp)
//
// Variants:
//   volpar           the world built from scene text generated for N (parseScene + buildScene), World::step()
//   volpar-mt        the same world with World::setThreads(T)
//   box              Bullet: one btBoxShape of half extents 0.15 m (default margin) per body, static planes
//                    (what a Bullet user would pick for a crate)
//   compound-planes  Bullet: one btCompoundShape of 27 btSphereShape(0.05) per body (shapes shared by all
//                    bodies), static planes
//   compound-boxes   Bullet: the compound bodies, ground and walls as static boxes 1 m thick
//   jolt-box         Jolt: one JPH::BoxShape of half extent 0.15 m per body (Jolt's default convex radius,
//                    0.05 m, rounds its edges), static planes, on one thread
//   jolt-box-mt      the same on T threads
//   jolt-compound    Jolt: one JPH::StaticCompoundShape of 27 SphereShape(0.05) at the lattice offsets, shared
//                    by all bodies, static planes, on one thread
//   jolt-compound-mt the same on T threads
// The Jolt variants exist when pile_bench is built with VOLPAR_JOLT_SOURCE (tools/bench/CMakeLists.txt).
// Every Bullet and Jolt body has mass 2.7 kg and the 27-sphere inertia (not the box shape's own), so the
// dynamics of all variants are comparable.
//
// Bullet (pile_bullet.cpp) runs btDbvtBroadphase, btDefaultCollisionConfiguration, btCollisionDispatcher,
// btSequentialImpulseConstraintSolver (10 iterations, other solver settings at their defaults) and
// btDiscreteDynamicsWorld, stepSimulation(dt, 0) (exactly one step of dt per call), every body
// DISABLE_DEACTIVATION, friction sqrt(0.5) and restitution sqrt(0.1) on every object, static ones included
// (Bullet multiplies the two objects' coefficients). Bodies have no motion state: the poses are read from the
// bodies.
//
// Jolt (pile_jolt.cpp) runs a PhysicsSystem with its default PhysicsSettings: 10 velocity and 2 position
// iterations (volpar and Bullet: 10 iterations), Baumgarte 0.2, penetration slop 0.02 m, speculative contact
// distance 0.02 m, restitution applied only to impacts faster than 1 m/s. Gravity (0, 0, -9.81) m/s^2 set on the
// system (z up), one PhysicsSystem::Update(dt, 1 collision step) per step, a JobSystemThreadPool with
// threads - 1 workers (the calling thread runs jobs too, as in Jolt's PerformanceTest), a TempAllocatorImpl
// sized for the bodies' contacts, two object layers (static, moving) in two broad phase layers as in Jolt's
// HelloWorld, OptimizeBroadPhase() after adding the bodies. Ground and walls are static bodies with
// JPH::PlaneShape at volpar's planes (the solid half space behind each). Every body, static ones included, has
// friction 0.5 and restitution 0.1 (Jolt combines the two bodies' as the geometric mean and the maximum: 0.5
// and 0.1); the dynamic ones have the crate's mass and inertia (EOverrideMassProperties::MassAndInertiaProvided),
// no damping (Jolt's default, 0.05 1/s linear and angular, is set to 0: the scene has none, nor do volpar and
// Bullet) and mAllowSleeping false. An Update that reports a full buffer stops the run with that error.
//
// Each repeat runs every variant in turn: build the world (untimed), step it `steps` times (timed with
// steady_clock, the stepping loop alone, and within it the first kCollapseSteps = 480 steps, the collapse, by a
// clock read as step 480 begins; the whole run when steps <= 480), then measure the end state:
//   kinetic energy   volpar: World::energy().kinetic; Bullet and Jolt: sum of 1/2 m v^2 + 1/2 w^T I w [J]
//   max penetration  volpar: the deepest touching contact (particle-particle or particle-plane) in
//                    World::contacts() after the last step, which describes the state the step produced
//                    (the same value as World::stats().maxPenetration); Bullet: collision detection is run
//                    once more on the final poses (untimed), then the largest -getDistance() over all
//                    points of the dispatcher's manifolds; Jolt: every dynamic body's shape collided with
//                    the world at its pose (NarrowPhaseQuery::CollideShape, the body itself excluded,
//                    untimed), the largest penetration depth [m]
//   escaped          bodies whose centre is outside the walls or below z = 0
//   highest          the highest body centre [m]
//   max v            the speed of the fastest body centre [m/s]
// The deepest overlap before the first step is measured the same way, untimed (for Bullet this runs its
// collision detection once before the loop; the first step finds the same contacts). volpar's scene builder
// refuses overlapping bodies; Bullet's boxes, whose corners reach 0.26 m from the centre while neighbouring
// centres are 0.45 m apart, may start overlapping.
//
// Before timing, the harness checks that the volpar, Bullet and Jolt worlds start from the same state (every
// Bullet sphere centre and every Jolt lattice site, from the body's centre-of-mass transform, against volpar's
// particle centres, and the mass and inertia each engine reports), and for N = 1000 that the generated scene
// gives the particle positions of scenes/bench/pile-1000.yaml. `--self-check` runs only these checks. The
// program exits with status 1 when a check fails, a run became non-finite or an engine reported an error.
//
// `--memory` measures instead of timing: for every N and variant a fresh process of this program
// (`--memory-run`) builds the world and steps it `steps` times; its peak resident size (VmHWM) less what it
// held before building (VmRSS) is the variant's memory, printed in MiB and per body.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <unistd.h>

#include "tools/bench/pile_bullet.hpp"
#include "tools/bench/pile_spec.hpp"
#ifdef VOLPAR_PILE_HAS_JOLT
#include "tools/bench/pile_jolt.hpp"
#endif
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "volpar/engine/world.hpp"

#ifndef VOLPAR_SOURCE_DIR
#define VOLPAR_SOURCE_DIR "."
#endif

namespace {

using namespace pile;  // the scene (pile_spec.hpp) and the peers' worlds (pile_bullet.hpp, pile_jolt.hpp)
using Clock = std::chrono::steady_clock;

// ---------------------------------------------------------------------------------------------------
// the scene

/// Shortest decimal text that reads back as the same double.
std::string num(double v) {
  std::array<char, 32> buf{};
  std::snprintf(buf.data(), buf.size(), "%.17g", v);
  return buf.data();
}

/// pile-N in the scene format (docs/scene-format.md): the full layers of the grid as one `repeat` with
/// `rotation_step`, as scenes/bench/pile-1000.yaml writes them, and the bodies of a last, partial layer
/// one by one with their position and orientation.
std::string pileSceneText(const PileLayout& pile, int steps) {
  const std::string crate =
      "shape: {box: {size: [0.3, 0.3, 0.3]}}, fill: {lattice: cubic, radius: " + num(kRadius) +
      ", spacing: " + num(kSpacing) + "}, particle_mass: " + num(kSphereMass) + ", material: crate";
  std::ostringstream s;
  s << "name: pile-" << pile.n << "\n"
    << "dt: " << num(kDt) << "\n"
    << "steps: " << steps << "\n"
    << "gravity: [0, 0, " << num(-kGravity) << "]\n"
    << "solver: {iterations: " << kIterations << "}\n"
    << "materials:\n"
    << "  crate: {density: 1000, restitution: " << num(kRestitution) << ", friction: " << num(kFriction) << "}\n"
    << "planes:\n"
    << "  - {normal: [0, 0, 1], offset: 0, material: crate}\n"
    << "  - {normal: [1, 0, 0], offset: " << num(-pile.wall) << ", material: crate}\n"
    << "  - {normal: [-1, 0, 0], offset: " << num(-pile.wall) << ", material: crate}\n"
    << "  - {normal: [0, 1, 0], offset: " << num(-pile.wall) << ", material: crate}\n"
    << "  - {normal: [0, -1, 0], offset: " << num(-pile.wall) << ", material: crate}\n"
    << "bodies:\n";
  const int layer = pile.k * pile.k;
  const int fullLayers = pile.n / layer;
  if (fullLayers > 0) {
    const Vec3& first = pile.centre[0];
    s << "  - {name: crate, " << crate << ", position: [" << num(first.x()) << ", " << num(first.y()) << ", "
      << num(first.z()) << "], repeat: {count: [" << pile.k << ", " << pile.k << ", " << fullLayers
      << "], spacing: [" << num(kGridSpacing) << ", " << num(kGridSpacing) << ", " << num(kGridSpacing)
      << "], rotation_step: [{axis: [0, 0, 1], angle: " << num(kTurnZ) << "}, {axis: [1, 0, 0], angle: "
      << num(kTurnX) << "}]}}\n";
  }
  for (int i = fullLayers * layer; i < pile.n; ++i) {
    const Vec3& c = pile.centre[static_cast<std::size_t>(i)];
    s << "  - {name: crate_" << i << ", " << crate << ", position: [" << num(c.x()) << ", " << num(c.y()) << ", "
      << num(c.z()) << "], orientation: [{axis: [0, 0, 1], angle: " << num(kTurnZ * i)
      << "}, {axis: [1, 0, 0], angle: " << num(kTurnX * i) << "}]}\n";
  }
  return s.str();
}

// ---------------------------------------------------------------------------------------------------
// what a run measures (Quality: pile_spec.hpp)

struct Run {
  int n = 0;
  std::string variant;
  int repeat = 0;
  int steps = 0;
  int threads = 1;
  double seconds = 0.0;          ///< the stepping loop alone [s]
  int collapseSteps = 0;         ///< min(steps, kCollapseSteps)
  double collapseSeconds = 0.0;  ///< the loop's first collapseSteps steps [s]
  Quality quality;
};

/// Calls `step` (false: the run went wrong, stop) `steps` times, timing the whole loop and its first
/// kCollapseSteps steps (a clock read as step kCollapseSteps begins; the whole loop when it has no more).
template <class Step>
void timeSteps(Run& run, int steps, Step&& step) {
  const auto t0 = Clock::now();
  auto tCollapse = t0;
  bool collapseRead = false;
  for (int s = 0; s < steps; ++s) {
    if (s == kCollapseSteps) {
      tCollapse = Clock::now();
      collapseRead = true;
    }
    if (!step()) break;
  }
  const auto t1 = Clock::now();
  run.steps = steps;
  run.seconds = std::chrono::duration<double>(t1 - t0).count();
  run.collapseSteps = std::min(steps, kCollapseSteps);
  run.collapseSeconds = collapseRead ? std::chrono::duration<double>(tCollapse - t0).count() : run.seconds;
}

// ---------------------------------------------------------------------------------------------------
// volpar

/// The volpar world of pile-N, built from generated scene text.
volpar::Result<volpar::BuiltScene> buildVolparPile(const PileLayout& pile, int steps) {
  auto desc = volpar::parseScene(pileSceneText(pile, steps), "pile-" + std::to_string(pile.n) + ".yaml");
  if (!desc) return desc.error();
  return volpar::buildScene(*desc);
}

/// The deepest touching contact of the world's current state [m] (0 when nothing overlaps).
double volparDeepest(const volpar::World& world) {
  double deepest = 0.0;
  for (const volpar::ParticleContact& c : world.contacts().contacts)
    if (c.touching()) deepest = std::max(deepest, c.depth);
  return deepest;
}

Run runVolpar(const PileLayout& pile, int steps, int threads) {
  Run run;
  auto built = buildVolparPile(pile, steps);
  if (!built) {
    std::fprintf(stderr, "pile_bench: %s\n", built.error().toString().c_str());
    std::exit(1);
  }
  volpar::World& world = built->world;
  world.setThreads(threads);
  run.threads = threads;
  run.quality.initialPenetration = volparDeepest(world);

  timeSteps(run, steps, [&] {
    if (!volpar::hasFlag(world.step(), volpar::StepStatus::NonFinite)) return true;
    run.quality.finite = false;
    return false;
  });

  Quality& q = run.quality;
  q.kinetic = world.energy().kinetic;
  q.maxPenetration = volparDeepest(world);
  CentreTally tally(pile.wall);
  const volpar::BodyStore& bodies = world.bodies();
  for (std::size_t b = 0; b < bodies.size(); ++b)
    if (bodies.info[b].alive) tally.add(bodies.state[b].position, bodies.state[b].linearVelocity);
  tally.into(q);
  return run;
}

// ---------------------------------------------------------------------------------------------------
// Bullet (pile_bullet.cpp) and Jolt (pile_jolt.cpp)

Run runBullet(const PileLayout& pile, int steps, BulletSetup setup) {
  Run run;
  BulletPile world(pile, setup);
  run.quality.initialPenetration = world.deepest();
  timeSteps(run, steps, [&] {
    world.step();
    return true;
  });
  world.measure(run.quality);
  run.quality.maxPenetration = world.deepest();
  return run;
}

#ifdef VOLPAR_PILE_HAS_JOLT
Run runJolt(const PileLayout& pile, int steps, JoltShape shape, int threads) {
  Run run;
  run.threads = threads;
  JoltPile world(pile, shape, threads);
  run.quality.initialPenetration = world.deepest();
  timeSteps(run, steps, [&] { return world.step(); });
  world.measure(run.quality);
  run.quality.maxPenetration = world.deepest();
  return run;
}
#endif

// ---------------------------------------------------------------------------------------------------
// checks

bool gCheckFailed = false;

void report(bool ok, const std::string& line) {
  std::printf("check %s %s\n", ok ? "ok      " : "MISMATCH", line.c_str());
  if (!ok) gCheckFailed = true;
}

/// `v` with `digits` decimals, fixed (1.234) or in scientific notation (1.234e-05).
std::string fixed(double v, int digits) {
  std::array<char, 64> buf{};
  std::snprintf(buf.data(), buf.size(), "%.*f", digits, v);
  return buf.data();
}
std::string sci(double v, int digits) {
  std::array<char, 64> buf{};
  std::snprintf(buf.data(), buf.size(), "%.*e", digits, v);
  return buf.data();
}

/// How far a peer's world starts from volpar's: the largest distance from one of a body's sphere centres to the
/// nearest particle of the same volpar body [m], and the largest mass [kg] and inertia [kg m^2] errors.
struct StartDifference {
  double position = 0.0, mass = 0.0, inertia = 0.0;
};

template <class Peer>
StartDifference startDifference(const volpar::World& world, const Peer& peer) {
  StartDifference d;
  const volpar::BodyStore& bodies = world.bodies();
  const Mat3 inertia = latticeInertia().asDiagonal();
  for (std::size_t b = 0; b < bodies.size(); ++b) {
    for (const Vec3& c : peer.sphereCentres(b)) {
      double nearest = 1e300;
      for (const volpar::ParticleId p : bodies.info[b].particles)
        nearest = std::min(nearest, (world.particles().position[p.index()] - c).norm());
      d.position = std::max(d.position, nearest);
    }
    d.mass = std::max(d.mass, std::abs(peer.mass(b) - kBodyMass));
    d.inertia = std::max(d.inertia, (peer.localInertia(b) - inertia).cwiseAbs().maxCoeff());
  }
  return d;
}

/// The volpar world of pile-N holds its bodies as specified, and the Bullet and Jolt worlds start from the same
/// state: every sphere centre of theirs lies on a volpar particle of the same body, and the masses and inertias
/// agree.
void checkSameStart(const PileLayout& pile) {
  constexpr double kTol = 1e-5;         // [m] Bullet's btScalar may be float; Jolt's positions are floats
  constexpr double kMassTol = 1e-6;     // [kg] a float's inverse mass, inverted
  constexpr double kInertiaTol = 1e-6;  // [kg m^2]
  const std::string name = "pile-" + std::to_string(pile.n);
  auto built = buildVolparPile(pile, 1);
  if (!built) {
    report(false, name + ": " + built.error().toString());
    return;
  }
  const volpar::World& world = built->world;
  const volpar::BodyStore& bodies = world.bodies();
  bool countsOk = bodies.size() == static_cast<std::size_t>(pile.n) && world.particles().size() == pile.particles();
  double worstMass = 0.0, worstInertia = 0.0;  // volpar's own
  for (std::size_t b = 0; countsOk && b < bodies.size(); ++b) {
    countsOk = countsOk && bodies.info[b].particles.size() == static_cast<std::size_t>(kSpheresPerBody);
    worstMass = std::max(worstMass, std::abs(bodies.info[b].mass - kBodyMass));
    worstInertia = std::max(worstInertia, (bodies.info[b].inertiaLocal - latticeInertia()).cwiseAbs().maxCoeff());
  }
  if (!countsOk) {
    report(false, name + ": volpar built " + std::to_string(bodies.size()) + " bodies, " +
                      std::to_string(world.particles().size()) + " particles");
    return;
  }
  const auto line = [&](const std::string& peer, const StartDifference& d) {
    report(d.position < kTol && d.mass < kMassTol && d.inertia < kInertiaTol,
           name + ": volpar and " + peer + " start alike: sphere centres within " + sci(d.position, 2) +
               " m, mass within " + sci(d.mass, 1) + " kg, inertia within " + sci(d.inertia, 1) + " kg m^2");
  };
  report(worstMass < 1e-12 && worstInertia < 1e-6,
         name + ": volpar's world: " + std::to_string(bodies.size()) + " bodies, " +
             std::to_string(world.particles().size()) + " particles, mass " + fixed(kBodyMass, 1) +
             " kg within " + sci(worstMass, 1) + ", inertia " + fixed(latticeInertia().x(), 5) +
             " kg m^2 per axis within " + sci(worstInertia, 1));
  line("Bullet (compound-planes)", startDifference(world, BulletPile(pile, BulletSetup::CompoundPlanes)));
#ifdef VOLPAR_PILE_HAS_JOLT
  line("Jolt (jolt-box, lattice sites)", startDifference(world, JoltPile(pile, JoltShape::Box, 1)));
  line("Jolt (jolt-compound, its children)", startDifference(world, JoltPile(pile, JoltShape::Compound, 1)));
#endif
}

/// The generated pile-1000 gives the particles and planes of scenes/bench/pile-1000.yaml.
void checkAgainstFile(const PileLayout& pile) {
  const std::string path = std::string(VOLPAR_SOURCE_DIR) + "/scenes/bench/pile-1000.yaml";
  auto fileDesc = volpar::loadScene(path);
  if (!fileDesc) {
    report(false, fileDesc.error().toString());
    return;
  }
  auto fromFile = volpar::buildScene(*fileDesc);
  auto generated = buildVolparPile(pile, 1);
  if (!fromFile || !generated) {
    report(false, "pile-1000: " + (fromFile ? generated.error() : fromFile.error()).toString());
    return;
  }
  const volpar::ParticleStore& a = generated->world.particles();
  const volpar::ParticleStore& b = fromFile->world.particles();
  bool ok = a.size() == b.size() && generated->world.planes().size() == fromFile->world.planes().size();
  double worst = 0.0;
  for (std::size_t p = 0; ok && p < a.size(); ++p) {
    worst = std::max(worst, (a.position[p] - b.position[p]).cwiseAbs().maxCoeff());
    ok = ok && a.radius[p] == b.radius[p] && a.mass[p] == b.mass[p] && a.body[p] == b.body[p];
  }
  for (std::size_t k = 0; ok && k < generated->world.planes().size(); ++k) {
    const volpar::Plane& pa = generated->world.planes()[k];
    const volpar::Plane& pb = fromFile->world.planes()[k];
    worst = std::max({worst, (pa.normal - pb.normal).cwiseAbs().maxCoeff(), std::abs(pa.offset - pb.offset)});
  }
  const volpar::WorldSettings& sa = generated->world.settings();
  const volpar::WorldSettings& sb = fromFile->world.settings();
  ok = ok && worst < 1e-12 && sa.dt == sb.dt && sa.gravity == sb.gravity && sa.solverIterations == sb.solverIterations;
  report(ok, "pile-1000: the generated scene builds the world of scenes/bench/pile-1000.yaml: " +
                 std::to_string(a.size()) + " particles, 5 planes, dt, gravity and iterations alike, largest "
                 "coordinate difference " + sci(worst, 2) + " m");
}

// ---------------------------------------------------------------------------------------------------
// the machine and the summary

std::string cpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) {
      const auto colon = line.find(':');
      if (colon != std::string::npos) return line.substr(colon + 2);
    }
  return "unknown";
}

std::string loadAverage() {
  std::ifstream in("/proc/loadavg");
  std::string one, five, fifteen;
  in >> one >> five >> fifteen;
  return one + " " + five + " " + fifteen;
}

std::string now() {
  const std::time_t t = std::time(nullptr);
  std::tm local{};
  localtime_r(&t, &local);
  std::array<char, 64> buf{};
  std::strftime(buf.data(), buf.size(), "%Y-%m-%d %H:%M:%S %Z", &local);
  return buf.data();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

/// The runs of one variant at one N, summarised.
struct Summary {
  std::string variant;
  double medianSeconds = 0.0, minSeconds = 0.0, maxSeconds = 0.0;
  double stepsPerSecond = 0.0;          ///< at the median time
  double medianCollapseSeconds = 0.0;   ///< of the first kCollapseSteps steps [s]
  double collapseStepsPerSecond = 0.0;  ///< over those steps, at their median time
  Quality quality;                      ///< of the last repeat
  bool qualityVaries = false;           ///< the repeats did not end in the same state
  bool finite = true;
  std::string error;                    ///< the first error an engine reported in these runs
};

Summary summarise(const std::vector<Run>& runs) {
  Summary s;
  s.variant = runs.front().variant;
  std::vector<double> seconds, collapse;
  for (const Run& r : runs) {
    seconds.push_back(r.seconds);
    collapse.push_back(r.collapseSeconds);
    s.finite = s.finite && r.quality.finite;
    if (s.error.empty()) s.error = r.quality.error;
    const Quality& a = r.quality;
    const Quality& b = runs.front().quality;
    if (a.kinetic != b.kinetic || a.maxPenetration != b.maxPenetration || a.escaped != b.escaped ||
        a.highest != b.highest || a.maxSpeed != b.maxSpeed)
      s.qualityVaries = true;
  }
  s.medianSeconds = median(seconds);
  s.minSeconds = *std::min_element(seconds.begin(), seconds.end());
  s.maxSeconds = *std::max_element(seconds.begin(), seconds.end());
  s.stepsPerSecond = runs.front().steps / s.medianSeconds;
  s.medianCollapseSeconds = median(collapse);
  s.collapseStepsPerSecond = runs.front().collapseSteps / s.medianCollapseSeconds;
  s.quality = runs.back().quality;
  return s;
}

bool isVolpar(const std::string& variant) { return variant.rfind("volpar", 0) == 0; }

/// Ratios of the median steps/s (`rate`), volpar's variants over every peer variant and over the fastest
/// compound setup of any peer (above 1: volpar is faster).
void printRatios(const std::string& title, const std::vector<Summary>& summaries, double Summary::*rate) {
  std::vector<const Summary*> ours, theirs;
  const Summary* fastestCompound = nullptr;
  for (const Summary& s : summaries) {
    (isVolpar(s.variant) ? ours : theirs).push_back(&s);
    if (s.variant.find("compound") != std::string::npos &&
        (!fastestCompound || s.*rate > fastestCompound->*rate))
      fastestCompound = &s;
  }
  if (ours.empty() || theirs.empty()) return;
  std::printf("steps/s ratio, %s (median volpar / median peer; above 1: volpar is faster)\n%-16s", title.c_str(), "");
  for (const Summary* b : theirs) std::printf(" %16s", b->variant.c_str());
  if (fastestCompound) std::printf("   fastest compound (%s)", fastestCompound->variant.c_str());
  std::printf("\n");
  for (const Summary* a : ours) {
    std::printf("%-16s", a->variant.c_str());
    for (const Summary* b : theirs) std::printf(" %16.3f", a->*rate / b->*rate);
    if (fastestCompound) std::printf("   %.3f", a->*rate / fastestCompound->*rate);
    std::printf("\n");
  }
}

void printTable(const PileLayout& pile, int steps, const std::vector<Summary>& summaries) {
  const int collapseSteps = std::min(steps, kCollapseSteps);
  const std::string collapseSecondsLabel = "0-" + std::to_string(collapseSteps) + " s";
  const std::string collapseRateLabel = "st/s 0-" + std::to_string(collapseSteps);
  std::printf("\npile-%d: %d bodies, %zu particles, k = %d, walls at +-%.3f m, %d steps of 1/240 s\n", pile.n,
              pile.n, pile.particles(), pile.k, pile.wall, steps);
  std::printf("%-16s %9s %21s %10s %10s %12s %16s %10s %11s %11s %11s %7s %11s %10s\n", "variant", "median s",
              "(min-max)", "steps/s", collapseSecondsLabel.c_str(), collapseRateLabel.c_str(), "particle-steps/s",
              "us/body-st", "KE [J]", "max pen [m]", "pen@0 [m]", "escaped", "highest [m]", "max v [m/s]");
  for (const Summary& s : summaries) {
    const double particleRate = s.stepsPerSecond * static_cast<double>(pile.particles());
    const double usPerBodyStep = 1e6 * s.medianSeconds / (static_cast<double>(steps) * pile.n);
    const Quality& q = s.quality;
    std::array<char, 48> range{};
    std::snprintf(range.data(), range.size(), "(%.4g-%.4g)", s.minSeconds, s.maxSeconds);
    std::printf("%-16s %9.4g %21s %10.1f %10.4g %12.1f %16.4g %10.3f %11.4g %11.3e %11.3e %7d %11.3f %11.3e%s%s%s%s\n",
                s.variant.c_str(), s.medianSeconds, range.data(), s.stepsPerSecond, s.medianCollapseSeconds,
                s.collapseStepsPerSecond, particleRate, usPerBodyStep, q.kinetic, q.maxPenetration,
                q.initialPenetration, q.escaped, q.highest, q.maxSpeed,
                s.qualityVaries ? "  (end state differs between repeats)" : "", s.finite ? "" : "  NON-FINITE",
                s.error.empty() ? "" : "  STOPPED: ", s.error.c_str());
  }
  std::printf("max pen %% of r:");
  for (const Summary& s : summaries)
    std::printf("  %s %.1f %%", s.variant.c_str(), 100.0 * s.quality.maxPenetration / kRadius);
  std::printf("\n");
  printRatios("whole run", summaries, &Summary::stepsPerSecond);
  if (steps > kCollapseSteps)
    printRatios("first " + std::to_string(kCollapseSteps) + " steps", summaries, &Summary::collapseStepsPerSecond);
}

void writeCsv(const std::string& path, const std::vector<Run>& runs) {
  std::ofstream out(path);
  if (!out) {
    std::fprintf(stderr, "pile_bench: cannot write %s\n", path.c_str());
    std::exit(1);
  }
  out << "n,particles,variant,repeat,steps,threads,seconds,steps_per_s,particle_steps_per_s,us_per_body_step,"
         "kinetic_energy_J,max_penetration_m,initial_penetration_m,escaped,highest_m,max_speed_m_per_s,finite,"
         "collapse_steps,collapse_seconds,collapse_steps_per_s,error\n";
  for (const Run& r : runs) {
    const double particles = static_cast<double>(r.n) * kSpheresPerBody;
    out << r.n << ',' << r.n * kSpheresPerBody << ',' << r.variant << ',' << r.repeat << ',' << r.steps << ','
        << r.threads << ',' << num(r.seconds) << ',' << num(r.steps / r.seconds) << ','
        << num(particles * r.steps / r.seconds) << ',' << num(1e6 * r.seconds / (static_cast<double>(r.steps) * r.n))
        << ',' << num(r.quality.kinetic) << ',' << num(r.quality.maxPenetration) << ','
        << num(r.quality.initialPenetration) << ',' << r.quality.escaped << ',' << num(r.quality.highest) << ','
        << num(r.quality.maxSpeed) << ',' << (r.quality.finite ? 1 : 0) << ',' << r.collapseSteps << ','
        << num(r.collapseSeconds) << ',' << num(r.collapseSteps / r.collapseSeconds) << ',' << r.quality.error
        << '\n';
  }
}

// ---------------------------------------------------------------------------------------------------
// command line

const std::vector<std::string> kBulletVariants = {"box", "compound-planes", "compound-boxes"};
const std::vector<std::string> kJoltVariants = {"jolt-box", "jolt-box-mt", "jolt-compound", "jolt-compound-mt"};
#ifdef VOLPAR_PILE_HAS_JOLT
constexpr bool kHasJolt = true;
#else
constexpr bool kHasJolt = false;
#endif

/// The variants this build runs, in the order of a run.
std::vector<std::string> allVariants() {
  std::vector<std::string> out = {"volpar", "volpar-mt"};
  out.insert(out.end(), kBulletVariants.begin(), kBulletVariants.end());
  if (kHasJolt) out.insert(out.end(), kJoltVariants.begin(), kJoltVariants.end());
  return out;
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ",") + item;
  return out;
}

struct Options {
  std::vector<int> n = {125, 1000, 8000, 27000};
  std::optional<int> steps, repeats;
  std::vector<std::string> variants = allVariants();
  int threads = 2;
  std::string csv;
  bool quick = false;
  bool selfCheck = false;
  bool memory = false;     ///< --memory: each variant's peak memory, in a process of its own
  bool memoryOne = false;  ///< (--memory-run: this process is one such measurement)
};

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: pile_bench [options]\n"
               "  --n LIST          body counts, comma-separated (default 125,1000,8000,27000)\n"
               "  --steps S         steps per run (default 2000)\n"
               "  --repeats R       runs of every variant per N, interleaved (default 3)\n"
               "  --variants LIST   of %s (default all)%s\n"
               "  --threads T       threads of volpar-mt%s (default 2)\n"
               "  --csv FILE        write every run, one row per run\n"
               "  --quick           smoke run: 200 steps, 1 repeat (unless --steps/--repeats say otherwise)\n"
               "  --self-check      only check the generated worlds (volpar vs Bullet%s, pile-1000 vs its file)\n"
               "  --memory          instead of timing: every variant's memory, each N and variant stepped once for\n"
               "                    --steps in a fresh process of this program (its peak resident memory less what\n"
               "                    it held before building the world), per body\n",
               joined(allVariants()).c_str(),
               kHasJolt ? ""
                        : "\n                    (jolt-box, jolt-box-mt, jolt-compound, jolt-compound-mt: build "
                          "with VOLPAR_JOLT_SOURCE)",
               kHasJolt ? ", jolt-box-mt and jolt-compound-mt" : "", kHasJolt ? " and Jolt" : "");
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

/// A whole positive integer, or nothing.
std::optional<int> positive(const std::string& text) {
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end != '\0' || v < 1 || v > 100'000'000) return std::nullopt;
  return static_cast<int>(v);
}

/// Parses the command line; prints the problem and returns nothing on bad input.
std::optional<Options> parseOptions(int argc, char** argv) {
  Options o;
  const std::vector<std::string> args(argv + 1, argv + argc);
  for (std::size_t i = 0; i < args.size(); ++i) {
    std::string key = args[i], value;
    const auto eq = key.find('=');
    const bool inlineValue = key.rfind("--", 0) == 0 && eq != std::string::npos;
    if (inlineValue) {
      value = key.substr(eq + 1);
      key = key.substr(0, eq);
    }
    const auto next = [&]() -> std::optional<std::string> {
      if (inlineValue) return value;
      if (i + 1 < args.size()) return args[++i];
      std::fprintf(stderr, "pile_bench: %s needs a value\n", key.c_str());
      return std::nullopt;
    };
    const auto count = [&](std::optional<int>& into) {
      const auto v = next();
      if (!v) return false;
      into = positive(*v);
      if (!into) std::fprintf(stderr, "pile_bench: %s expects a positive integer, got '%s'\n", key.c_str(), v->c_str());
      return into.has_value();
    };
    if (key == "--help" || key == "-h") {
      usage(stdout);
      std::exit(0);
    } else if (key == "--quick") {
      o.quick = true;
    } else if (key == "--self-check") {
      o.selfCheck = true;
    } else if (key == "--memory") {
      o.memory = true;
    } else if (key == "--memory-run") {
      o.memoryOne = true;
    } else if (key == "--steps") {
      if (!count(o.steps)) return std::nullopt;
    } else if (key == "--repeats") {
      if (!count(o.repeats)) return std::nullopt;
    } else if (key == "--threads") {
      std::optional<int> t;
      if (!count(t)) return std::nullopt;
      o.threads = *t;
    } else if (key == "--csv") {
      const auto v = next();
      if (!v) return std::nullopt;
      o.csv = *v;
    } else if (key == "--n") {
      const auto v = next();
      if (!v) return std::nullopt;
      o.n.clear();
      for (const std::string& item : split(*v)) {
        const auto n = positive(item);
        if (!n) {
          std::fprintf(stderr, "pile_bench: --n expects positive integers, got '%s'\n", item.c_str());
          return std::nullopt;
        }
        o.n.push_back(*n);
      }
      if (o.n.empty()) return std::nullopt;
    } else if (key == "--variants") {
      const auto v = next();
      if (!v) return std::nullopt;
      o.variants = split(*v);
      const std::vector<std::string> known = allVariants();
      for (const std::string& name : o.variants)
        if (std::find(known.begin(), known.end(), name) == known.end()) {
          const bool jolt = std::find(kJoltVariants.begin(), kJoltVariants.end(), name) != kJoltVariants.end();
          std::fprintf(stderr, "pile_bench: %s variant '%s'%s\n", jolt ? "no" : "unknown", name.c_str(),
                       jolt ? ": this pile_bench was built without Jolt (CMake's VOLPAR_JOLT_SOURCE)" : "");
          return std::nullopt;
        }
      if (o.variants.empty()) return std::nullopt;
    } else {
      std::fprintf(stderr, "pile_bench: unknown option '%s'\n", args[i].c_str());
      usage(stderr);
      return std::nullopt;
    }
  }
  return o;
}

Run runVariant(const PileLayout& pile, const std::string& variant, int steps, int threads) {
  if (variant == "volpar") return runVolpar(pile, steps, 1);
  if (variant == "volpar-mt") return runVolpar(pile, steps, threads);
  if (variant == "box") return runBullet(pile, steps, BulletSetup::Box);
  if (variant == "compound-planes") return runBullet(pile, steps, BulletSetup::CompoundPlanes);
#ifdef VOLPAR_PILE_HAS_JOLT
  if (variant == "jolt-box") return runJolt(pile, steps, JoltShape::Box, 1);
  if (variant == "jolt-box-mt") return runJolt(pile, steps, JoltShape::Box, threads);
  if (variant == "jolt-compound") return runJolt(pile, steps, JoltShape::Compound, 1);
  if (variant == "jolt-compound-mt") return runJolt(pile, steps, JoltShape::Compound, threads);
#endif
  return runBullet(pile, steps, BulletSetup::CompoundBoxes);
}

/// A line "Name:   N kB" of /proc/self/status, in bytes (0 when absent).
std::size_t statusBytes(const char* name) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string key = std::string(name) + ":";
  while (std::getline(in, line))
    if (line.rfind(key, 0) == 0) return static_cast<std::size_t>(std::strtoull(line.c_str() + key.size(), nullptr, 10)) * 1024;
  return 0;
}

/// --memory-run: one variant at one N in this process; prints "memory BEFORE PEAK" [bytes] (resident before
/// building the world, the peak resident size after stepping it).
int memoryRun(const Options& o, int steps) {
  const std::size_t before = statusBytes("VmRSS");
  const PileLayout pile(o.n.front());
  const Run run = runVariant(pile, o.variants.front(), steps, o.threads);
  std::printf("memory %zu %zu\n", before, statusBytes("VmHWM"));
  return run.quality.finite && run.quality.error.empty() ? 0 : 1;
}

/// --memory: every N and variant measured by memoryRun in a child process of this program.
int memoryTable(const Options& o, int steps) {
  std::printf("\nmemory: peak resident size of a process that builds pile-N and steps it %d times, less what it "
              "held before building\n%8s %-18s %12s %14s\n", steps, "N", "variant", "peak [MiB]", "per body [KiB]");
  // (this program's own file: /proc/self/exe in the command would name the shell that popen runs)
  std::array<char, 4096> self{};
  const ssize_t length = readlink("/proc/self/exe", self.data(), self.size() - 1);
  if (length <= 0) {
    std::fprintf(stderr, "pile_bench: cannot find this program's file (/proc/self/exe)\n");
    return 1;
  }
  const std::string program(self.data(), static_cast<std::size_t>(length));
  bool ok = true;
  for (const int n : o.n)
    for (const std::string& variant : o.variants) {
      const std::string command = "'" + program + "' --memory-run --n " + std::to_string(n) + " --variants " + variant +
                                  " --steps " + std::to_string(steps) + " --threads " + std::to_string(o.threads);
      std::FILE* child = popen(command.c_str(), "r");
      std::size_t before = 0, peak = 0;
      std::array<char, 256> line{};
      while (child && std::fgets(line.data(), static_cast<int>(line.size()), child))
        if (std::sscanf(line.data(), "memory %zu %zu", &before, &peak) != 2) continue;
      const int status = child ? pclose(child) : -1;
      if (status != 0 || peak == 0) {
        std::printf("%8d %-18s failed (status %d)\n", n, variant.c_str(), status);
        ok = false;
        continue;
      }
      const double grown = static_cast<double>(peak - std::min(peak, before));
      std::printf("%8d %-18s %12.1f %14.2f\n", n, variant.c_str(), grown / (1024.0 * 1024.0), grown / 1024.0 / n);
      std::fflush(stdout);
    }
  return ok ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const auto parsed = parseOptions(argc, argv);
  if (!parsed) return 2;
  const Options& o = *parsed;
  const int steps = o.steps.value_or(o.quick ? 200 : 2000);
  const int repeats = o.repeats.value_or(o.quick ? 1 : 3);
  if (o.memoryOne) return memoryRun(o, steps);

  std::printf("pile_bench  %s\n", now().c_str());
  std::printf("machine: %u hardware threads, %s, load average %s\n", std::thread::hardware_concurrency(),
              cpuModel().c_str(), loadAverage().c_str());
  std::printf("bodies: mass %.1f kg, 27-sphere inertia %.5f kg m^2 per axis in every variant\n", kBodyMass,
              latticeInertia().x());
  std::printf("%s; box variant: static planes\n", bulletDescription().c_str());
#ifdef VOLPAR_PILE_HAS_JOLT
  std::printf("%s\n", joltDescription().c_str());
#else
  std::printf("Jolt: not built (CMake's VOLPAR_JOLT_SOURCE)\n");
#endif
  std::printf("steps %d (the first %d timed on their own as well), repeats %d, threads of the -mt variants %d\n",
              steps, std::min(steps, kCollapseSteps), repeats, o.threads);

  // the worlds start alike
  for (const int n : o.n) {
    const PileLayout pile(n);
    checkSameStart(pile);
    if (n == 1000) checkAgainstFile(pile);
  }
  std::fflush(stdout);
  if (o.selfCheck) return gCheckFailed ? 1 : 0;
  if (o.memory) return memoryTable(o, steps) != 0 || gCheckFailed ? 1 : 0;

  // per N: every repeat runs every variant in turn
  std::vector<Run> all;
  bool allOk = true;
  for (const int n : o.n) {
    const PileLayout pile(n);
    std::vector<std::vector<Run>> runs(o.variants.size());
    for (int r = 0; r < repeats; ++r)
      for (std::size_t v = 0; v < o.variants.size(); ++v) {
        Run run = runVariant(pile, o.variants[v], steps, o.threads);
        run.n = n;
        run.variant = o.variants[v];
        run.repeat = r;
        std::fprintf(stderr, "  pile-%d %-16s repeat %d: %.4g s (first %d steps %.4g s)%s%s\n", n,
                     run.variant.c_str(), r, run.seconds, run.collapseSteps, run.collapseSeconds,
                     run.quality.error.empty() ? "" : ": ", run.quality.error.c_str());
        allOk = allOk && run.quality.finite && run.quality.error.empty();
        runs[v].push_back(run);
        all.push_back(run);
      }
    std::vector<Summary> summaries;
    for (const auto& variantRuns : runs) summaries.push_back(summarise(variantRuns));
    printTable(pile, steps, summaries);
    std::fflush(stdout);
  }
  if (!o.csv.empty()) writeCsv(o.csv, all);
  return gCheckFailed || !allOk ? 1 : 0;
}
