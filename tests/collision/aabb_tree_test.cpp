// The dynamic AABB tree and the broadphase: invariants under random churn, pair sets equal to brute force,
// and a superset of what FCL's dynamic AABB tree manager reports.

#include <fcl/fcl.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include "volpar/collision/aabb_tree.hpp"
#include "volpar/collision/broadphase.hpp"

namespace volpar {
namespace {

Aabb randomBox(std::mt19937& rng, double world) {
  std::uniform_real_distribution<double> pos(-world, world), size(0.05, 0.6);
  const Vec3 c(pos(rng), pos(rng), pos(rng));
  const Vec3 h(size(rng), size(rng), size(rng));
  return {c - 0.5 * h, c + 0.5 * h};
}

TEST(AabbTree, InvariantsHoldUnderTenThousandRandomOperations) {
  std::mt19937 rng(11);
  AabbTree tree;
  std::map<std::int32_t, Aabb> tight;  // proxy -> its current tight box
  std::uniform_int_distribution<int> op(0, 9);
  std::normal_distribution<double> step(0.0, 0.1);
  const double margin = 0.1;
  for (int i = 0; i < 10000; ++i) {
    const int o = op(rng);
    if (tight.size() < 20 || o < 3) {  // insert
      const Aabb b = randomBox(rng, 10.0);
      tight[tree.createProxy(b, margin, static_cast<std::uint32_t>(i))] = b;
    } else if (o < 5) {  // remove a random proxy
      auto it = tight.begin();
      std::advance(it, std::uniform_int_distribution<std::size_t>(0, tight.size() - 1)(rng));
      tree.destroyProxy(it->first);
      tight.erase(it);
    } else {  // move a random proxy a little (often staying inside its fat box)
      auto it = tight.begin();
      std::advance(it, std::uniform_int_distribution<std::size_t>(0, tight.size() - 1)(rng));
      const Vec3 d(step(rng), step(rng), step(rng));
      it->second = {it->second.lo + d, it->second.hi + d};
      tree.moveProxy(it->first, it->second, margin, d);
    }
    ASSERT_EQ(tree.validate(), "") << "after operation " << i;
    if (i % 100 == 0 || i == 9999) {
      for (const auto& [proxy, box] : tight) ASSERT_TRUE(tree.fatAabb(proxy).contains(box)) << "after operation " << i;
    }
  }
  ASSERT_EQ(tree.proxyCount(), tight.size());
  // AVL balance bounds the height by 1.44 log2(n + 2)
  EXPECT_LE(tree.height(), static_cast<int>(1.45 * std::log2(static_cast<double>(tight.size()) + 2.0)) + 1);
}

TEST(AabbTree, StayingInsideTheFatBoxCostsNothing) {
  AabbTree tree;
  const Aabb b{Vec3(0, 0, 0), Vec3(1, 1, 1)};
  const std::int32_t p = tree.createProxy(b, 0.2, 7);
  EXPECT_FALSE(tree.moveProxy(p, {Vec3(0.1, 0.1, 0.1), Vec3(1.1, 1.1, 1.1)}, 0.2, Vec3::Zero()));
  EXPECT_TRUE(tree.moveProxy(p, {Vec3(0.5, 0, 0), Vec3(1.5, 1, 1)}, 0.2, Vec3(0.5, 0, 0)));
  // the new fat box is stretched along the displacement
  EXPECT_NEAR(tree.fatAabb(p).hi.x(), 1.5 + 0.2 + 0.5, 1e-15);
  EXPECT_NEAR(tree.fatAabb(p).lo.x(), 0.5 - 0.2, 1e-15);
  EXPECT_EQ(tree.userData(p), 7u);
}

TEST(AabbTree, RayCastFindsTheBoxesOnTheSegment) {
  AabbTree tree;
  std::vector<std::int32_t> ids;
  for (int i = 0; i < 10; ++i) ids.push_back(tree.createProxy({Vec3(i, 0, 0), Vec3(i + 0.5, 1, 1)}, 0.0, static_cast<std::uint32_t>(i)));
  std::set<std::uint32_t> hit;
  tree.rayCast(Vec3(-1, 0.5, 0.5), Vec3(1, 0, 0), 5.2, [&](std::int32_t p, double t) {
    hit.insert(tree.userData(p));
    EXPECT_NEAR(t, tree.fatAabb(p).lo.x() + 1.0, 1e-12);
    return 5.2;
  });
  EXPECT_EQ(hit, (std::set<std::uint32_t>{0, 1, 2, 3, 4}));
  hit.clear();
  tree.rayCast(Vec3(-1, 2, 0.5), Vec3(1, 0, 0), 100, [&](std::int32_t p, double) {
    hit.insert(tree.userData(p));
    return 100.0;
  });
  EXPECT_TRUE(hit.empty());
}

/// FCL's dynamic AABB tree manager over the same tight boxes.
std::set<std::pair<std::uint32_t, std::uint32_t>> fclPairs(const std::vector<Aabb>& boxes, const std::vector<bool>& isStatic) {
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects;
  std::vector<fcl::CollisionObjectd*> raw;
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Vec3 size = boxes[i].hi - boxes[i].lo;
    fcl::Transform3d x = fcl::Transform3d::Identity();
    x.translation() = boxes[i].centre();
    objects.push_back(std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Boxd>(size.x(), size.y(), size.z()), x));
    objects.back()->setUserData(reinterpret_cast<void*>(static_cast<std::uintptr_t>(i)));
    raw.push_back(objects.back().get());
  }
  fcl::DynamicAABBTreeCollisionManagerd manager;
  manager.registerObjects(raw);
  manager.setup();
  struct Data {
    std::set<std::pair<std::uint32_t, std::uint32_t>> pairs;
    const std::vector<bool>* isStatic;
  } data{{}, &isStatic};
  manager.collide(&data, [](fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* d) {
    auto* out = static_cast<Data*>(d);
    const auto a = static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(o1->getUserData()));
    const auto b = static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(o2->getUserData()));
    if ((*out->isStatic)[a] && (*out->isStatic)[b]) return false;
    out->pairs.insert({std::min(a, b), std::max(a, b)});
    return false;
  });
  return data.pairs;
}

// (rounds 0, 2 and 4 find the pairs on one thread; 1 and 3 share the queries of the moved bodies among
// three threads)
TEST(Broadphase, PairsEqualBruteForceAndContainFclsPairs) {
  std::mt19937 rng(5);
  std::normal_distribution<double> step(0.0, 0.15);
  ThreadPool threads(3);
  for (int round = 0; round < 5; ++round) {
    ThreadPool* pool = round % 2 == 1 ? &threads : nullptr;
    const std::size_t n = 600;
    std::vector<Aabb> boxes;
    std::vector<bool> isStatic;
    Broadphase bp;
    bp.setMargin(0.1);
    for (std::size_t i = 0; i < n; ++i) {
      boxes.push_back(randomBox(rng, 4.0));
      isStatic.push_back(i % 7 == 0);
      bp.addBody(BodyId(i), boxes.back(), isStatic.back());
    }
    std::vector<Plane> planes{Plane{Vec3::UnitZ(), -3.5, MaterialId{}}, Plane{Vec3(1, 1, 0).normalized(), -4.0, MaterialId{}}};
    for (int frame = 0; frame < 10; ++frame) {
      // the planes' pairs are kept from frame to frame for the boxes that stay; a plane that moves, or
      // one added, must be seen
      if (frame == 4) planes[1].offset = -2.5;
      if (frame == 7) planes.push_back(Plane{Vec3(0, -1, 1).normalized(), -2.0, MaterialId{}});
      for (std::size_t i = 0; i < n; ++i) {
        if (isStatic[i]) continue;
        const Vec3 d(step(rng), step(rng), step(rng));
        boxes[i] = {boxes[i].lo + d, boxes[i].hi + d};
        bp.moveBody(BodyId(i), boxes[i], d);
      }
      bp.findPairs(planes, pool);
      const std::vector<BodyPair> pairs(bp.pairs().begin(), bp.pairs().end());
      std::vector<BodyPlanePair> planePairs(bp.planePairs().begin(), bp.planePairs().end());
      ASSERT_EQ(bp.movingTree().validate(), "");
      // brute force over the fat boxes: exactly the same list, each pair once, sorted
      std::vector<BodyPair> brute;
      for (std::size_t i = 0; i < n; ++i)
        for (std::size_t j = i + 1; j < n; ++j)
          if (!(isStatic[i] && isStatic[j]) && bp.fatBox(BodyId(i)).overlaps(bp.fatBox(BodyId(j)))) brute.push_back({BodyId(i), BodyId(j)});
      ASSERT_EQ(pairs, brute);
      std::vector<BodyPlanePair> brutePlanes;
      for (std::size_t i = 0; i < n; ++i) {
        if (isStatic[i]) continue;
        const Aabb& f = bp.fatBox(BodyId(i));
        for (std::size_t k = 0; k < planes.size(); ++k) {
          double lowest = std::numeric_limits<double>::infinity();
          for (int c = 0; c < 8; ++c)
            lowest = std::min(lowest, planes[k].normal.dot(Vec3(c & 1 ? f.hi.x() : f.lo.x(), c & 2 ? f.hi.y() : f.lo.y(), c & 4 ? f.hi.z() : f.lo.z())));
          if (lowest <= planes[k].offset + 1e-12) brutePlanes.push_back({BodyId(i), PlaneId(k)});
        }
      }
      std::sort(planePairs.begin(), planePairs.end());
      ASSERT_EQ(planePairs, brutePlanes);
      // every pair FCL's manager reports for the tight boxes is among them
      for (const auto& [a, b] : fclPairs(boxes, isStatic))
        ASSERT_TRUE(std::binary_search(pairs.begin(), pairs.end(), BodyPair{BodyId(a), BodyId(b)})) << a << " " << b;
    }
  }
}

}  // namespace
}  // namespace volpar
