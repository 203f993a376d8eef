#include "volpar/collision/broadphase.hpp"

#include <algorithm>

namespace volpar {

namespace {

/// Drops from the sorted list `kept` the entries `drop` names and merges the sorted `fresh` in, each entry
/// once (an entry both kept and fresh meets itself in a row), in one pass through `scratch`.
template <class T, class Drop>
void mergeFresh(std::vector<T>& kept, const std::vector<T>& fresh, const Drop& drop, std::vector<T>& scratch) {
  scratch.resize(kept.size() + fresh.size());
  auto out = scratch.begin();
  const auto emit = [&](const T& x) {
    if (out == scratch.begin() || out[-1] != x) *out++ = x;
  };
  auto f = fresh.cbegin();
  for (const T& x : kept) {
    for (; f != fresh.cend() && *f < x; ++f) emit(*f);
    if (!drop(x)) emit(x);
  }
  for (; f != fresh.cend(); ++f) emit(*f);
  scratch.erase(out, scratch.end());
  std::swap(kept, scratch);
}

}  // namespace

void Broadphase::addBody(BodyId id, const Aabb& tight, bool isStatic) {
  if (proxies_.size() <= id.index()) proxies_.resize(id.index() + 1);
  Proxy& p = proxies_[id.index()];
  p.isStatic = isStatic;
  p.node = (isStatic ? static_ : moving_).createProxy(tight, isStatic ? 0.0 : margin_, id.value);
  copyFatBox(id);
  if (!isStatic) movingBodies_.insert(std::lower_bound(movingBodies_.begin(), movingBodies_.end(), id), id);
  if (moved_.size() <= id.index()) moved_.resize(id.index() + 1, 0);
  pairsDirty_ = true;
}

void Broadphase::removeBody(BodyId id) {
  Proxy& p = proxies_[id.index()];
  if (p.node == AabbTree::kNull) return;
  (p.isStatic ? static_ : moving_).destroyProxy(p.node);
  p.node = AabbTree::kNull;
  if (!p.isStatic) movingBodies_.erase(std::lower_bound(movingBodies_.begin(), movingBodies_.end(), id));
  pairsDirty_ = true;
}

void Broadphase::copyFatBox(BodyId id) {
  const Proxy& p = proxies_[id.index()];
  if (fat_.size() <= id.index()) fat_.resize(id.index() + 1);
  fat_[id.index()] = (p.isStatic ? static_ : moving_).fatAabb(p.node);
}

void Broadphase::moveBody(BodyId id, const Aabb& tight, const Vec3& displacement) {
  const Proxy& p = proxies_[id.index()];
  VOLPAR_ASSERT(!p.isStatic && p.node != AabbTree::kNull, "only moving bodies move");
  // the test on the compact copy of the fat box; the tree's node is read only for a box that moves
  if (keepsFatBox(id, tight, displacement)) return;
  const bool moved = moving_.moveProxy(p.node, tight, margin_, displacement);
  VOLPAR_ASSERT(moved, "the tree's fat box is the one kept apart");
  copyFatBox(id);
  ++reinsertions_;
  if (!moved_[id.index()]) {
    moved_[id.index()] = 1;
    movedList_.push_back(id);
  }
}

void Broadphase::rebuildPairs() {
  pairs_.clear();
  auto ordered = [](BodyId x, BodyId y) { return x < y ? BodyPair{x, y} : BodyPair{y, x}; };
  moving_.selfPairs(stack_, [&](std::int32_t i, std::int32_t j) {
    pairs_.push_back(ordered(BodyId(moving_.userData(i)), BodyId(moving_.userData(j))));
  });
  moving_.pairsWith(static_, stack_, [&](std::int32_t i, std::int32_t j) {
    pairs_.push_back(ordered(BodyId(moving_.userData(i)), BodyId(static_.userData(j))));
  });
  std::sort(pairs_.begin(), pairs_.end());
}

void Broadphase::queryMoved(std::size_t begin, std::size_t end, std::vector<BodyPair>& out) const {
  for (std::size_t k = begin; k < end; ++k) {
    const BodyId id = movedList_[k];
    const Aabb& box = fatBox(id);
    moving_.query(box, [&](std::int32_t node) {
      const BodyId other(moving_.userData(node));
      if (other == id || (moved_[other.index()] && other < id)) return true;
      out.push_back(id < other ? BodyPair{id, other} : BodyPair{other, id});
      return true;
    });
    static_.query(box, [&](std::int32_t node) {
      const BodyId other(static_.userData(node));
      out.push_back(id < other ? BodyPair{id, other} : BodyPair{other, id});
      return true;
    });
  }
}

void Broadphase::findPlanePairs(BodyId id, std::span<const Plane> planes, std::vector<BodyPlanePair>& out) const {
  const Aabb& box = fatBox(id);
  // the box reaches below a plane when its lowest corner along the normal does
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const Plane& pl = planes[k];
    const double lowest = pl.normal.dot(box.centre()) - pl.normal.cwiseAbs().dot(0.5 * (box.hi - box.lo));
    if (lowest <= pl.offset) out.push_back({id, PlaneId(k)});
  }
}

void Broadphase::findPairs(std::span<const Plane> planes, ThreadPool* pool) {
  const bool everyBody = pairsDirty_;
  if (pairsDirty_) {
    rebuildPairs();
    pairsDirty_ = false;
  } else if (!movedList_.empty()) {
    // find the pairs of rebuilt fat boxes anew (a pair of two rebuilt boxes is found from the smaller id
    // only; the queries in chunks of the rebuilt bodies where threads share them, their pairs sorted
    // together; a query costs a few microseconds, so threads share them from 8 rebuilt boxes a worker:
    // pile-1000's collapse rebuilds fewer than 64 a worker in most steps) ...
    fresh_.clear();
    const std::size_t moved = movedList_.size();
    if (pool && pool->worthSharing(moved, 8)) {
      const std::size_t chunks = ThreadPool::kChunksPerWorker * static_cast<std::size_t>(pool->workers());
      if (freshChunks_.size() < chunks) freshChunks_.resize(chunks);
      pool->runItems(chunks, [&](int, std::size_t c) {
        freshChunks_[c].clear();
        queryMoved(moved * c / chunks, moved * (c + 1) / chunks, freshChunks_[c]);
      });
      for (std::size_t c = 0; c < chunks; ++c) fresh_.insert(fresh_.end(), freshChunks_[c].begin(), freshChunks_[c].end());
    } else {
      queryMoved(0, moved, fresh_);
    }
    std::sort(fresh_.begin(), fresh_.end());
    // ... and, in one pass over the kept list, drop the pairs of rebuilt boxes that no longer overlap and
    // merge the fresh pairs in
    auto stale = [&](const BodyPair& pr) {
      return (moved_[pr.a.index()] || moved_[pr.b.index()]) && !fatBox(pr.a).overlaps(fatBox(pr.b));
    };
    mergeFresh(pairs_, fresh_, stale, merged_);
  }
  // the plane pairs: every body's afresh when the bodies or the planes changed, otherwise only the
  // rebuilt boxes' (the others' boxes and the planes are as they were)
  auto samePlane = [](const Plane& x, const Plane& y) { return x.normal == y.normal && x.offset == y.offset; };
  const bool planesChanged =
      planes.size() != planesSeen_.size() || !std::equal(planes.begin(), planes.end(), planesSeen_.begin(), samePlane);
  if (everyBody || planesChanged) {
    planesSeen_.assign(planes.begin(), planes.end());
    planePairs_.clear();
    for (const BodyId id : movingBodies_) findPlanePairs(id, planes, planePairs_);
  } else if (!movedList_.empty() && !planes.empty()) {
    freshPlanePairs_.clear();
    for (const BodyId id : movedList_) findPlanePairs(id, planes, freshPlanePairs_);
    std::sort(freshPlanePairs_.begin(), freshPlanePairs_.end());
    // (a rebuilt box's plane pairs are all among the fresh ones)
    mergeFresh(planePairs_, freshPlanePairs_, [&](const BodyPlanePair& pr) { return moved_[pr.body.index()] != 0; },
               mergedPlanePairs_);
  }

  for (const BodyId id : movedList_) moved_[id.index()] = 0;
  movedList_.clear();
  reinsertions_ = 0;
}

}  // namespace volpar
