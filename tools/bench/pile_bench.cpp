// pile_bench: the canonical pile-N scene stepped by volpar and by Bullet (Debian's libbullet 3.24, its
// Bullet 2 rigid-body API) in the same run, interleaved, with the quality of the end state next to the speed.
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
//
// Variants:
//   volpar           the world built from scene text generated for N (parseScene + buildScene), World::step()
//   volpar-mt        the same world with World::setThreads(T)
//   box              Bullet: one btBoxShape of half extents 0.15 m (default margin) per body, static planes
//                    (what a Bullet user would pick for a crate)
//   compound-planes  Bullet: one btCompoundShape of 27 btSphereShape(0.05) per body (shapes shared by all
//                    bodies), static planes
//   compound-boxes   Bullet: the compound bodies, ground and walls as static boxes 1 m thick
// Every Bullet body has mass 2.7 kg and the 27-sphere inertia (not btBoxShape::calculateLocalInertia), so
// the dynamics of all variants are comparable. Bullet runs btDbvtBroadphase, btDefaultCollisionConfiguration,
// btCollisionDispatcher, btSequentialImpulseConstraintSolver (10 iterations, other solver settings at
// their defaults) and btDiscreteDynamicsWorld, stepSimulation(dt, 0) (exactly one step of dt per call),
// every body DISABLE_DEACTIVATION, friction sqrt(0.5) and restitution sqrt(0.1) on every object, static
// ones included (Bullet multiplies the two objects' coefficients). Bodies have no motion state: the poses
// are read from the bodies.
//
// Each repeat runs every variant in turn: build the world (untimed), step it `steps` times (timed with
// steady_clock, the stepping loop alone), then measure the end state:
//   kinetic energy   volpar: World::energy().kinetic; Bullet: sum of 1/2 m v^2 + 1/2 w^T I w [J]
//   max penetration  volpar: the deepest touching contact (particle-particle or particle-plane) in
//                    World::contacts() after the last step, which describes the state the step produced
//                    (the same value as World::stats().maxPenetration); Bullet: collision detection is run
//                    once more on the final poses (untimed), then the largest -getDistance() over all
//                    points of the dispatcher's manifolds [m]
//   escaped          bodies whose centre is outside the walls or below z = 0
//   highest          the highest body centre [m]
//   max v            the speed of the fastest body centre [m/s]
// The deepest overlap before the first step is measured the same way, untimed (for Bullet this runs its
// collision detection once before the loop; the first step finds the same contacts). volpar's scene builder
// refuses overlapping bodies; Bullet's boxes, whose corners reach 0.26 m from the centre while neighbouring
// centres are 0.45 m apart, may start overlapping.
//
// Before timing, the harness checks that the volpar and Bullet worlds start from the same state (every
// Bullet sphere centre against volpar's particle centres, and the inertia), and for N = 1000 that the
// generated scene gives the particle positions of scenes/bench/pile-1000.yaml. `--self-check` runs only
// these checks. The program exits with status 1 when a check fails or a run became non-finite.

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "volpar/engine/world.hpp"

#ifndef VOLPAR_SOURCE_DIR
#define VOLPAR_SOURCE_DIR "."
#endif

namespace {

using volpar::Quat;
using volpar::Vec3;
using Clock = std::chrono::steady_clock;

// ---------------------------------------------------------------------------------------------------
// the scene

constexpr int kLatticeSide = 3;                       // spheres per body edge
constexpr int kSpheresPerBody = 27;
constexpr double kRadius = 0.05;                      // [m] sphere radius
constexpr double kSpacing = 0.1;                      // [m] between sphere centres
constexpr double kSphereMass = 0.1;                   // [kg]
constexpr double kBodyMass = kSpheresPerBody * kSphereMass;  // [kg]
constexpr double kBoxHalf = 0.15;                     // [m] half side of the box the spheres fill
constexpr double kGridSpacing = 0.45;                 // [m] between body centres at start
constexpr double kLowestCentre = 0.5;                 // [m] height of the lowest layer of centres
constexpr double kWallGap = 0.3;                      // [m] from the outermost grid half width to a wall
constexpr double kTurnZ = 0.37;                       // [rad] per body index, about world z ...
constexpr double kTurnX = 0.11;                       // [rad] ... then about world x
constexpr double kDt = 1.0 / 240.0;                   // [s]
constexpr int kIterations = 10;
constexpr double kRestitution = 0.1;
constexpr double kFriction = 0.5;
constexpr double kGravity = 9.81;                     // [m/s^2], along -z

/// Offsets of the 27 sphere centres from the body centre, x fastest, then y, then z [m].
std::array<Vec3, kSpheresPerBody> latticeOffsets() {
  std::array<Vec3, kSpheresPerBody> out;
  for (int c = 0; c < kSpheresPerBody; ++c)
    out[static_cast<std::size_t>(c)] = kSpacing * Vec3(c % kLatticeSide - 1, (c / kLatticeSide) % kLatticeSide - 1,
                                                       c / (kLatticeSide * kLatticeSide) - 1);
  return out;
}

/// Principal moments of the crate about its centre [kg m^2]: each of the 27 particles stands for its lattice
/// cell, a cube of side s (own moment m s^2 / 6), plus m d^2, d the particle's distance from the axis; the cells
/// tile the solid 0.3 m cube, whose moments these are (all three equal: 0.0405).
Vec3 latticeInertia() {
  Vec3 inertia = Vec3::Zero();
  for (const Vec3& o : latticeOffsets()) {
    const Vec3 sq = o.cwiseProduct(o);
    inertia += kSphereMass * Vec3(sq.y() + sq.z(), sq.x() + sq.z(), sq.x() + sq.y());
    inertia += Vec3::Constant(kSphereMass * kSpacing * kSpacing / 6.0);
  }
  return inertia;
}

/// k = ceil(cbrt(n)), the smallest k with k^3 >= n, in integers.
int gridSide(int n) {
  auto k = static_cast<std::int64_t>(std::llround(std::cbrt(static_cast<double>(n))));
  while (k * k * k < n) ++k;
  while (k > 1 && (k - 1) * (k - 1) * (k - 1) >= n) --k;
  return static_cast<int>(k);
}

/// The start state of pile-N, shared by every variant.
struct PileLayout {
  int n = 0;
  int k = 0;              ///< bodies per grid row
  double wall = 0.0;      ///< walls at x, y = +-wall [m]
  std::vector<Vec3> centre;       ///< [N] body centres [m]
  std::vector<Quat> orientation;  ///< [N] body frame -> world

  explicit PileLayout(int bodies) : n(bodies), k(gridSide(bodies)), wall(kGridSpacing * k / 2.0 + kWallGap) {
    const double half = (k - 1) / 2.0;
    for (int i = 0; i < n; ++i) {
      centre.emplace_back((i % k - half) * kGridSpacing, ((i / k) % k - half) * kGridSpacing,
                          kLowestCentre + (i / (k * k)) * kGridSpacing);
      orientation.push_back(Quat(Eigen::AngleAxisd(kTurnX * i, Vec3::UnitX())) *
                            Quat(Eigen::AngleAxisd(kTurnZ * i, Vec3::UnitZ())));
    }
  }
  [[nodiscard]] std::size_t particles() const { return static_cast<std::size_t>(n) * kSpheresPerBody; }
};

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
// what a run measures

struct Quality {
  double kinetic = 0.0;             ///< [J]
  double maxPenetration = 0.0;      ///< deepest overlap of the end state [m]
  double initialPenetration = 0.0;  ///< deepest overlap before the first step [m]
  int escaped = 0;                  ///< bodies outside the walls or below the ground
  double highest = 0.0;             ///< highest body centre [m]
  double maxSpeed = 0.0;            ///< fastest body centre [m/s]
  bool finite = true;               ///< false: a step produced NaN/inf (the run stopped there)
};

struct Run {
  int n = 0;
  std::string variant;
  int repeat = 0;
  int steps = 0;
  int threads = 1;
  double seconds = 0.0;  ///< the stepping loop alone [s]
  Quality quality;
};

/// Body-centre counts of a state: escaped bodies, the highest centre and the fastest one.
struct CentreTally {
  explicit CentreTally(double wallHalfWidth) : wall(wallHalfWidth) {}
  double wall = 0.0;  ///< walls at x, y = +-wall [m]
  int escaped = 0;
  double highest = -1e300;  ///< [m]
  double maxSpeed = 0.0;    ///< [m/s]
  bool finite = true;
  /// A body with centre `c` [m] moving at `v` [m/s].
  void add(const Vec3& c, const Vec3& v) {
    if (!c.allFinite() || !v.allFinite()) finite = false;
    if (!(std::abs(c.x()) <= wall && std::abs(c.y()) <= wall && c.z() >= 0.0)) ++escaped;
    highest = std::max(highest, c.z());
    maxSpeed = std::max(maxSpeed, v.norm());
  }
  /// Copies the counts into `q` (a non-finite state stays marked).
  void into(Quality& q) const {
    q.escaped = escaped;
    q.highest = highest;
    q.maxSpeed = maxSpeed;
    q.finite = q.finite && finite;
  }
};

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

  // the timed loop
  const auto t0 = Clock::now();
  for (int s = 0; s < steps; ++s)
    if (volpar::hasFlag(world.step(), volpar::StepStatus::NonFinite)) {
      run.quality.finite = false;
      break;
    }
  run.seconds = std::chrono::duration<double>(Clock::now() - t0).count();

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
// Bullet

enum class BulletSetup { Box, CompoundPlanes, CompoundBoxes };

btVector3 toBt(const Vec3& v) {
  return {static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z())};
}
Vec3 fromBt(const btVector3& v) {
  return {static_cast<double>(v.x()), static_cast<double>(v.y()), static_cast<double>(v.z())};
}
btQuaternion toBt(const Quat& q) {
  return {static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()), static_cast<btScalar>(q.z()),
          static_cast<btScalar>(q.w())};
}

/// A Bullet world holding pile-N in one of the three setups.
class BulletPile {
 public:
  BulletPile(const PileLayout& pile, BulletSetup setup) : wall_(pile.wall) {
    config_ = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ = std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(),
                                                       config_.get());
    world_->setGravity(btVector3(0, 0, static_cast<btScalar>(-kGravity)));
    world_->getSolverInfo().m_numIterations = kIterations;

    // ground and walls: planes n . x = -wall with inward normals, or boxes 1 m thick behind those planes
    if (setup == BulletSetup::CompoundBoxes) {
      const double thick = 0.5;                                          // half thickness [m]
      const double reach = pile.wall + 2.0 * thick;                      // half length, past the corners [m]
      const double top = kLowestCentre + pile.k * kGridSpacing + 1.0;   // walls reach above the pile [m]
      const double zMid = (top - 2.0 * thick) / 2.0, zHalf = (top + 2.0 * thick) / 2.0;
      addStaticBox(Vec3(reach, reach, thick), Vec3(0, 0, -thick));
      addStaticBox(Vec3(thick, reach, zHalf), Vec3(pile.wall + thick, 0, zMid));
      addStaticBox(Vec3(thick, reach, zHalf), Vec3(-pile.wall - thick, 0, zMid));
      addStaticBox(Vec3(reach, thick, zHalf), Vec3(0, pile.wall + thick, zMid));
      addStaticBox(Vec3(reach, thick, zHalf), Vec3(0, -pile.wall - thick, zMid));
    } else {
      addStaticPlane(Vec3::UnitZ(), 0.0);
      addStaticPlane(Vec3::UnitX(), -pile.wall);
      addStaticPlane(-Vec3::UnitX(), -pile.wall);
      addStaticPlane(Vec3::UnitY(), -pile.wall);
      addStaticPlane(-Vec3::UnitY(), -pile.wall);
    }

    // one body shape shared by all bodies
    btCollisionShape* bodyShape = nullptr;
    if (setup == BulletSetup::Box) {
      bodyShape = own(std::make_unique<btBoxShape>(toBt(Vec3(kBoxHalf, kBoxHalf, kBoxHalf))));
    } else {
      auto* sphere = own(std::make_unique<btSphereShape>(static_cast<btScalar>(kRadius)));
      auto compound = std::make_unique<btCompoundShape>();
      for (const Vec3& o : latticeOffsets()) {
        btTransform child;
        child.setIdentity();
        child.setOrigin(toBt(o));
        compound->addChildShape(child, sphere);
      }
      bodyShape = own(std::move(compound));
    }

    // the bodies, at rest, with the 27-sphere inertia
    const btVector3 inertia = toBt(latticeInertia());
    for (int i = 0; i < pile.n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      btRigidBody::btRigidBodyConstructionInfo info(static_cast<btScalar>(kBodyMass), nullptr, bodyShape, inertia);
      info.m_startWorldTransform = btTransform(toBt(pile.orientation[u]), toBt(pile.centre[u]));
      bodies_.push_back(addBody(info));
    }
  }

  BulletPile(const BulletPile&) = delete;
  BulletPile& operator=(const BulletPile&) = delete;

  ~BulletPile() {
    for (auto it = objects_.rbegin(); it != objects_.rend(); ++it) world_->removeRigidBody(it->get());
  }

  /// Exactly one step of dt (maxSubSteps 0: no fixed-step accumulator, no interpolation).
  void step() { world_->stepSimulation(static_cast<btScalar>(kDt), 0); }

  /// Runs collision detection on the current poses (as the next step would) and returns the deepest
  /// overlap over all manifold points [m].
  double deepest() {
    world_->performDiscreteCollisionDetection();
    double worst = 0.0;
    const int manifolds = dispatcher_->getNumManifolds();
    for (int m = 0; m < manifolds; ++m) {
      const btPersistentManifold* manifold = dispatcher_->getManifoldByIndexInternal(m);
      for (int p = 0; p < manifold->getNumContacts(); ++p)
        worst = std::max(worst, -static_cast<double>(manifold->getContactPoint(p).getDistance()));
    }
    return worst;
  }

  /// Kinetic energy, escaped bodies, the highest centre and the fastest body of the current state.
  void measure(Quality& q) const {
    q.kinetic = 0.0;
    CentreTally tally(wall_);
    for (const btRigidBody* body : bodies_) {
      const Vec3 v = fromBt(body->getLinearVelocity());
      const btMatrix3x3& basis = body->getWorldTransform().getBasis();
      const Vec3 wLocal = fromBt(basis.transpose() * body->getAngularVelocity());  // body frame
      const Vec3 inertia = fromBt(body->getLocalInertia());
      q.kinetic += 0.5 * kBodyMass * v.squaredNorm() + 0.5 * wLocal.dot(inertia.cwiseProduct(wLocal));
      tally.add(fromBt(body->getWorldTransform().getOrigin()), v);
    }
    tally.into(q);
    q.finite = q.finite && std::isfinite(q.kinetic);
  }

  /// World centres of body i's 27 spheres (the compound setups' children; the lattice sites for boxes) [m].
  [[nodiscard]] std::array<Vec3, kSpheresPerBody> sphereCentres(std::size_t i) const {
    const btTransform& x = bodies_[i]->getWorldTransform();
    std::array<Vec3, kSpheresPerBody> out;
    const auto offsets = latticeOffsets();
    for (std::size_t c = 0; c < out.size(); ++c) out[c] = fromBt(x * toBt(offsets[c]));
    return out;
  }
  [[nodiscard]] Vec3 localInertia(std::size_t i) const { return fromBt(bodies_[i]->getLocalInertia()); }

 private:
  template <class Shape>
  Shape* own(std::unique_ptr<Shape> shape) {
    Shape* raw = shape.get();
    shapes_.push_back(std::move(shape));
    return raw;
  }

  btRigidBody* addBody(const btRigidBody::btRigidBodyConstructionInfo& info) {
    auto body = std::make_unique<btRigidBody>(info);
    body->setFriction(static_cast<btScalar>(std::sqrt(kFriction)));
    body->setRestitution(static_cast<btScalar>(std::sqrt(kRestitution)));
    body->setActivationState(DISABLE_DEACTIVATION);
    world_->addRigidBody(body.get());
    objects_.push_back(std::move(body));
    return objects_.back().get();
  }

  void addStaticPlane(const Vec3& normal, double offset) {
    auto* shape = own(std::make_unique<btStaticPlaneShape>(toBt(normal), static_cast<btScalar>(offset)));
    addBody(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, shape));
  }

  void addStaticBox(const Vec3& halfExtents, const Vec3& centre) {
    auto* shape = own(std::make_unique<btBoxShape>(toBt(halfExtents)));
    btRigidBody::btRigidBodyConstructionInfo info(0, nullptr, shape);
    info.m_startWorldTransform = btTransform(btQuaternion::getIdentity(), toBt(centre));
    addBody(info);
  }

  double wall_ = 0.0;
  // destroyed in reverse order: bodies (removed from the world first), shapes, then the world and its parts
  std::unique_ptr<btDefaultCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btDbvtBroadphase> broadphase_;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btRigidBody>> objects_;  // static ground and walls, then the bodies
  std::vector<btRigidBody*> bodies_;                   // [N] the dynamic bodies, in pile order
};

Run runBullet(const PileLayout& pile, int steps, BulletSetup setup) {
  Run run;
  BulletPile world(pile, setup);
  run.quality.initialPenetration = world.deepest();

  // the timed loop
  const auto t0 = Clock::now();
  for (int s = 0; s < steps; ++s) world.step();
  run.seconds = std::chrono::duration<double>(Clock::now() - t0).count();

  world.measure(run.quality);
  run.quality.maxPenetration = world.deepest();
  return run;
}

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

/// The volpar and Bullet worlds of pile-N start from the same state: every Bullet sphere centre lies on a
/// volpar particle of the same body, and the mass properties agree.
void checkSameStart(const PileLayout& pile) {
  constexpr double kTol = 1e-5;  // [m] Bullet's btScalar may be float
  auto built = buildVolparPile(pile, 1);
  if (!built) {
    report(false, "pile-" + std::to_string(pile.n) + ": " + built.error().toString());
    return;
  }
  const volpar::World& world = built->world;
  const BulletPile bullet(pile, BulletSetup::CompoundPlanes);
  const volpar::BodyStore& bodies = world.bodies();
  bool countsOk = bodies.size() == static_cast<std::size_t>(pile.n) && world.particles().size() == pile.particles();
  double worstPosition = 0.0, worstMass = 0.0, worstInertia = 0.0;
  for (std::size_t b = 0; countsOk && b < bodies.size(); ++b) {
    const auto& particles = bodies.info[b].particles;
    countsOk = countsOk && particles.size() == static_cast<std::size_t>(kSpheresPerBody);
    for (const Vec3& c : bullet.sphereCentres(b)) {
      double nearest = 1e300;
      for (const volpar::ParticleId p : particles)
        nearest = std::min(nearest, (world.particles().position[p.index()] - c).norm());
      worstPosition = std::max(worstPosition, nearest);
    }
    worstMass = std::max(worstMass, std::abs(bodies.info[b].mass - kBodyMass));
    worstInertia = std::max(worstInertia, (bodies.info[b].inertiaLocal - latticeInertia()).cwiseAbs().maxCoeff());
    worstInertia = std::max(worstInertia, (bullet.localInertia(b) - latticeInertia()).cwiseAbs().maxCoeff());
  }
  report(countsOk && worstPosition < kTol && worstMass < 1e-12 && worstInertia < 1e-6,
         "pile-" + std::to_string(pile.n) + ": volpar and Bullet start alike: " + std::to_string(bodies.size()) +
             " bodies, " + std::to_string(world.particles().size()) + " particles; sphere centres within " +
             sci(worstPosition, 2) + " m, mass within " + sci(worstMass, 1) + " kg, inertia (" +
             fixed(latticeInertia().x(), 5) + " kg m^2 per axis) within " + sci(worstInertia, 1));
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
  double stepsPerSecond = 0.0;  ///< at the median time
  Quality quality;              ///< of the last repeat
  bool qualityVaries = false;   ///< the repeats did not end in the same state
  bool finite = true;
};

Summary summarise(const std::vector<Run>& runs) {
  Summary s;
  s.variant = runs.front().variant;
  std::vector<double> seconds;
  for (const Run& r : runs) {
    seconds.push_back(r.seconds);
    s.finite = s.finite && r.quality.finite;
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
  s.quality = runs.back().quality;
  return s;
}

bool isVolpar(const std::string& variant) { return variant.rfind("volpar", 0) == 0; }

void printTable(const PileLayout& pile, int steps, const std::vector<Summary>& summaries) {
  std::printf("\npile-%d: %d bodies, %zu particles, k = %d, walls at +-%.3f m, %d steps of 1/240 s\n", pile.n,
              pile.n, pile.particles(), pile.k, pile.wall, steps);
  std::printf("%-16s %9s %21s %10s %16s %10s %11s %11s %11s %7s %11s %10s\n", "variant", "median s",
              "(min-max)", "steps/s", "particle-steps/s", "us/body-st", "KE [J]", "max pen [m]", "pen@0 [m]",
              "escaped", "highest [m]", "max v [m/s]");
  for (const Summary& s : summaries) {
    const double particleRate = s.stepsPerSecond * static_cast<double>(pile.particles());
    const double usPerBodyStep = 1e6 * s.medianSeconds / (static_cast<double>(steps) * pile.n);
    const Quality& q = s.quality;
    std::array<char, 48> range{};
    std::snprintf(range.data(), range.size(), "(%.4g-%.4g)", s.minSeconds, s.maxSeconds);
    std::printf("%-16s %9.4g %21s %10.1f %16.4g %10.3f %11.4g %11.3e %11.3e %7d %11.3f %11.3e%s%s\n",
                s.variant.c_str(), s.medianSeconds, range.data(), s.stepsPerSecond, particleRate, usPerBodyStep,
                q.kinetic, q.maxPenetration, q.initialPenetration, q.escaped, q.highest, q.maxSpeed,
                s.qualityVaries ? "  (end state differs between repeats)" : "",
                s.finite ? "" : "  NON-FINITE");
  }
  std::printf("max pen %% of r:");
  for (const Summary& s : summaries)
    std::printf("  %s %.1f %%", s.variant.c_str(), 100.0 * s.quality.maxPenetration / kRadius);
  std::printf("\n");

  // ratios of median steps/s, volpar over Bullet (above 1: volpar is faster)
  std::vector<const Summary*> ours, theirs;
  const Summary* fastestCompound = nullptr;
  for (const Summary& s : summaries) {
    (isVolpar(s.variant) ? ours : theirs).push_back(&s);
    if (s.variant.rfind("compound", 0) == 0 && (!fastestCompound || s.stepsPerSecond > fastestCompound->stepsPerSecond))
      fastestCompound = &s;
  }
  if (ours.empty() || theirs.empty()) return;
  std::printf("steps/s ratio (median volpar / median Bullet; above 1: volpar is faster)\n%-16s", "");
  for (const Summary* b : theirs) std::printf(" %16s", b->variant.c_str());
  if (fastestCompound) std::printf("   fastest compound (%s)", fastestCompound->variant.c_str());
  std::printf("\n");
  for (const Summary* a : ours) {
    std::printf("%-16s", a->variant.c_str());
    for (const Summary* b : theirs) std::printf(" %16.3f", a->stepsPerSecond / b->stepsPerSecond);
    if (fastestCompound) std::printf("   %.3f", a->stepsPerSecond / fastestCompound->stepsPerSecond);
    std::printf("\n");
  }
}

void writeCsv(const std::string& path, const std::vector<Run>& runs) {
  std::ofstream out(path);
  if (!out) {
    std::fprintf(stderr, "pile_bench: cannot write %s\n", path.c_str());
    std::exit(1);
  }
  out << "n,particles,variant,repeat,steps,threads,seconds,steps_per_s,particle_steps_per_s,us_per_body_step,"
         "kinetic_energy_J,max_penetration_m,initial_penetration_m,escaped,highest_m,max_speed_m_per_s,finite\n";
  for (const Run& r : runs) {
    const double particles = static_cast<double>(r.n) * kSpheresPerBody;
    out << r.n << ',' << r.n * kSpheresPerBody << ',' << r.variant << ',' << r.repeat << ',' << r.steps << ','
        << r.threads << ',' << num(r.seconds) << ',' << num(r.steps / r.seconds) << ','
        << num(particles * r.steps / r.seconds) << ',' << num(1e6 * r.seconds / (static_cast<double>(r.steps) * r.n))
        << ',' << num(r.quality.kinetic) << ',' << num(r.quality.maxPenetration) << ','
        << num(r.quality.initialPenetration) << ',' << r.quality.escaped << ',' << num(r.quality.highest) << ','
        << num(r.quality.maxSpeed) << ',' << (r.quality.finite ? 1 : 0) << '\n';
  }
}

// ---------------------------------------------------------------------------------------------------
// command line

const std::vector<std::string> kVariants = {"volpar", "volpar-mt", "box", "compound-planes", "compound-boxes"};

struct Options {
  std::vector<int> n = {125, 1000, 8000, 27000};
  std::optional<int> steps, repeats;
  std::vector<std::string> variants = kVariants;
  int threads = 2;
  std::string csv;
  bool quick = false;
  bool selfCheck = false;
};

void usage(std::FILE* to) {
  std::fprintf(to,
               "usage: pile_bench [options]\n"
               "  --n LIST          body counts, comma-separated (default 125,1000,8000,27000)\n"
               "  --steps S         steps per run (default 2000)\n"
               "  --repeats R       runs of every variant per N, interleaved (default 3)\n"
               "  --variants LIST   of volpar,volpar-mt,box,compound-planes,compound-boxes (default all)\n"
               "  --threads T       volpar-mt threads (default 2)\n"
               "  --csv FILE        write every run, one row per run\n"
               "  --quick           smoke run: 200 steps, 1 repeat (unless --steps/--repeats say otherwise)\n"
               "  --self-check      only check the generated worlds (volpar vs Bullet, pile-1000 vs its file)\n");
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
      for (const std::string& name : o.variants)
        if (std::find(kVariants.begin(), kVariants.end(), name) == kVariants.end()) {
          std::fprintf(stderr, "pile_bench: unknown variant '%s'\n", name.c_str());
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
  return runBullet(pile, steps, BulletSetup::CompoundBoxes);
}

}  // namespace

int main(int argc, char** argv) {
  const auto parsed = parseOptions(argc, argv);
  if (!parsed) return 2;
  const Options& o = *parsed;
  const int steps = o.steps.value_or(o.quick ? 200 : 2000);
  const int repeats = o.repeats.value_or(o.quick ? 1 : 3);

  std::printf("pile_bench  %s\n", now().c_str());
  std::printf("machine: %u hardware threads, %s, load average %s\n", std::thread::hardware_concurrency(),
              cpuModel().c_str(), loadAverage().c_str());
  std::printf("Bullet %d.%02d (btScalar: %zu-byte floats), bodies: mass %.1f kg, 27-sphere inertia %.5f kg m^2 per "
              "axis in every variant; box variant: static planes, btBoxShape margin %.3f m\n",
              btGetVersion() / 100, btGetVersion() % 100, sizeof(btScalar), kBodyMass, latticeInertia().x(),
              static_cast<double>(CONVEX_DISTANCE_MARGIN));
  std::printf("steps %d, repeats %d, volpar-mt threads %d\n", steps, repeats, o.threads);

  // the worlds start alike
  for (const int n : o.n) {
    const PileLayout pile(n);
    checkSameStart(pile);
    if (n == 1000) checkAgainstFile(pile);
  }
  std::fflush(stdout);
  if (o.selfCheck) return gCheckFailed ? 1 : 0;

  // per N: every repeat runs every variant in turn
  std::vector<Run> all;
  bool allFinite = true;
  for (const int n : o.n) {
    const PileLayout pile(n);
    std::vector<std::vector<Run>> runs(o.variants.size());
    for (int r = 0; r < repeats; ++r)
      for (std::size_t v = 0; v < o.variants.size(); ++v) {
        Run run = runVariant(pile, o.variants[v], steps, o.threads);
        run.n = n;
        run.variant = o.variants[v];
        run.repeat = r;
        run.steps = steps;
        std::fprintf(stderr, "  pile-%d %-16s repeat %d: %.4g s\n", n, run.variant.c_str(), r, run.seconds);
        allFinite = allFinite && run.quality.finite;
        runs[v].push_back(run);
        all.push_back(run);
      }
    std::vector<Summary> summaries;
    for (const auto& variantRuns : runs) summaries.push_back(summarise(variantRuns));
    printTable(pile, steps, summaries);
    std::fflush(stdout);
  }
  if (!o.csv.empty()) writeCsv(o.csv, all);
  return gCheckFailed || !allFinite ? 1 : 0;
}
