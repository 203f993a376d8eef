#pragma once
// Dynamic AABB tree (docs/architecture.md), after Box2D's b2DynamicTree (Erin Catto) with Bullet's btDbvt
// ideas: leaves hold *fat* boxes (the tight box grown by a margin and by the predicted displacement), so a
// proxy whose tight box stays inside its fat box costs nothing to move. Insertion descends by the
// surface-area heuristic (branch cost = area growth of the ancestors), and AVL rotations after every
// insertion and removal keep every internal node's subtrees within one level of each other, so the
// height stays O(log n). Nodes live in one array and are addressed by index; freed nodes are recycled.

#include <cstdint>
#include <string>
#include <vector>

#include "volpar/collision/aabb.hpp"
#include "volpar/engine/core/status.hpp"

namespace volpar {

/// Depth-first traversal stack on the caller's stack: queries allocate nothing and may run concurrently.
/// An AVL-balanced tree of 2^32 leaves is under 47 levels deep, and the stack holds at most height + 1.
class TraversalStack {
 public:
  void push(std::int32_t i) {
    VOLPAR_ASSERT(size_ < kCapacity, "tree deeper than the traversal stack");
    items_[size_++] = i;
  }
  std::int32_t pop() { return items_[--size_]; }
  [[nodiscard]] bool empty() const { return size_ == 0; }

 private:
  static constexpr std::size_t kCapacity = 128;
  std::int32_t items_[kCapacity];
  std::size_t size_ = 0;
};

class AabbTree {
 public:
  static constexpr std::int32_t kNull = -1;

  /// Inserts a proxy for `tight`, stored fattened by `margin` [m]; returns its id.
  std::int32_t createProxy(const Aabb& tight, double margin, std::uint32_t userData);
  void destroyProxy(std::int32_t proxy);
  /// Updates a proxy. If `tight` still lies inside its fat box nothing happens and false is returned;
  /// otherwise the proxy is reinserted with a box grown by `margin` and by `displacement` [m] (the
  /// expected motion until the next update) and true is returned.
  bool moveProxy(std::int32_t proxy, const Aabb& tight, double margin, const Vec3& displacement);
  /// Whether a proxy whose fat box is `fat` stays as it is when moved to `tight` (moveProxy's test, for a
  /// caller that holds the fat boxes apart from the tree's nodes and so can test without touching them).
  [[nodiscard]] static bool keepsFatBox(const Aabb& fat, const Aabb& tight, double margin, const Vec3& displacement);

  [[nodiscard]] const Aabb& fatAabb(std::int32_t proxy) const { return nodes_[static_cast<std::size_t>(proxy)].box; }
  [[nodiscard]] std::uint32_t userData(std::int32_t proxy) const {
    return static_cast<std::uint32_t>(nodes_[static_cast<std::size_t>(proxy)].child2);
  }
  [[nodiscard]] std::size_t proxyCount() const { return leafCount_; }
  /// Height of the tree (a single leaf has height 0; empty: -1).
  [[nodiscard]] int height() const { return root_ == kNull ? -1 : nodes_[static_cast<std::size_t>(root_)].height; }

  /// Calls f(proxy) for every proxy whose fat box overlaps `box`; f returns false to stop.
  template <class F>
  void query(const Aabb& box, F&& f) const;

  /// Calls f(proxy, tEnter) for every proxy whose fat box the segment origin + t dir, t in [0, maxT],
  /// enters (slab test); f returns the new maxT (return the old one to keep going, 0 to stop).
  template <class F>
  void rayCast(const Vec3& origin, const Vec3& dir, double maxT, F&& f) const;

  /// Calls f(proxyA, proxyB) once for every pair of this tree's proxies whose fat boxes overlap, by a
  /// simultaneous descent of the tree against itself (far fewer node visits than one query per proxy).
  /// `stack` is scratch that keeps its capacity between calls.
  template <class F>
  void selfPairs(std::vector<std::pair<std::int32_t, std::int32_t>>& stack, F&& f) const;
  /// Likewise for every pair (proxy of this tree, proxy of `other`) whose fat boxes overlap.
  template <class F>
  void pairsWith(const AabbTree& other, std::vector<std::pair<std::int32_t, std::int32_t>>& stack, F&& f) const;

  /// Checks the structure: parents enclose children, heights and parent links are right, every internal
  /// node is AVL-balanced, the free list and leaf count add up. Returns an empty string when all hold,
  /// otherwise what is wrong.
  [[nodiscard]] std::string validate() const;

 private:
  /// One cache line: a traversal reads one line per node it visits.
  struct alignas(64) Node {
    Aabb box;
    std::int32_t parent = kNull;  ///< also the next free node while on the free list
    std::int32_t child1 = kNull;  ///< kNull: a leaf
    std::int32_t child2 = kNull;  ///< a leaf's user data (as the bits of a std::uint32_t)
    std::int32_t height = -1;     ///< leaf 0, free -1
    [[nodiscard]] bool leaf() const { return child1 == kNull; }
  };
  static_assert(sizeof(Node) == 64);

  std::int32_t allocate();
  void release(std::int32_t node);
  void insertLeaf(std::int32_t leaf);
  void removeLeaf(std::int32_t leaf);
  std::int32_t balance(std::int32_t a);
  void refit(std::int32_t index);  // heights, boxes and balance from index up to the root
  [[nodiscard]] std::string validateNode(std::int32_t index, int& leaves) const;

  std::vector<Node> nodes_;
  std::int32_t root_ = kNull;
  std::int32_t freeList_ = kNull;
  std::size_t leafCount_ = 0;
};



template <class F>
void AabbTree::query(const Aabb& box, F&& f) const {
  if (root_ == kNull) return;
  TraversalStack stack;
  stack.push(root_);
  while (!stack.empty()) {
    const std::int32_t i = stack.pop();
    const Node& n = nodes_[static_cast<std::size_t>(i)];
    if (!n.box.overlaps(box)) continue;
    if (n.leaf()) {
      if (!f(i)) return;
    } else {
      stack.push(n.child1);
      stack.push(n.child2);
    }
  }
}

template <class F>
void AabbTree::pairsWith(const AabbTree& other, std::vector<std::pair<std::int32_t, std::int32_t>>& stack, F&& f) const {
  stack.clear();
  if (root_ == kNull || other.root_ == kNull) return;
  stack.emplace_back(root_, other.root_);
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    const Node& a = nodes_[static_cast<std::size_t>(i)];
    const Node& b = other.nodes_[static_cast<std::size_t>(j)];
    if (!a.box.overlaps(b.box)) continue;
    if (a.leaf() && b.leaf()) {
      f(i, j);
    } else if (b.leaf() || (!a.leaf() && a.box.area() >= b.box.area())) {  // descend the larger node
      stack.emplace_back(a.child1, j);
      stack.emplace_back(a.child2, j);
    } else {
      stack.emplace_back(i, b.child1);
      stack.emplace_back(i, b.child2);
    }
  }
}

template <class F>
void AabbTree::selfPairs(std::vector<std::pair<std::int32_t, std::int32_t>>& stack, F&& f) const {
  stack.clear();
  if (root_ == kNull) return;
  // (i, i) means "pairs inside subtree i"; (i, j) with i != j means "pairs across subtrees i and j"
  stack.emplace_back(root_, root_);
  while (!stack.empty()) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    const Node& a = nodes_[static_cast<std::size_t>(i)];
    if (i == j) {
      if (a.leaf()) continue;
      stack.emplace_back(a.child1, a.child1);
      stack.emplace_back(a.child2, a.child2);
      stack.emplace_back(a.child1, a.child2);
      continue;
    }
    const Node& b = nodes_[static_cast<std::size_t>(j)];
    if (!a.box.overlaps(b.box)) continue;
    if (a.leaf() && b.leaf()) {
      f(i, j);
    } else if (b.leaf() || (!a.leaf() && a.box.area() >= b.box.area())) {
      stack.emplace_back(a.child1, j);
      stack.emplace_back(a.child2, j);
    } else {
      stack.emplace_back(i, b.child1);
      stack.emplace_back(i, b.child2);
    }
  }
}

template <class F>
void AabbTree::rayCast(const Vec3& origin, const Vec3& dir, double maxT, F&& f) const {
  if (root_ == kNull) return;
  const Vec3 inv(1.0 / dir.x(), 1.0 / dir.y(), 1.0 / dir.z());
  auto enter = [&](const Aabb& b, double& tEnter) {
    double t0 = 0.0, t1 = maxT;
    for (int k = 0; k < 3; ++k) {
      if (dir[k] == 0.0) {
        if (origin[k] < b.lo[k] || origin[k] > b.hi[k]) return false;
        continue;
      }
      double ta = (b.lo[k] - origin[k]) * inv[k], tb = (b.hi[k] - origin[k]) * inv[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
      if (t0 > t1) return false;
    }
    tEnter = t0;
    return true;
  };
  TraversalStack stack;
  stack.push(root_);
  while (!stack.empty()) {
    const std::int32_t i = stack.pop();
    const Node& n = nodes_[static_cast<std::size_t>(i)];
    double t = 0.0;
    if (!enter(n.box, t)) continue;
    if (n.leaf()) {
      maxT = f(i, t);
      if (maxT <= 0.0) return;
    } else {
      stack.push(n.child1);
      stack.push(n.child2);
    }
  }
}

}  // namespace volpar
