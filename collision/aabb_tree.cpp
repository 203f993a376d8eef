#include "volpar/collision/aabb_tree.hpp"

#include <sstream>

namespace volpar {

namespace {

Aabb fatten(const Aabb& tight, double margin, const Vec3& displacement) {
  Aabb fat = tight.expanded(margin);
  fat.lo += displacement.cwiseMin(0.0);
  fat.hi += displacement.cwiseMax(0.0);
  return fat;
}

}  // namespace

std::int32_t AabbTree::allocate() {
  if (freeList_ == kNull) {
    nodes_.emplace_back();
    nodes_.back().height = 0;
    return static_cast<std::int32_t>(nodes_.size() - 1);
  }
  const std::int32_t i = freeList_;
  Node& n = nodes_[static_cast<std::size_t>(i)];
  freeList_ = n.parent;
  n = Node{};
  n.height = 0;
  return i;
}

void AabbTree::release(std::int32_t i) {
  Node& n = nodes_[static_cast<std::size_t>(i)];
  n = Node{};
  n.parent = freeList_;
  n.height = -1;
  freeList_ = i;
}

std::int32_t AabbTree::createProxy(const Aabb& tight, double margin, std::uint32_t userData) {
  const std::int32_t leaf = allocate();
  Node& n = nodes_[static_cast<std::size_t>(leaf)];
  n.box = fatten(tight, margin, Vec3::Zero());
  n.child2 = static_cast<std::int32_t>(userData);
  insertLeaf(leaf);
  ++leafCount_;
  return leaf;
}

void AabbTree::destroyProxy(std::int32_t proxy) {
  VOLPAR_ASSERT(nodes_[static_cast<std::size_t>(proxy)].leaf(), "not a proxy");
  removeLeaf(proxy);
  release(proxy);
  --leafCount_;
}

bool AabbTree::keepsFatBox(const Aabb& fat, const Aabb& tight, double margin, const Vec3& displacement) {
  if (!fat.contains(tight)) return false;
  // still inside; but a box left huge by earlier fast motion is shrunk (as Box2D does)
  return fatten(tight, margin, displacement).expanded(4.0 * margin).contains(fat);
}

bool AabbTree::moveProxy(std::int32_t proxy, const Aabb& tight, double margin, const Vec3& displacement) {
  if (keepsFatBox(nodes_[static_cast<std::size_t>(proxy)].box, tight, margin, displacement)) return false;
  removeLeaf(proxy);
  nodes_[static_cast<std::size_t>(proxy)].box = fatten(tight, margin, displacement);
  insertLeaf(proxy);
  return true;
}

void AabbTree::insertLeaf(std::int32_t leaf) {
  if (root_ == kNull) {
    root_ = leaf;
    nodes_[static_cast<std::size_t>(leaf)].parent = kNull;
    return;
  }
  // find the best sibling by the surface-area heuristic (Box2D v2.4 descent)
  const Aabb leafBox = nodes_[static_cast<std::size_t>(leaf)].box;
  std::int32_t index = root_;
  while (!nodes_[static_cast<std::size_t>(index)].leaf()) {
    const Node& n = nodes_[static_cast<std::size_t>(index)];
    const double area = n.box.area();
    const double combinedArea = n.box.merged(leafBox).area();
    // cost of making a new parent for this node and the leaf
    const double cost = 2.0 * combinedArea;
    // the least cost of pushing the leaf further down
    const double inheritance = 2.0 * (combinedArea - area);
    auto descendCost = [&](std::int32_t c) {
      const Node& child = nodes_[static_cast<std::size_t>(c)];
      const double merged = child.box.merged(leafBox).area();
      return (child.leaf() ? merged : merged - child.box.area()) + inheritance;
    };
    const double cost1 = descendCost(n.child1);
    const double cost2 = descendCost(n.child2);
    if (cost < cost1 && cost < cost2) break;
    index = cost1 < cost2 ? n.child1 : n.child2;
  }
  const std::int32_t sibling = index;

  // a new parent for the sibling and the leaf
  const std::int32_t oldParent = nodes_[static_cast<std::size_t>(sibling)].parent;
  const std::int32_t newParent = allocate();
  {
    Node& p = nodes_[static_cast<std::size_t>(newParent)];
    p.parent = oldParent;
    p.box = leafBox.merged(nodes_[static_cast<std::size_t>(sibling)].box);
    p.height = nodes_[static_cast<std::size_t>(sibling)].height + 1;
    p.child1 = sibling;
    p.child2 = leaf;
  }
  if (oldParent != kNull) {
    Node& op = nodes_[static_cast<std::size_t>(oldParent)];
    (op.child1 == sibling ? op.child1 : op.child2) = newParent;
  } else {
    root_ = newParent;
  }
  nodes_[static_cast<std::size_t>(sibling)].parent = newParent;
  nodes_[static_cast<std::size_t>(leaf)].parent = newParent;
  refit(newParent);
}

void AabbTree::removeLeaf(std::int32_t leaf) {
  if (leaf == root_) {
    root_ = kNull;
    return;
  }
  const std::int32_t parent = nodes_[static_cast<std::size_t>(leaf)].parent;
  const Node& p = nodes_[static_cast<std::size_t>(parent)];
  const std::int32_t grandParent = p.parent;
  const std::int32_t sibling = p.child1 == leaf ? p.child2 : p.child1;
  if (grandParent != kNull) {
    Node& g = nodes_[static_cast<std::size_t>(grandParent)];
    (g.child1 == parent ? g.child1 : g.child2) = sibling;
    nodes_[static_cast<std::size_t>(sibling)].parent = grandParent;
    release(parent);
    refit(grandParent);
  } else {
    root_ = sibling;
    nodes_[static_cast<std::size_t>(sibling)].parent = kNull;
    release(parent);
  }
}

void AabbTree::refit(std::int32_t index) {
  // a node above the first that neither turns nor changes its box or height leaves every node above it
  // as it was, so the walk stops there
  for (bool first = true; index != kNull; first = false) {
    const std::int32_t before = index;
    index = balance(index);
    Node& n = nodes_[static_cast<std::size_t>(index)];
    const Node& c1 = nodes_[static_cast<std::size_t>(n.child1)];
    const Node& c2 = nodes_[static_cast<std::size_t>(n.child2)];
    const std::int32_t height = 1 + std::max(c1.height, c2.height);
    const Aabb box = c1.box.merged(c2.box);
    if (!first && index == before && height == n.height && box.lo == n.box.lo && box.hi == n.box.hi) return;
    n.height = height;
    n.box = box;
    index = n.parent;
  }
}

// A rotation lifts the taller child when the two subtrees of a differ by more than one level
// (Box2D's b2DynamicTree::Balance). The children of a node are unordered, so the taller grandchild
// can always stay high and one rotation restores the AVL property.
std::int32_t AabbTree::balance(std::int32_t iA) {
  Node& a = nodes_[static_cast<std::size_t>(iA)];
  if (a.leaf() || a.height < 2) return iA;
  const std::int32_t iB = a.child1;
  const std::int32_t iC = a.child2;
  Node& b = nodes_[static_cast<std::size_t>(iB)];
  Node& c = nodes_[static_cast<std::size_t>(iC)];
  const int difference = c.height - b.height;

  // lift `up` (a child of a) above a; `other` is a's other child
  auto lift = [&](std::int32_t iUp, Node& up, Node& other, bool upIsChild2) {
    const std::int32_t iF = up.child1;
    const std::int32_t iG = up.child2;
    Node& f = nodes_[static_cast<std::size_t>(iF)];
    Node& g = nodes_[static_cast<std::size_t>(iG)];
    // up takes a's place
    up.child1 = iA;
    up.parent = a.parent;
    a.parent = iUp;
    if (up.parent != kNull) {
      Node& pp = nodes_[static_cast<std::size_t>(up.parent)];
      (pp.child1 == iA ? pp.child1 : pp.child2) = iUp;
    } else {
      root_ = iUp;
    }
    // the taller grandchild stays with up, the shorter one goes under a
    const bool fTaller = f.height > g.height;
    const std::int32_t iTall = fTaller ? iF : iG;
    const std::int32_t iShort = fTaller ? iG : iF;
    Node& tall = fTaller ? f : g;
    Node& shorter = fTaller ? g : f;
    up.child2 = iTall;
    (upIsChild2 ? a.child2 : a.child1) = iShort;
    shorter.parent = iA;
    a.box = other.box.merged(shorter.box);
    up.box = a.box.merged(tall.box);
    a.height = 1 + std::max(other.height, shorter.height);
    up.height = 1 + std::max(a.height, tall.height);
    return iUp;
  };
  if (difference > 1) return lift(iC, c, b, true);
  if (difference < -1) return lift(iB, b, c, false);
  return iA;
}

std::string AabbTree::validateNode(std::int32_t i, int& leaves) const {
  const Node& n = nodes_[static_cast<std::size_t>(i)];
  std::ostringstream err;
  if (n.height < 0) return "node " + std::to_string(i) + " is on the free list but in the tree";
  if (!n.box.valid()) return "node " + std::to_string(i) + " has an empty box";
  if (n.leaf()) {
    if (n.height != 0) return "leaf " + std::to_string(i) + " malformed";
    ++leaves;
    return "";
  }
  const Node& c1 = nodes_[static_cast<std::size_t>(n.child1)];
  const Node& c2 = nodes_[static_cast<std::size_t>(n.child2)];
  if (c1.parent != i || c2.parent != i) return "node " + std::to_string(i) + ": a child's parent link is wrong";
  if (n.height != 1 + std::max(c1.height, c2.height)) return "node " + std::to_string(i) + ": wrong height";
  if (std::abs(c1.height - c2.height) > 1) return "node " + std::to_string(i) + " is not balanced";
  if (!n.box.contains(c1.box) || !n.box.contains(c2.box)) return "node " + std::to_string(i) + " does not enclose a child";
  std::string e = validateNode(n.child1, leaves);
  if (!e.empty()) return e;
  return validateNode(n.child2, leaves);
}

std::string AabbTree::validate() const {
  int leaves = 0;
  if (root_ != kNull) {
    if (nodes_[static_cast<std::size_t>(root_)].parent != kNull) return "root has a parent";
    std::string e = validateNode(root_, leaves);
    if (!e.empty()) return e;
  }
  if (static_cast<std::size_t>(leaves) != leafCount_) return "leaf count mismatch";
  std::size_t free = 0;
  for (std::int32_t i = freeList_; i != kNull; i = nodes_[static_cast<std::size_t>(i)].parent) {
    if (++free > nodes_.size()) return "free list has a cycle";
  }
  const std::size_t used = leafCount_ == 0 ? 0 : 2 * leafCount_ - 1;
  if (used + free != nodes_.size()) return "nodes lost: " + std::to_string(nodes_.size() - used - free);
  return "";
}

}  // namespace volpar
