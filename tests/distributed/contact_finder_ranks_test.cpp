// The particle contacts found by MPI processes together (run under mpirun with 1, 2 and 3 processes): each
// searches its share of the pairs and keeps its own candidate lists, and every process then holds the
// contacts one process alone finds, bit for bit, step after step, with one or two threads each; and without
// the others' shares a process's contacts do differ, so the processes really did divide the search.

#include <gtest/gtest.h>
#include <mpi.h>

#include "tests/distributed/mpi_test_support.hpp"
#include "tests/support/test_support.hpp"
#include "volpar/distributed/mpi_process_group.hpp"
#include "volpar/engine/world.hpp"

namespace volpar {
namespace {

using test::everywhere;

// Rigid boxes on a cloth and on a soft cube, a second cloth on a static ball, a floor: pairs of rigid bodies,
// rigid and deformable ones, bodies on a plane, and two cloths that fold onto themselves.
constexpr const char* kScene = R"(name: mixed
dt: 0.004166667
duration: 2.0
gravity: [0, 0, -9.81]
solver: {substeps: 4}
materials:
  m: {density: 500, restitution: 0.0, friction: 0.5}
planes:
  - {normal: [0, 0, 1], offset: 0, material: m}
bodies:
  - {name: ball, kind: static, shape: {sphere: {radius: 0.25}}, fill: {radius: 0.04}, material: m, position: [0, 0, 0.25]}
  - {name: cloth, kind: deformable, shape: {box: {size: [0.9, 0.9, 0.04]}}, fill: {radius: 0.02},
     connectors: {springs: {stiffness: 2000, damping: 2}}, material: m, position: [0, 0, 0.6]}
  - {name: drape, kind: deformable, shape: {box: {size: [0.7, 0.7, 0.04]}}, fill: {radius: 0.02},
     connectors: {springs: {stiffness: 1500, damping: 2}}, material: m, position: [1.2, 0, 0.3]}
  - {name: jelly, kind: deformable, shape: {box: {size: [0.3, 0.3, 0.3]}}, fill: {radius: 0.05},
     connectors: {springs: {stiffness: 20000, damping: 5}}, material: m, position: [-1.0, 0, 0.4]}
  - {name: box, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: m, position: [0.05, 0.1, 1.0],
     angular_velocity: [1, 2, 0]}
  - {name: box2, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: m, position: [0.0, -0.1, 1.4]}
  - {name: box3, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: m, position: [-1.0, 0.0, 0.9]}
  - {name: box4, shape: {box: {size: [0.2, 0.2, 0.2]}}, fill: {radius: 0.05}, material: m, position: [1.2, 0.0, 0.7],
     velocity: [0, 0, -2]}
)";

bool same(const ContactSet& x, const ContactSet& y) {
  if (x.contacts.size() != y.contacts.size() || x.groups.size() != y.groups.size()) return false;
  for (std::size_t i = 0; i < x.groups.size(); ++i) {
    const ContactGroup &g = x.groups[i], &h = y.groups[i];
    if (g.a != h.a || g.b != h.b || g.plane != h.plane || g.first != h.first || g.count != h.count) return false;
  }
  for (std::size_t i = 0; i < x.contacts.size(); ++i) {
    const ParticleContact &c = x.contacts[i], &d = y.contacts[i];
    if (c.a != d.a || c.b != d.b || c.plane != d.plane || c.point != d.point || c.normal != d.normal || c.depth != d.depth)
      return false;
  }
  return true;
}

/// An exchange that hands back this process's share alone, as if it were the only one.
class Alone final : public ProcessGroup {
 public:
  explicit Alone(ProcessGroup& real) : real_(real) {}
  [[nodiscard]] int rank() const override { return real_.rank(); }
  [[nodiscard]] int size() const override { return real_.size(); }
  void share(std::span<std::byte>, std::span<const std::size_t>, std::span<const std::size_t>) override {}
  void gather(std::span<const std::byte> mine, ExchangeBytes& all) override {
    all.assign(mine.begin(), mine.end());
    // (the others' shares empty: two counts of groups, a time and two empty vectors, all zero bytes)
    all.resize(all.size() + static_cast<std::size_t>(size() - 1) * 5 * sizeof(std::uint64_t), std::byte{0});
  }

 private:
  ProcessGroup& real_;
};

struct Compared {
  bool allSame = true;
  std::size_t contacts = 0, selfGroups = 0, planeGroups = 0, bodyGroups = 0;
};

/// Steps the scene alone and, after every step, finds its contacts again with a finder shared by the
/// processes through `exchange`, comparing the two.
Compared compare(ProcessGroup& exchange, int threads, int steps) {
  Compared result;
  World w = test::worldFromString(kScene, "mixed.yaml");
  ContactFinder shared;
  for (std::size_t i = 0; i < w.bodies().size(); ++i) shared.addBody(BodyId(i), w.particles(), w.bodies());
  shared.setMargin(w.settings().contactMargin);
  shared.setSweepTime(w.settings().dt);
  shared.setProcesses(&exchange);
  ThreadPool pool(threads);
  ContactSet found;
  for (int step = 0; step < steps; ++step) {
    if (w.step() != StepStatus::Ok) {
      ADD_FAILURE() << "step " << step;
      result.allSame = false;
      return result;
    }
    shared.find(w.particles(), w.bodies(), w.connectors(), w.bodyPairs(), w.planePairs(), w.planes(), w.bodyBoxes(),
                found, threads > 1 ? &pool : nullptr);
    result.allSame = result.allSame && same(found, w.contacts());
    result.contacts += w.contacts().contacts.size();
    for (const ContactGroup& g : w.contacts().groups) {
      if (g.plane.valid()) ++result.planeGroups;
      else if (g.a == g.b) ++result.selfGroups;
      else ++result.bodyGroups;
    }
  }
  return result;
}

TEST(ContactFinderRanks, EveryProcessFindsTheContactsOfOne) {
  for (const int threads : {1, 2}) {
    MpiProcessGroup exchange(MPI_COMM_WORLD);
    const Compared c = compare(exchange, threads, 240);
    EXPECT_TRUE(everywhere(c.allSame)) << exchange.size() << " processes, " << threads << " threads";
    // (what the comparison saw: every kind of group, many times)
    EXPECT_GT(c.bodyGroups, 200u);
    EXPECT_GT(c.planeGroups, 200u);
    EXPECT_GT(c.selfGroups, 20u);
    EXPECT_GT(c.contacts, 50000u);
    if (exchange.size() > 1) {
      EXPECT_GT(exchange.bytesReceived(), 0u);
    }
  }
}

TEST(ContactFinderRanks, WithoutTheOthersSharesAProcessFindsLess) {
  MpiProcessGroup real(MPI_COMM_WORLD);
  if (real.size() == 1) GTEST_SKIP() << "one process divides nothing";
  Alone alone(real);
  const Compared c = compare(alone, 1, 240);
  EXPECT_TRUE(everywhere(!c.allSame));
}

}  // namespace
}  // namespace volpar
