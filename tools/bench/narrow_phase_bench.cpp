// Narrow-phase benchmark: volpar's separating planes per body pair against FCL 0.7, on the scenes of
// tests/collision/plane_accuracy_test.cpp. Results and the command that produced them: docs/benchmarks.md.
//
// Scenes: two bodies filled from primitives (box-box, box-sphere, sphere-sphere, capsule-box,
// cylinder-box: the primitives of the accuracy sweep, tests/collision/plane_sweep.cpp), each in a fixed set
// of kPoses seeded random relative poses whose primitives penetrate by 0.1 to 1.5 particle radii (FCL's
// primitive contact decides). Poses where no particles touch yet (the world's contacts, if any, all
// speculative) are skipped. Every pose has a world of its own, built untimed, whose refreshContacts() has run.
//
// Each benchmark iteration is one sweep over the kPoses poses; the counter `per_pose` is the time per pose.
//   <scene>/volpar_planes      NarrowPhase::run(world.narrowPhaseInput(), world.contacts(), patches): patches
//                              and a separating plane per patch, from the particle contacts already found
//   <scene>/volpar_contacts    ContactFinder::find on the world's body pair (a finder of the benchmark's
//                              own): the particle contacts themselves, for reference
//   <scene>/fcl_particles      FCL A: one DynamicAABBTreeCollisionManagerd of sphere objects per body (built
//                              untimed), managerA.collide(&managerB, ...), the callback running fcl::collide
//                              with contacts on each sphere pair and accumulating the contact normals
//   <scene>/fcl_primitives     FCL B: reference::primitiveContact between the two primitives (closed forms
//                              for spheres, GJK/EPA signed distance via libccd otherwise): the exact normal
// These do different jobs: the planes start from contacts already found; FCL A finds the sphere contacts;
// FCL B solves the primitive problem, which a body without a primitive (a mesh, a deformed body) lacks.
//
// Before the benchmarks run, every scene is checked: FCL A's touching pairs must equal volpar's touching
// contacts in every pose (grazing pairs aside; the world also reports speculative contacts within its
// contact margin, WorldSettings::contactMargin, which FCL's collide does not), the benchmark's
// ContactFinder (margin 0) must find the world's touching contacts, and the benchmark's NarrowPhase must
// reproduce the world's patches. The outcome and the median angles of the normals against FCL B's go to
// stderr; the program exits with status 1 if a check failed.
//
// --quick: the checks, then every benchmark once (one iteration, one repetition): a smoke run for the tests.

#include <benchmark/benchmark.h>
#include <fcl/fcl.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "volpar/collision/narrow_phase.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/builders/fill.hpp"
#include "volpar/engine/builders/shapes.hpp"
#include "volpar/engine/world.hpp"
#include "tools/bench/quick_flag.hpp"

namespace {

using volpar::BodyId;
using volpar::Quat;
using volpar::SourceShape;
using volpar::Vec3;
using IdPair = std::pair<std::uint32_t, std::uint32_t>;

constexpr int kPoses = 200;         // poses with particle contact per scene
constexpr unsigned kSeed = 7;       // as in the accuracy test
bool gChecksFailed = false;
bool gQuick = false;  // --quick

void report(bool ok, const std::string& line) {
  std::fprintf(stderr, "check %s: %s\n", ok ? "ok      " : "MISMATCH", line.c_str());
  if (!ok) gChecksFailed = true;
}

/// Min and max over the repetitions, reported next to mean, median and stddev.
void addMinMax(benchmark::internal::Benchmark* b) {
  b->ComputeStatistics("min", [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); });
  b->ComputeStatistics("max", [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); });
}

double degrees(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t m = v.size() / 2;
  return v.size() % 2 == 1 ? v[m] : 0.5 * (v[m - 1] + v[m]);
}

// ---------------------------------------------------------------------------------------------------
// scenes (as in tests/collision/plane_accuracy_test.cpp)

struct Shape {
  SourceShape source;
  volpar::ParticleCloud cloud;
  double radius;    ///< particle radius [m]
  double bounding;  ///< bounding-sphere radius of the primitive [m]
};

Shape makeShape(SourceShape s, const volpar::SolidShape& solid, double r) {
  auto c = volpar::fillShape(solid, {volpar::Lattice::Cubic, r});
  if (!c.ok()) {
    std::fprintf(stderr, "fillShape failed: %s\n", c.error().toString().c_str());
    std::exit(2);
  }
  return {s, std::move(c).value(), r, 0.5 * solid.bounds().diagonal().norm()};
}

Shape box() {
  SourceShape s{SourceShape::Kind::Box, Vec3(0.4, 0.3, 0.3), 0, 0, Vec3::Zero(), {}};
  return makeShape(s, volpar::BoxShape(s.size), 0.025);
}
Shape sphere() {
  SourceShape s{SourceShape::Kind::Sphere, Vec3::Zero(), 0.25, 0, Vec3::Zero(), {}};
  return makeShape(s, volpar::SphereShape(0.25), 0.025);
}
Shape capsule() {
  SourceShape s{SourceShape::Kind::Capsule, Vec3::Zero(), 0.12, 0.3, Vec3::Zero(), {}};
  return makeShape(s, volpar::CapsuleShape(0.12, 0.3), 0.02);
}
Shape cylinder() {
  SourceShape s{SourceShape::Kind::Cylinder, Vec3::Zero(), 0.15, 0.4, Vec3::Zero(), {}};
  return makeShape(s, volpar::CylinderShape(0.15, 0.4), 0.025);
}

struct Pose {
  Quat qa, qb;  ///< orientations of the shape frames; A's origin at 0, B's at pb
  Vec3 pb;
  volpar::reference::PrimitiveContact ref;  ///< FCL's contact between the primitives
  std::unique_ptr<volpar::World> world;     ///< A and B in this pose, contacts refreshed
};

struct Scene {
  std::string name;
  Shape a, b;
  std::vector<Pose> poses;
  int tried = 0;    ///< poses generated
  int skipped = 0;  ///< of them without particle contact
};

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Quat(g(rng), g(rng), g(rng), g(rng)).normalized();
}

std::unique_ptr<volpar::World> makeWorld(const Scene& s, const Pose& p) {
  volpar::WorldSettings settings;
  settings.gravity = Vec3::Zero();
  auto w = std::make_unique<volpar::World>(settings);
  const volpar::MaterialId m = w->addMaterial(volpar::Material{"m"});
  volpar::BodyDef da, db;
  da.name = "a";
  db.name = "b";
  da.material = db.material = m;
  da.source = s.a.source;
  db.source = s.b.source;
  const BodyId a = w->addBody(da, s.a.cloud).value();
  const BodyId b = w->addBody(db, s.b.cloud).value();
  auto setPose = [&](BodyId id, const Vec3& origin, const Quat& q) {
    volpar::BodyState& st = w->bodyState(id);
    const volpar::BodyInfo& info = w->bodies().info[id.index()];
    st.orientation = (q * info.principalInShape).normalized();
    st.position = origin + q * info.comInShape;
  };
  setPose(a, Vec3::Zero(), p.qa);
  setPose(b, p.pb, p.qb);
  w->syncParticles();
  w->refreshContacts();
  return w;
}

Scene makeScene(std::string name, Shape sa, Shape sb) {
  Scene s{std::move(name), std::move(sa), std::move(sb), {}, 0, 0};
  std::mt19937 rng(kSeed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double r = std::max(s.a.radius, s.b.radius);
  while (static_cast<int>(s.poses.size()) < kPoses && s.tried < 50 * kPoses) {
    ++s.tried;
    Pose p;
    for (int attempt = 0; attempt < 1000; ++attempt) {
      p.qa = randomRotation(rng);
      p.qb = randomRotation(rng);
      const Vec3 dir = Vec3(g(rng), g(rng), g(rng)).normalized();
      p.pb = dir * (u(rng) * (s.a.bounding + s.b.bounding));
      p.ref = volpar::reference::primitiveContact(s.a.source, Vec3::Zero(), p.qa, s.b.source, p.pb, p.qb);
      if (p.ref.hit && p.ref.normalValid && p.ref.depth >= 0.1 * r && p.ref.depth <= 1.5 * r) break;
      p.ref.hit = false;
    }
    if (!p.ref.hit) {
      std::fprintf(stderr, "%s: no pose found\n", s.name.c_str());
      std::exit(2);
    }
    p.world = makeWorld(s, p);
    const auto& contacts = p.world->contacts().contacts;
    if (std::none_of(contacts.begin(), contacts.end(), [](const auto& c) { return c.touching(); })) {
      ++s.skipped;
      continue;
    }
    s.poses.push_back(std::move(p));
  }
  if (static_cast<int>(s.poses.size()) < kPoses) {
    std::fprintf(stderr, "%s: only %zu poses with contact\n", s.name.c_str(), s.poses.size());
    std::exit(2);
  }
  return s;
}

// ---------------------------------------------------------------------------------------------------
// FCL A: the two bodies' sphere clusters, manager against manager, contacts enabled

void* tagOf(std::size_t i) { return reinterpret_cast<void*>(static_cast<std::uintptr_t>(i)); }
std::uint32_t tag(const fcl::CollisionObjectd* o) {
  return static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(o->getUserData()));
}

struct NormalAccumulator {
  fcl::CollisionRequestd request{100000, true};  // contacts enabled, no cap worth the name
  std::uint32_t firstB = 0;  ///< particles >= firstB belong to body B
  Vec3 normal = Vec3::Zero();  ///< sum of contact normals x depth, from A towards B
  std::size_t contacts = 0;
  std::vector<IdPair>* pairs = nullptr;  ///< collected when set (checks)
  void reset() {
    normal.setZero();
    contacts = 0;
  }
};

bool onSpherePair(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data) {
  auto* d = static_cast<NormalAccumulator*>(data);
  fcl::CollisionResultd result;
  if (fcl::collide(o1, o2, d->request, result)) {
    const double sign = tag(o1) < d->firstB ? 1.0 : -1.0;  // FCL's normal points from o1 to o2
    for (std::size_t i = 0; i < result.numContacts(); ++i) {
      const fcl::Contactd& c = result.getContact(i);
      d->normal += sign * c.penetration_depth * c.normal;
      ++d->contacts;
    }
    if (d->pairs != nullptr) {
      const std::uint32_t a = tag(o1), b = tag(o2);
      d->pairs->emplace_back(std::min(a, b), std::max(a, b));
    }
  }
  return false;  // keep going: all pairs
}

/// One sphere manager per body of one pose, at the world's particle positions (user data: particle index).
struct FclPose {
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  fcl::DynamicAABBTreeCollisionManagerd managerA, managerB;
  std::uint32_t firstB = 0;

  explicit FclPose(const volpar::World& w) {
    const volpar::ParticleStore& p = w.particles();
    firstB = w.bodies().info[1].particles.front().value;
    std::shared_ptr<fcl::Sphered> sphere;
    for (const BodyId body : {BodyId(0u), BodyId(1u)}) {
      std::vector<fcl::CollisionObjectd*> raw;
      for (const volpar::ParticleId id : w.bodies().info[body.index()].particles) {
        const double r = p.radius[id.index()];
        if (!sphere || sphere->radius != r) sphere = std::make_shared<fcl::Sphered>(r);
        fcl::Transform3d x = fcl::Transform3d::Identity();
        x.translation() = p.position[id.index()];
        objects.push_back(std::make_unique<fcl::CollisionObjectd>(sphere, x));
        objects.back()->setUserData(tagOf(id.index()));
        raw.push_back(objects.back().get());
      }
      auto& m = body == BodyId(0u) ? managerA : managerB;
      m.registerObjects(raw);
      m.setup();
    }
  }
  void collide(NormalAccumulator& acc) {
    acc.reset();
    acc.firstB = firstB;
    managerA.collide(&managerB, &acc, onSpherePair);
  }
};

/// Pairs touching within a relative kGrazing of r_a + r_b: FCL (sqrt) and volpar (squares) may disagree there.
std::size_t grazing(const volpar::World& w, const std::vector<IdPair>& pairs) {
  std::size_t n = 0;
  for (const auto& [a, b] : pairs) {
    const double d = (w.particles().position[a] - w.particles().position[b]).norm();
    const double rs = w.particles().radius[a] + w.particles().radius[b];
    if (std::abs(d - rs) <= volpar::reference::kGrazing * rs) ++n;
  }
  return n;
}

/// The touching contacts of a set as particle pairs, sorted (speculative contacts, depth <= 0, left out).
std::vector<IdPair> volparPairs(const volpar::ContactSet& set) {
  std::vector<IdPair> out;
  for (const auto& c : set.contacts)
    if (c.touching()) out.emplace_back(std::min(c.a.value, c.b.value), std::max(c.a.value, c.b.value));
  std::sort(out.begin(), out.end());
  return out;
}

/// Removes grazing pairs.
std::vector<IdPair> firm(const volpar::World& w, std::vector<IdPair> pairs) {
  std::erase_if(pairs, [&](const IdPair& p) { return grazing(w, {p}) > 0; });
  return pairs;
}

/// The contact search of one pose by a ContactFinder of its own.
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

// ---------------------------------------------------------------------------------------------------
// checks

void checkScene(const Scene& s) {
  volpar::NarrowPhase np;
  volpar::PatchSet out;
  std::size_t samePairs = 0, samePatches = 0, sameSearch = 0, graz = 0;
  std::vector<double> anglePlanes, angleFclA;
  for (const Pose& p : s.poses) {
    const volpar::World& w = *p.world;
    // FCL A against the world's contacts
    FclPose f(w);
    std::vector<IdPair> fclPairs;
    NormalAccumulator acc;
    acc.pairs = &fclPairs;
    f.collide(acc);
    std::sort(fclPairs.begin(), fclPairs.end());
    const auto v = volparPairs(w.contacts());
    graz += grazing(w, fclPairs) + grazing(w, v);
    if (firm(w, fclPairs) == firm(w, v)) ++samePairs;
    // the benchmark's own contact search and narrow phase against the world's
    ContactSearch search(w);
    search.find();
    if (volparPairs(search.set) == v && search.set.contacts.size() == v.size()) ++sameSearch;
    volpar::PlaneSettings planes = w.settings().planes;
    planes.reuse = false;  // each pose on its own
    np.setSettings(planes);
    np.run(w.narrowPhaseInput(), w.contacts(), out);
    const auto& ref = w.patches().patches;
    bool same = out.patches.size() == ref.size();
    for (std::size_t i = 0; same && i < ref.size(); ++i)
      same = out.patches[i].normal == ref[i].normal && out.patches[i].count == ref[i].count;
    if (same) ++samePatches;
    // normals against FCL B's: the patch with the most contacts speaks for the pair, as in the accuracy test
    const auto biggest = std::max_element(out.patches.begin(), out.patches.end(),
                                          [](const auto& x, const auto& y) { return x.count < y.count; });
    if (biggest != out.patches.end()) anglePlanes.push_back(degrees(biggest->normal, p.ref.normal));
    if (acc.normal.norm() > 0) angleFclA.push_back(degrees(acc.normal, p.ref.normal));
  }
  const std::size_t n = s.poses.size();
  char angles[160];
  std::snprintf(angles, sizeof angles, "median angle to FCL B's normal: planes %.2f deg, FCL A's summed normal %.2f deg",
                median(anglePlanes), median(angleFclA));
  const auto& info = s.poses.front().world->bodies().info;
  report(samePairs == n && samePatches == n && sameSearch == n,
         s.name + ": " + std::to_string(info[0].particles.size()) + " + " + std::to_string(info[1].particles.size()) +
             " particles, " + std::to_string(n) + " poses (" + std::to_string(s.skipped) + " of " + std::to_string(s.tried) +
             " skipped: no particle contact); FCL A pairs == volpar contacts in " + std::to_string(samePairs) +
             ", own search == world's in " + std::to_string(sameSearch) + ", own patches == world's in " +
             std::to_string(samePatches) + "; grazing " + std::to_string(graz) + "; " + angles);
}

// ---------------------------------------------------------------------------------------------------
// benchmarks: one iteration = one sweep over the poses

void perPose(benchmark::State& state, const Scene& s) {
  state.counters["per_pose"] = benchmark::Counter(static_cast<double>(s.poses.size()),
                                                  benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

void BM_Planes(benchmark::State& state, const Scene* s) {
  volpar::NarrowPhase np;
  volpar::PlaneSettings planes = s->poses.front().world->settings().planes;
  planes.reuse = false;  // every patch computed (not taken over from the previous pose)
  np.setSettings(planes);
  volpar::PatchSet out;
  double patches = 0, contacts = 0, unvalidated = 0;
  for (const Pose& p : s->poses) {  // untimed: sizes the scratch buffers; the counters
    np.run(p.world->narrowPhaseInput(), p.world->contacts(), out);
    patches += static_cast<double>(out.patches.size());
    contacts += static_cast<double>(p.world->contacts().contacts.size());
    unvalidated += static_cast<double>(out.stats.unvalidated);
  }
  for (auto _ : state) {
    for (const Pose& p : s->poses) {
      np.run(p.world->narrowPhaseInput(), p.world->contacts(), out);
      benchmark::DoNotOptimize(out.patches.data());
    }
    benchmark::ClobberMemory();
  }
  const auto n = static_cast<double>(s->poses.size());
  perPose(state, *s);
  state.counters["patches"] = patches / n;
  state.counters["contacts"] = contacts / n;
  state.counters["unvalidated"] = unvalidated / n;
}

void BM_Contacts(benchmark::State& state, const Scene* s) {
  std::vector<std::unique_ptr<ContactSearch>> searches;
  double contacts = 0;
  for (const Pose& p : s->poses) {  // untimed: the finders (grids, adjacency) and their first search
    searches.push_back(std::make_unique<ContactSearch>(*p.world));
    searches.back()->find();
    contacts += static_cast<double>(searches.back()->set.contacts.size());
  }
  for (auto _ : state) {
    for (auto& search : searches) {
      search->find();
      benchmark::DoNotOptimize(search->set.contacts.data());
    }
    benchmark::ClobberMemory();
  }
  perPose(state, *s);
  state.counters["contacts"] = contacts / static_cast<double>(s->poses.size());
}

void BM_FclParticles(benchmark::State& state, const Scene* s) {
  std::vector<std::unique_ptr<FclPose>> poses;
  for (const Pose& p : s->poses) poses.push_back(std::make_unique<FclPose>(*p.world));  // untimed
  NormalAccumulator acc;
  double contacts = 0;
  for (auto& f : poses) {
    f->collide(acc);
    contacts += static_cast<double>(acc.contacts);
  }
  for (auto _ : state) {
    for (auto& f : poses) {
      f->collide(acc);
      benchmark::DoNotOptimize(acc.normal.data());
    }
    benchmark::ClobberMemory();
  }
  perPose(state, *s);
  state.counters["contacts"] = contacts / static_cast<double>(s->poses.size());
}

void BM_FclPrimitives(benchmark::State& state, const Scene* s) {
  for (auto _ : state) {
    for (const Pose& p : s->poses) {
      const auto c = volpar::reference::primitiveContact(s->a.source, Vec3::Zero(), p.qa, s->b.source, p.pb, p.qb);
      benchmark::DoNotOptimize(c.normal.data());
    }
    benchmark::ClobberMemory();
  }
  perPose(state, *s);
}

void configure(benchmark::internal::Benchmark* b) {
  if (gQuick) {
    b->Iterations(1)->Repetitions(1)->Unit(benchmark::kMicrosecond)->UseRealTime();
    return;
  }
  // real time, also for the per_pose counter (a rate, which would otherwise use CPU time)
  b->Repetitions(5)->ReportAggregatesOnly(true)->Unit(benchmark::kMicrosecond)->UseRealTime();
  addMinMax(b);
}

}  // namespace

int main(int argc, char** argv) {
  gQuick = volpar::bench::takeQuickFlag(argc, argv, "narrow_phase_bench");
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  std::vector<Scene> scenes;
  scenes.push_back(makeScene("box_box", box(), box()));
  scenes.push_back(makeScene("box_sphere", box(), sphere()));
  scenes.push_back(makeScene("sphere_sphere", sphere(), sphere()));
  scenes.push_back(makeScene("capsule_box", capsule(), box()));
  scenes.push_back(makeScene("cylinder_box", cylinder(), box()));
  for (const Scene& s : scenes) checkScene(s);
  for (const Scene& s : scenes) {
    configure(benchmark::RegisterBenchmark((s.name + "/volpar_planes").c_str(), BM_Planes, &s));
    configure(benchmark::RegisterBenchmark((s.name + "/volpar_contacts").c_str(), BM_Contacts, &s));
    configure(benchmark::RegisterBenchmark((s.name + "/fcl_particles").c_str(), BM_FclParticles, &s));
    configure(benchmark::RegisterBenchmark((s.name + "/fcl_primitives").c_str(), BM_FclPrimitives, &s));
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return gChecksFailed ? 1 : 0;
}
