#include "collision/broadphase.hpp"

#include <algorithm>

namespace volpar {

void Broadphase::addBody(BodyId id, const Aabb& tight, bool isStatic) {
  if (proxies_.size() <= id.index()) proxies_.resize(id.index() + 1);
  Proxy& p = proxies_[id.index()];
  p.isStatic = isStatic;
  p.node = (isStatic ? static_ : moving_).createProxy(tight, isStatic ? 0.0 : margin_, id.value);
  if (!isStatic) movingBodies_.insert(std::lower_bound(movingBodies_.begin(), movingBodies_.end(), id), id);
}

void Broadphase::removeBody(BodyId id) {
  Proxy& p = proxies_[id.index()];
  if (p.node == AabbTree::kNull) return;
  (p.isStatic ? static_ : moving_).destroyProxy(p.node);
  p.node = AabbTree::kNull;
  if (!p.isStatic) movingBodies_.erase(std::lower_bound(movingBodies_.begin(), movingBodies_.end(), id));
}

void Broadphase::moveBody(BodyId id, const Aabb& tight, const Vec3& displacement) {
  const Proxy& p = proxies_[id.index()];
  VOLPAR_ASSERT(!p.isStatic && p.node != AabbTree::kNull, "only moving bodies move");
  if (moving_.moveProxy(p.node, tight, margin_, displacement)) ++reinsertions_;
}

const Aabb& Broadphase::fatBox(BodyId id) const {
  const Proxy& p = proxies_[id.index()];
  return (p.isStatic ? static_ : moving_).fatAabb(p.node);
}

void Broadphase::findPairs(std::span<const Plane> planes, std::vector<BodyPair>& pairs,
                           std::vector<BodyPlanePair>& planePairs) const {
  pairs.clear();
  planePairs.clear();
  reinsertions_ = 0;
  for (const BodyId id : movingBodies_) {
    const Aabb& box = moving_.fatAabb(proxies_[id.index()].node);
    // moving-moving pairs once (the other body has the larger id), moving-static pairs always
    moving_.query(box, [&](std::int32_t node) {
      const BodyId other(moving_.userData(node));
      if (id < other) pairs.push_back({id, other});
      return true;
    });
    static_.query(box, [&](std::int32_t node) {
      const BodyId other(static_.userData(node));
      pairs.push_back(id < other ? BodyPair{id, other} : BodyPair{other, id});
      return true;
    });
    // the box reaches below a plane when its lowest corner along the normal does
    for (std::size_t k = 0; k < planes.size(); ++k) {
      const Plane& pl = planes[k];
      const double lowest = pl.normal.dot(box.centre()) - pl.normal.cwiseAbs().dot(0.5 * (box.hi - box.lo));
      if (lowest <= pl.offset) planePairs.push_back({id, PlaneId(k)});
    }
  }
  std::sort(pairs.begin(), pairs.end());
}

}  // namespace volpar
