#pragma once
// Body-level broadphase: two dynamic AABB trees, one for moving bodies and one for static bodies, so
// static-static pairs never arise. The pair list persists between steps, as in Box2D: a body that stays
// inside its fat box neither queries nor changes its pairs; each step only the pairs of bodies whose fat
// boxes were rebuilt are re-examined (dropped if the fat boxes no longer overlap, added from one query per
// such body). After bodies are added or removed the list is rebuilt by a simultaneous descent of the
// moving tree against itself and against the static tree. The list is kept sorted, so its order is
// deterministic. Planes are tested against the fat boxes directly (there are few of them).
//
// The fat boxes are also kept apart from the trees, by body index, so that the step's passes over every
// body (whether its box left its fat box, which planes its fat box reaches) and over every pair (whether a
// rebuilt pair still overlaps) read one compact array instead of a tree node per body. The list is
// updated in one pass (stale pairs dropped, fresh ones merged in) and read where it lies.

#include <cstdint>
#include <span>
#include <vector>

#include "volpar/collision/aabb_tree.hpp"
#include "volpar/engine/core/ids.hpp"
#include "volpar/engine/core/plane.hpp"
#include "volpar/engine/core/thread_pool.hpp"

namespace volpar {

struct BodyPair {
  BodyId a;  ///< a < b
  BodyId b;
  auto operator<=>(const BodyPair&) const = default;
};

struct BodyPlanePair {
  BodyId body;
  PlaneId plane;
  auto operator<=>(const BodyPlanePair&) const = default;
};

class Broadphase {
 public:
  /// `margin` [m]: how far a fat box reaches beyond the tight one.
  void setMargin(double margin) { margin_ = margin; }
  [[nodiscard]] double margin() const { return margin_; }

  void addBody(BodyId id, const Aabb& tight, bool isStatic);
  /// Adds a body with the fat box it had (a world restored from a checkpoint finds the same pairs).
  void restoreBody(BodyId id, const Aabb& fat, bool isStatic);
  void removeBody(BodyId id);
  /// Updates a moving body's box; `displacement` [m] is its expected motion over the next step.
  void moveBody(BodyId id, const Aabb& tight, const Vec3& displacement);
  /// Whether moveBody(id, tight, displacement) would leave the body's fat box as it is (a read only:
  /// threads may test many bodies at once, and then move those that fail one after another).
  [[nodiscard]] bool keepsFatBox(BodyId id, const Aabb& tight, const Vec3& displacement) const {
    return AabbTree::keepsFatBox(fat_[id.index()], tight, margin_, displacement);
  }

  /// Finds every pair of bodies whose fat boxes overlap (at least one of them moving), sorted, and every
  /// (moving body, plane) pair whose fat box reaches the plane's solid side, sorted; pairs() and
  /// planePairs() hold them until the next call. With a `pool`, the queries of the bodies whose fat boxes
  /// were rebuilt are shared among its threads; the pairs are the same.
  void findPairs(std::span<const Plane> planes, ThreadPool* pool = nullptr);
  [[nodiscard]] std::span<const BodyPair> pairs() const { return pairs_; }
  [[nodiscard]] std::span<const BodyPlanePair> planePairs() const { return planePairs_; }

  [[nodiscard]] const AabbTree& movingTree() const { return moving_; }
  [[nodiscard]] const AabbTree& staticTree() const { return static_; }
  [[nodiscard]] bool isStatic(BodyId id) const { return proxies_[id.index()].isStatic; }
  [[nodiscard]] const Aabb& fatBox(BodyId id) const { return fat_[id.index()]; }
  /// Number of proxies moved (reinserted) by the last moveBody calls since the last findPairs.
  [[nodiscard]] std::size_t reinsertions() const { return reinsertions_; }

 private:
  struct Proxy {
    std::int32_t node = AabbTree::kNull;
    bool isStatic = false;
  };
  AabbTree moving_;
  AabbTree static_;
  std::vector<Proxy> proxies_;  // by body index
  std::vector<Aabb> fat_;       // by body index: the fat box of its proxy, as the tree holds it
  std::vector<BodyId> movingBodies_;  // ascending
  void rebuildPairs();
  /// Appends the (body, plane) pairs whose plane the body's fat box reaches.
  void findPlanePairs(BodyId id, std::span<const Plane> planes, std::vector<BodyPlanePair>& out) const;
  /// Copies a proxy's fat box from its tree into fat_.
  void copyFatBox(BodyId id);
  /// Appends the pairs of movedList_[begin, end) (a pair of two moved bodies from the smaller id only).
  void queryMoved(std::size_t begin, std::size_t end, std::vector<BodyPair>& out) const;

  double margin_ = 0.05;
  std::size_t reinsertions_ = 0;
  std::vector<std::pair<std::int32_t, std::int32_t>> stack_;  // traversal scratch
  std::vector<BodyPair> pairs_;                // persistent, sorted
  std::vector<BodyPlanePair> planePairs_;      // sorted
  std::vector<BodyPlanePair> freshPlanePairs_, mergedPlanePairs_;  // scratch
  std::vector<Plane> planesSeen_;              // the planes planePairs_ was found for
  std::vector<BodyPair> fresh_, merged_;       // scratch
  std::vector<std::vector<BodyPair>> freshChunks_;  // scratch: the pairs found by each chunk of the queries
  bool pairsDirty_ = true;
  std::vector<std::uint8_t> moved_;            // by body: fat box rebuilt since the last findPairs
  std::vector<BodyId> movedList_;
};

}  // namespace volpar
