// Collision benchmarks: volpar's broadphase and particle contacts against FCL 0.7 on the same inputs.
// Results and the command that produced them: docs/benchmarks.md.
//
//   broadphase/...   N boxes of 0.3 m on a jittered grid, every box moved a little per iteration (a bounded
//                    random walk, warmed up untimed), all overlapping pairs found (volpar::Broadphase vs
//                    fcl::DynamicAABBTreeCollisionManagerd); timed by hand around the update, so drawing
//                    the new positions is not counted
//   pair/...         touching particle pairs between two lattice bodies (ContactFinder::find vs one FCL
//                    manager of spheres per body, manager against manager)
//   pile/...         a grid of N 27-particle bodies, every touching particle pair (ContactFinder::find vs
//                    one FCL manager over all spheres, self-collide)
//
// The particle-contact benchmarks time the contact search alone: World::refreshContacts() runs once,
// untimed (broadphase pairs, tight boxes, and the separating-plane narrow phase, which is not timed
// here: tools/bench/narrow_phase_bench.cpp), then a ContactFinder of the benchmark's own, with every body
// registered, searches the world's body pairs on the world's data.
//
// Before the benchmarks run, every scene is checked: FCL's pair set must equal volpar's (for the
// broadphase: volpar's fat-box pairs whose tight boxes overlap; for contacts: the pairs of the benchmark's
// ContactFinder, which must also equal the world's own touching contacts: the world's finder also reports
// speculative pairs within its contact margin, WorldSettings::contactMargin, which FCL's collide does not).
// The outcome goes to stderr, and the program exits with status 1 if a check failed.
//
// --quick: the checks, then every benchmark once (one iteration, one repetition): a smoke run for the tests.

#include <benchmark/benchmark.h>
#include <fcl/fcl.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "volpar/collision/aabb.hpp"
#include "volpar/collision/broadphase.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/world.hpp"
#include "tools/bench/quick_flag.hpp"

namespace {

using volpar::Aabb;
using volpar::BodyId;
using volpar::Quat;
using volpar::Vec3;
using Clock = std::chrono::steady_clock;
using IdPair = std::pair<std::uint32_t, std::uint32_t>;

bool gChecksFailed = false;
bool gQuick = false;  // --quick

// ---------------------------------------------------------------------------------------------------
// helpers

/// splitmix64: small, fast and the same on every platform.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (s_ += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  /// Uniform in [lo, hi).
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * (static_cast<double>(next() >> 11) * 0x1.0p-53);
  }
  Vec3 uniformVec(double half) { return {uniform(-half, half), uniform(-half, half), uniform(-half, half)}; }
  Vec3 unitVec() {
    for (;;) {
      const Vec3 v = uniformVec(1.0);
      const double n = v.norm();
      if (n > 0.1 && n <= 1.0) return v / n;
    }
  }

 private:
  std::uint64_t s_;
};

fcl::Transform3d translation(const Vec3& p) {
  fcl::Transform3d x = fcl::Transform3d::Identity();
  x.translation() = p;
  return x;
}

void* tagOf(std::size_t i) { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(i)); }
std::uint32_t tag(const fcl::CollisionObjectd* o) {
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(o->getUserData()));
}
IdPair ordered(std::uint32_t a, std::uint32_t b) { return a < b ? IdPair{a, b} : IdPair{b, a}; }

/// Min and max over the repetitions, reported next to mean, median and stddev.
void addMinMax(benchmark::internal::Benchmark* b) {
  b->ComputeStatistics("min", [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); });
  b->ComputeStatistics("max", [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); });
}

void report(bool ok, const std::string& line) {
  std::fprintf(stderr, "check %s: %s\n", ok ? "ok      " : "MISMATCH", line.c_str());
  if (!ok) gChecksFailed = true;
}

/// A set of FCL objects sharing one geometry, with their indices as user data.
struct FclObjects {
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  std::vector<fcl::CollisionObjectd*> raw;

  FclObjects(const std::shared_ptr<fcl::CollisionGeometryd>& geometry, const std::vector<Vec3>& centres,
             std::size_t first = 0) {
    objects.reserve(centres.size());
    raw.reserve(centres.size());
    for (std::size_t i = 0; i < centres.size(); ++i) {
      objects.push_back(std::make_unique<fcl::CollisionObjectd>(geometry, translation(centres[i])));
      objects.back()->setUserData(tagOf(first + i));
      raw.push_back(objects.back().get());
    }
  }
  /// setTranslation + computeAABB for every object (what a moved object needs before manager.update()).
  void place(const std::vector<Vec3>& centres) {
    for (std::size_t i = 0; i < objects.size(); ++i) {
      objects[i]->setTranslation(centres[i]);
      objects[i]->computeAABB();
    }
  }
};

// ---------------------------------------------------------------------------------------------------
// 1. broadphase

constexpr double kBoxSize = 0.3;        // [m] tight box side
constexpr double kGridSpacing = 0.31;   // [m] between home positions
constexpr double kHomeJitter = 0.03;    // [m] home = grid site + U(-j, j) per axis
constexpr double kStepSize = 0.004;     // [m] per-iteration displacement U(-s, s) per axis ...
constexpr double kPull = 0.05;          // ... minus kPull x (position - home): a bounded random walk
constexpr double kBroadMargin = 0.01;   // [m] volpar fat-box margin
constexpr int kWarmupSteps = 50;        // untimed steps before timing: the walk reaches its steady spread

/// N boxes on a jittered grid and their motion; the same seed gives the same sequence on both sides.
struct BoxCloud {
  std::vector<Vec3> home, position, displacement;
  Rng rng{0x5eed0001};

  explicit BoxCloud(std::size_t n) {
    const auto side = static_cast<std::size_t>(std::ceil(std::cbrt(static_cast<double>(n)) - 1e-9));
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 site(static_cast<double>(i % side), static_cast<double>((i / side) % side),
                      static_cast<double>(i / (side * side)));
      home.push_back(kGridSpacing * site + rng.uniformVec(kHomeJitter));
    }
    position = home;
    displacement.assign(n, Vec3::Zero());
  }
  void move() {
    for (std::size_t i = 0; i < position.size(); ++i) {
      displacement[i] = rng.uniformVec(kStepSize) - kPull * (position[i] - home[i]);
      position[i] += displacement[i];
    }
  }
  [[nodiscard]] Aabb tight(std::size_t i) const {
    return {position[i].array() - 0.5 * kBoxSize, position[i].array() + 0.5 * kBoxSize};
  }
};

struct VolparBroadphase {
  volpar::Broadphase bp;
  std::size_t moved = 0;  // reinsertions of the last update

  explicit VolparBroadphase(const BoxCloud& c) {
    bp.setMargin(kBroadMargin);
    for (std::size_t i = 0; i < c.position.size(); ++i) bp.addBody(BodyId(i), c.tight(i), false);
  }
  void update(const BoxCloud& c) {
    for (std::size_t i = 0; i < c.position.size(); ++i) bp.moveBody(BodyId(i), c.tight(i), c.displacement[i]);
    moved = bp.reinsertions();
    bp.findPairs({});
  }
  [[nodiscard]] std::vector<IdPair> tightPairs(const BoxCloud& c) const {
    std::vector<IdPair> out;
    for (const auto& p : bp.pairs())
      if (c.tight(p.a.index()).overlaps(c.tight(p.b.index()))) out.emplace_back(p.a.value, p.b.value);
    return out;
  }
};

struct PairCollector {
  std::vector<IdPair> pairs;
  bool keep = false;  // count only, or also collect
  std::size_t count = 0;
};

bool onBoxPair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* d = static_cast<PairCollector*>(data);
  ++d->count;
  if (d->keep) d->pairs.push_back(ordered(tag(o1), tag(o2)));
  return false;  // keep going: all pairs
}

struct FclBroadphase {
  FclObjects objects;
  fcl::DynamicAABBTreeCollisionManagerd manager;
  PairCollector found;

  explicit FclBroadphase(const BoxCloud& c)
      : objects(std::make_shared<fcl::Boxd>(kBoxSize, kBoxSize, kBoxSize), c.position) {
    manager.registerObjects(objects.raw);
    manager.setup();
  }
  void update(const BoxCloud& c) {
    objects.place(c.position);
    manager.update();
    found.count = 0;
    found.pairs.clear();
    manager.collide(&found, onBoxPair);
  }
};

void checkBroadphase(std::size_t n) {
  BoxCloud a(n), b(n);
  VolparBroadphase v(a);
  FclBroadphase f(b);
  f.found.keep = true;
  constexpr int kSteps = 50;
  std::size_t fat = 0, tight = 0, fclPairs = 0, moved = 0, bad = 0;
  for (int s = 0; s < kSteps; ++s) {
    a.move();
    b.move();
    v.update(a);
    f.update(b);
    auto t = v.tightPairs(a);
    auto p = f.found.pairs;
    std::sort(t.begin(), t.end());
    std::sort(p.begin(), p.end());
    if (t != p) ++bad;
    fat += v.bp.pairs().size();
    tight += t.size();
    fclPairs += p.size();
    moved += v.moved;
  }
  report(bad == 0, "broadphase N=" + std::to_string(n) + ", " + std::to_string(kSteps) +
                       " steps: FCL tight-box pairs == volpar fat-box pairs whose tight boxes overlap in " +
                       std::to_string(kSteps - static_cast<int>(bad)) + "/" + std::to_string(kSteps) +
                       " steps; per step: FCL " + std::to_string(fclPairs / kSteps) + ", volpar fat " +
                       std::to_string(fat / kSteps) + " (tight " + std::to_string(tight / kSteps) + "), moved " +
                       std::to_string(moved / kSteps) + " of " + std::to_string(n));
}

// Counters: pairs (and for volpar, those of them whose tight boxes overlap) in the first timed step, which
// is the same state on both sides; moved = reinsertions per step, averaged over the timed steps.
void BM_BroadphaseVolpar(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  BoxCloud cloud(n);
  VolparBroadphase v(cloud);
  for (int s = 0; s < kWarmupSteps; ++s) {
    cloud.move();
    v.update(cloud);
  }
  double moved = 0;
  bool first = true;
  for (auto _ : state) {
    cloud.move();  // untimed: the new positions
    const auto t0 = Clock::now();
    v.update(cloud);
    benchmark::DoNotOptimize(v.bp.pairs().data());
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    moved += static_cast<double>(v.moved);
    if (first) {
      state.counters["pairs"] = static_cast<double>(v.bp.pairs().size());
      state.counters["tight"] = static_cast<double>(v.tightPairs(cloud).size());
      first = false;
    }
  }
  state.counters["moved"] = moved / static_cast<double>(state.iterations());
}

void BM_BroadphaseFcl(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  BoxCloud cloud(n);
  FclBroadphase f(cloud);
  for (int s = 0; s < kWarmupSteps; ++s) {
    cloud.move();
    f.update(cloud);
  }
  bool first = true;
  for (auto _ : state) {
    cloud.move();  // untimed: the new positions
    const auto t0 = Clock::now();
    f.update(cloud);
    benchmark::DoNotOptimize(f.found.count);
    state.SetIterationTime(std::chrono::duration<double>(Clock::now() - t0).count());
    if (first) {
      state.counters["pairs"] = static_cast<double>(f.found.count);
      first = false;
    }
  }
}

// ---------------------------------------------------------------------------------------------------
// particle worlds (2. one body pair, 3. pile)

constexpr double kRadius = 0.05;   // [m]
constexpr double kSpacing = 0.1;   // [m] = 2 r, cubic lattice

volpar::ParticleCloud latticeCube(int perSide) {
  auto cloud = volpar::fillShape(volpar::BoxShape(Vec3::Constant(kSpacing * perSide)), {volpar::Lattice::Cubic, kRadius});
  if (!cloud.ok()) {
    std::fprintf(stderr, "fillShape failed: %s\n", cloud.error().toString().c_str());
    std::exit(2);
  }
  return std::move(cloud).value();
}

struct BodyPose {
  Vec3 position;
  Quat orientation;
};

std::unique_ptr<volpar::World> makeWorld(const volpar::ParticleCloud& cloud, const std::vector<BodyPose>& poses) {
  volpar::WorldSettings settings;
  settings.gravity = Vec3::Zero();
  auto world = std::make_unique<volpar::World>(settings);
  const volpar::MaterialId material = world->addMaterial(volpar::Material{"bench", 1000.0, 0.5, 0.5});
  for (std::size_t i = 0; i < poses.size(); ++i) {
    volpar::BodyDef def;
    def.name = "b";
    def.name += std::to_string(i);  // (not "b" + to_string: GCC 12 -O3 false -Wrestrict)
    def.material = material;
    def.position = poses[i].position;
    def.orientation = poses[i].orientation;
    auto id = world->addBody(def, cloud);
    if (!id.ok()) {
      std::fprintf(stderr, "addBody failed: %s\n", id.error().toString().c_str());
      std::exit(2);
    }
  }
  world->refreshContacts();
  return world;
}

/// World positions of the particles of one body.
std::vector<Vec3> bodyParticles(const volpar::World& w, BodyId id) {
  std::vector<Vec3> out;
  for (const volpar::ParticleId p : w.bodies().info[id.index()].particles) out.push_back(w.particles().position[p.index()]);
  return out;
}

/// The touching contacts of a set as particle pairs, sorted (speculative contacts, depth <= 0, left out).
std::vector<IdPair> volparContactPairs(const volpar::ContactSet& set) {
  std::vector<IdPair> out;
  for (const auto& c : set.contacts)
    if (c.touching()) out.push_back(ordered(c.a.value, c.b.value));
  std::sort(out.begin(), out.end());
  return out;
}

/// The contact search alone, on a world whose refreshContacts() has run: a ContactFinder of its own (every
/// body registered once) reading the world's particles, bodies, connectors, broadphase pairs, planes and
/// tight boxes, writing its own ContactSet.
struct ContactSearch {
  const volpar::World& world;
  volpar::ContactFinder finder;
  volpar::ContactSet set;

  explicit ContactSearch(const volpar::World& w) : world(w) {
    for (std::size_t i = 0; i < w.bodies().size(); ++i) finder.addBody(BodyId(i), w.particles(), w.bodies());
    finder.setReuse(false);  // every search from scratch, as the peer does
  }
  void find() {
    finder.find(world.particles(), world.bodies(), world.connectors(), world.bodyPairs(), world.planePairs(),
                world.planes(), world.bodyBoxes(), set);
  }
};

/// Narrow phase on a sphere pair the broadphase reported; `body` (when set) skips pairs of one body.
struct SphereCollector {
  fcl::CollisionRequestd request;  // yes/no
  const volpar::LargeVector<BodyId>* body = nullptr;
  std::vector<IdPair> pairs;
};

bool onSpherePair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* d = static_cast<SphereCollector*>(data);
  const std::uint32_t a = tag(o1), b = tag(o2);
  if (d->body != nullptr && (*d->body)[a] == (*d->body)[b]) return false;
  fcl::CollisionResultd result;
  if (fcl::collide(o1, o2, d->request, result)) d->pairs.push_back(ordered(a, b));
  return false;  // keep going: all pairs
}

/// Pairs touching within a relative 1e-9 of r_a + r_b: FCL (sqrt) and volpar (squares) may disagree there.
std::size_t grazing(const volpar::World& w, const std::vector<IdPair>& pairs) {
  std::size_t n = 0;
  for (const auto& [a, b] : pairs) {
    const double d = (w.particles().position[a] - w.particles().position[b]).norm();
    const double rs = w.particles().radius[a] + w.particles().radius[b];
    if (std::abs(d - rs) <= 1e-9 * rs) ++n;
  }
  return n;
}

/// FCL's pairs against those of a ContactSearch on `w` (which must also equal the world's own touching
/// contacts; the world's speculative ones are counted in the report).
void checkPairs(const std::string& what, const volpar::World& w, std::vector<IdPair> fcl) {
  std::sort(fcl.begin(), fcl.end());
  ContactSearch search(w);
  search.find();
  const auto v = volparContactPairs(search.set);
  const auto world = volparContactPairs(w.contacts());
  const bool sameAsWorld = v == world && search.set.contacts.size() == v.size();
  const std::size_t g = grazing(w, fcl) + grazing(w, v);
  report(v == fcl && sameAsWorld,
         what + ": FCL " + std::to_string(fcl.size()) + " touching pairs, volpar " + std::to_string(v.size()) +
             (v == fcl ? " (same set)" : " (sets differ)") +
             (sameAsWorld ? ", = world's touching" : ", NOT the world's touching") + " (the world's " +
             std::to_string(world.size()) + " and " + std::to_string(w.contacts().contacts.size() - world.size()) +
             " speculative), grazing " + std::to_string(g));
}

// --- 2. one body pair

struct PairCase {
  const char* name;
  int perSide;        // lattice sites per box side: 3 (27 particles) or 10 (1000)
  double sinkLayers;  // extra lattice layers B is sunk into A beyond the one-layer pose
};
const PairCase kPairCases[] = {
    {"27/one_layer", 3, 0.0},
    {"27/deep", 3, 1.5},
    {"1000/one_layer", 10, 0.0},
    {"1000/deep", 10, 5.0},
};

/// A at the origin; B above it, rotated 0.05 rad about z, shifted sideways by (0.37 r, 0.21 r) and down so
/// that the facing layers interpenetrate by 0.3 r, then sunk `sinkLayers` lattice layers further.
std::unique_ptr<volpar::World> makePairWorld(const PairCase& c) {
  const double side = kSpacing * c.perSide;
  const Vec3 b(0.37 * kRadius, 0.21 * kRadius, side - 0.3 * kRadius - c.sinkLayers * kSpacing);
  return makeWorld(latticeCube(c.perSide), {{Vec3::Zero(), Quat::Identity()},
                                            {b, Quat(Eigen::AngleAxisd(0.05, Vec3::UnitZ()))}});
}

/// One FCL sphere manager per body, user data = volpar particle index.
struct FclPair {
  std::shared_ptr<fcl::Sphered> sphere = std::make_shared<fcl::Sphered>(kRadius);
  std::vector<Vec3> centresB;
  FclObjects a, b;
  fcl::DynamicAABBTreeCollisionManagerd managerA, managerB;
  SphereCollector found;

  explicit FclPair(const volpar::World& w)
      : centresB(bodyParticles(w, BodyId(1u))),
        a(sphere, bodyParticles(w, BodyId(0u)), w.bodies().info[0].particles.front().index()),
        b(sphere, centresB, w.bodies().info[1].particles.front().index()) {
    managerA.registerObjects(a.raw);
    managerA.setup();
    managerB.registerObjects(b.raw);
    managerB.setup();
  }
  void query() {
    found.pairs.clear();
    managerA.collide(&managerB, &found, onSpherePair);
  }
  void refitBAndQuery() {
    b.place(centresB);
    managerB.update();
    query();
  }
};

void checkPair(const PairCase& c) {
  auto w = makePairWorld(c);
  FclPair f(*w);
  f.query();
  checkPairs(std::string("pair ") + c.name + ", query only", *w, f.found.pairs);
  f.refitBAndQuery();
  checkPairs(std::string("pair ") + c.name + ", refit B + query", *w, f.found.pairs);
}

void BM_PairVolpar(benchmark::State& state, const PairCase& c) {
  auto w = makePairWorld(c);  // refreshContacts() has run
  ContactSearch search(*w);
  search.find();  // untimed: builds the connector adjacency and sizes the buffers, as in the world's finder
  for (auto _ : state) {
    search.find();
    benchmark::DoNotOptimize(search.set.contacts.data());
  }
  state.counters["contacts"] = static_cast<double>(search.set.contacts.size());
}

void BM_PairFclQuery(benchmark::State& state, const PairCase& c) {
  auto w = makePairWorld(c);
  FclPair f(*w);
  for (auto _ : state) {
    f.query();
    benchmark::DoNotOptimize(f.found.pairs.data());
  }
  state.counters["contacts"] = static_cast<double>(f.found.pairs.size());
}

void BM_PairFclRefitQuery(benchmark::State& state, const PairCase& c) {
  auto w = makePairWorld(c);
  FclPair f(*w);
  for (auto _ : state) {
    f.refitBAndQuery();
    benchmark::DoNotOptimize(f.found.pairs.data());
  }
  state.counters["contacts"] = static_cast<double>(f.found.pairs.size());
}

// --- 3. pile

constexpr double kPileSpacing = 0.29;     // [m] between body centres (bodies are 0.3 m boxes of 27 particles)
constexpr double kPileJitter = 0.002;     // [m] position jitter per axis
constexpr double kPileTilt = 0.02;        // [rad] largest rotation about a random axis

std::unique_ptr<volpar::World> makePileWorld(std::size_t n) {
  const auto side = static_cast<std::size_t>(std::lround(std::cbrt(static_cast<double>(n))));
  Rng rng(0x5eed0003);
  std::vector<BodyPose> poses;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3 site(static_cast<double>(i % side), static_cast<double>((i / side) % side),
                    static_cast<double>(i / (side * side)));
    const Vec3 axis = rng.unitVec();
    const double angle = rng.uniform(0.0, kPileTilt);
    poses.push_back({kPileSpacing * site + rng.uniformVec(kPileJitter), Quat(Eigen::AngleAxisd(angle, axis))});
  }
  return makeWorld(latticeCube(3), poses);
}

/// One FCL manager over every particle of every body.
struct FclPile {
  std::shared_ptr<fcl::Sphered> sphere = std::make_shared<fcl::Sphered>(kRadius);
  std::vector<Vec3> centres;
  FclObjects objects;
  fcl::DynamicAABBTreeCollisionManagerd manager;
  SphereCollector found;

  explicit FclPile(const volpar::World& w)
      : centres(w.particles().position.begin(), w.particles().position.end()), objects(sphere, centres) {
    found.body = &w.particles().body;
    manager.registerObjects(objects.raw);
    manager.setup();
  }
  void updateAndCollide() {
    objects.place(centres);
    manager.update();
    found.pairs.clear();
    manager.collide(&found, onSpherePair);
  }
};

void checkPile(std::size_t n) {
  auto w = makePileWorld(n);
  FclPile f(*w);
  f.updateAndCollide();
  checkPairs("pile N=" + std::to_string(n) + " (" + std::to_string(w->bodyPairs().size()) + " body pairs)", *w,
             f.found.pairs);
}

void BM_PileVolpar(benchmark::State& state) {
  auto w = makePileWorld(static_cast<std::size_t>(state.range(0)));  // refreshContacts() has run
  ContactSearch search(*w);
  search.find();  // untimed: builds the connector adjacency and sizes the buffers, as in the world's finder
  for (auto _ : state) {
    search.find();
    benchmark::DoNotOptimize(search.set.contacts.data());
  }
  state.counters["contacts"] = static_cast<double>(search.set.contacts.size());
  state.counters["body_pairs"] = static_cast<double>(w->bodyPairs().size());
}

void BM_PileFcl(benchmark::State& state) {
  auto w = makePileWorld(static_cast<std::size_t>(state.range(0)));
  FclPile f(*w);
  for (auto _ : state) {
    f.updateAndCollide();
    benchmark::DoNotOptimize(f.found.pairs.data());
  }
  state.counters["contacts"] = static_cast<double>(f.found.pairs.size());
}

// ---------------------------------------------------------------------------------------------------

const std::int64_t kBroadphaseSizes[] = {1000, 3000, 10000};
const std::int64_t kPileSizes[] = {1000, 8000};

void configure(benchmark::internal::Benchmark* b) {
  if (gQuick) {
    b->Iterations(1)->Repetitions(1)->Unit(benchmark::kMicrosecond);
    return;
  }
  b->Repetitions(5)->ReportAggregatesOnly(true)->Unit(benchmark::kMicrosecond);
  addMinMax(b);
}

void registerAll() {
  for (const std::int64_t n : kBroadphaseSizes) {
    configure(benchmark::RegisterBenchmark("broadphase/volpar", BM_BroadphaseVolpar)->Arg(n)->ArgName("N")->UseManualTime());
    configure(benchmark::RegisterBenchmark("broadphase/fcl", BM_BroadphaseFcl)->Arg(n)->ArgName("N")->UseManualTime());
  }
  for (const PairCase& c : kPairCases) {
    const std::string base = std::string("pair/") + c.name;
    configure(benchmark::RegisterBenchmark((base + "/volpar").c_str(), BM_PairVolpar, c));
    configure(benchmark::RegisterBenchmark((base + "/fcl_query").c_str(), BM_PairFclQuery, c));
    configure(benchmark::RegisterBenchmark((base + "/fcl_refit_query").c_str(), BM_PairFclRefitQuery, c));
  }
  for (const std::int64_t n : kPileSizes) {
    configure(benchmark::RegisterBenchmark("pile/volpar", BM_PileVolpar)->Arg(n)->ArgName("N"));
    configure(benchmark::RegisterBenchmark("pile/fcl", BM_PileFcl)->Arg(n)->ArgName("N"));
  }
}

void runChecks() {
  for (const std::int64_t n : kBroadphaseSizes) checkBroadphase(static_cast<std::size_t>(n));
  for (const PairCase& c : kPairCases) checkPair(c);
  for (const std::int64_t n : kPileSizes) checkPile(static_cast<std::size_t>(n));
}

}  // namespace

int main(int argc, char** argv) {
  gQuick = volpar::bench::takeQuickFlag(argc, argv, "collision_bench");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  runChecks();
  registerAll();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return gChecksFailed ? 1 : 0;
}
