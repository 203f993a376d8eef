#include "volpar/collision/broadphase.hpp"

#include <algorithm>

namespace volpar {

void Broadphase::addBody(BodyId id, const Aabb& tight, bool isStatic) {
  if (proxies_.size() <= id.index()) proxies_.resize(id.index() + 1);
  Proxy& p = proxies_[id.index()];
  p.isStatic = isStatic;
  p.node = (isStatic ? static_ : moving_).createProxy(tight, isStatic ? 0.0 : margin_, id.value);
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

void Broadphase::moveBody(BodyId id, const Aabb& tight, const Vec3& displacement) {
  const Proxy& p = proxies_[id.index()];
  VOLPAR_ASSERT(!p.isStatic && p.node != AabbTree::kNull, "only moving bodies move");
  if (moving_.moveProxy(p.node, tight, margin_, displacement)) {
    ++reinsertions_;
    if (!moved_[id.index()]) {
      moved_[id.index()] = 1;
      movedList_.push_back(id);
    }
  }
}

const Aabb& Broadphase::fatBox(BodyId id) const {
  const Proxy& p = proxies_[id.index()];
  return (p.isStatic ? static_ : moving_).fatAabb(p.node);
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

void Broadphase::findPairs(std::span<const Plane> planes, std::vector<BodyPair>& pairs,
                           std::vector<BodyPlanePair>& planePairs, ThreadPool* pool) {
  if (pairsDirty_) {
    rebuildPairs();
    pairsDirty_ = false;
  } else if (!movedList_.empty()) {
    // pairs of rebuilt fat boxes: drop those that no longer overlap ...
    auto stale = [&](const BodyPair& pr) {
      return (moved_[pr.a.index()] || moved_[pr.b.index()]) && !fatBox(pr.a).overlaps(fatBox(pr.b));
    };
    pairs_.erase(std::remove_if(pairs_.begin(), pairs_.end(), stale), pairs_.end());
    // ... and find their pairs anew (a pair of two rebuilt boxes is found from the smaller id only; the
    // queries in chunks of the rebuilt bodies where threads share them, their pairs sorted together)
    fresh_.clear();
    const std::size_t moved = movedList_.size();
    if (pool && pool->worthSharing(moved, 64)) {
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
    merged_.resize(pairs_.size() + fresh_.size());
    merged_.erase(std::merge(pairs_.begin(), pairs_.end(), fresh_.begin(), fresh_.end(), merged_.begin()), merged_.end());
    merged_.erase(std::unique(merged_.begin(), merged_.end()), merged_.end());
    std::swap(pairs_, merged_);
  }
  for (const BodyId id : movedList_) moved_[id.index()] = 0;
  movedList_.clear();
  reinsertions_ = 0;

  pairs.assign(pairs_.begin(), pairs_.end());
  planePairs.clear();
  for (const BodyId id : movingBodies_) {
    const Aabb& box = moving_.fatAabb(proxies_[id.index()].node);
    // the box reaches below a plane when its lowest corner along the normal does
    for (std::size_t k = 0; k < planes.size(); ++k) {
      const Plane& pl = planes[k];
      const double lowest = pl.normal.dot(box.centre()) - pl.normal.cwiseAbs().dot(0.5 * (box.hi - box.lo));
      if (lowest <= pl.offset) planePairs.push_back({id, PlaneId(k)});
    }
  }
}

}  // namespace volpar
