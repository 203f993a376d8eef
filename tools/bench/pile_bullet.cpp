// The Bullet world of pile-N (pile_bullet.hpp; the variants are specified at the top of pile_bench.cpp).

#include "tools/bench/pile_bullet.hpp"

#include <btBulletDynamicsCommon.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

namespace pile {
namespace {

btVector3 toBt(const Vec3& v) {
  return {static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z())};
}
Vec3 fromBt(const btVector3& v) {
  return {static_cast<double>(v.x()), static_cast<double>(v.y()), static_cast<double>(v.z())};
}
btQuaternion toBt(const Quat& q) {
  return {static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()), static_cast<btScalar>(q.z()),
          static_cast<btScalar>(q.w())};
}

}  // namespace

/// The world itself (BulletPile forwards to it).
struct BulletPile::Impl {
 public:
  Impl(const PileLayout& pile, BulletSetup setup) : wall_(pile.wall) {
    config_ = std::make_unique<btDefaultCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    solver_ = std::make_unique<btSequentialImpulseConstraintSolver>();
    world_ = std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(), solver_.get(),
                                                       config_.get());
    world_->setGravity(btVector3(0, 0, static_cast<btScalar>(-kGravity)));
    world_->getSolverInfo().m_numIterations = kIterations;

    // ground and walls: planes n . x = -wall with inward normals, or boxes 1 m thick behind those planes
    if (setup == BulletSetup::CompoundBoxes) {
      const double thick = 0.5;                                          // half thickness [m]
      const double reach = pile.wall + 2.0 * thick;                      // half length, past the corners [m]
      const double top = kLowestCentre + pile.k * kGridSpacing + 1.0;   // walls reach above the pile [m]
      const double zMid = (top - 2.0 * thick) / 2.0, zHalf = (top + 2.0 * thick) / 2.0;
      addStaticBox(Vec3(reach, reach, thick), Vec3(0, 0, -thick));
      addStaticBox(Vec3(thick, reach, zHalf), Vec3(pile.wall + thick, 0, zMid));
      addStaticBox(Vec3(thick, reach, zHalf), Vec3(-pile.wall - thick, 0, zMid));
      addStaticBox(Vec3(reach, thick, zHalf), Vec3(0, pile.wall + thick, zMid));
      addStaticBox(Vec3(reach, thick, zHalf), Vec3(0, -pile.wall - thick, zMid));
    } else {
      addStaticPlane(Vec3::UnitZ(), 0.0);
      addStaticPlane(Vec3::UnitX(), -pile.wall);
      addStaticPlane(-Vec3::UnitX(), -pile.wall);
      addStaticPlane(Vec3::UnitY(), -pile.wall);
      addStaticPlane(-Vec3::UnitY(), -pile.wall);
    }

    // one body shape shared by all bodies
    btCollisionShape* bodyShape = nullptr;
    if (setup == BulletSetup::Box) {
      bodyShape = own(std::make_unique<btBoxShape>(toBt(Vec3(kBoxHalf, kBoxHalf, kBoxHalf))));
    } else {
      auto* sphere = own(std::make_unique<btSphereShape>(static_cast<btScalar>(kRadius)));
      auto compound = std::make_unique<btCompoundShape>();
      for (const Vec3& o : latticeOffsets()) {
        btTransform child;
        child.setIdentity();
        child.setOrigin(toBt(o));
        compound->addChildShape(child, sphere);
      }
      bodyShape = own(std::move(compound));
    }

    // the bodies, at rest, with the 27-sphere inertia
    const btVector3 inertia = toBt(latticeInertia());
    for (int i = 0; i < pile.n; ++i) {
      const auto u = static_cast<std::size_t>(i);
      btRigidBody::btRigidBodyConstructionInfo info(static_cast<btScalar>(kBodyMass), nullptr, bodyShape, inertia);
      info.m_startWorldTransform = btTransform(toBt(pile.orientation[u]), toBt(pile.centre[u]));
      bodies_.push_back(addBody(info));
    }
  }

  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  ~Impl() {
    for (auto it = objects_.rbegin(); it != objects_.rend(); ++it) world_->removeRigidBody(it->get());
  }

  /// Exactly one step of dt (maxSubSteps 0: no fixed-step accumulator, no interpolation).
  void step() { world_->stepSimulation(static_cast<btScalar>(kDt), 0); }

  /// Runs collision detection on the current poses (as the next step would) and returns the deepest
  /// overlap over all manifold points [m].
  double deepest() {
    world_->performDiscreteCollisionDetection();
    double worst = 0.0;
    const int manifolds = dispatcher_->getNumManifolds();
    for (int m = 0; m < manifolds; ++m) {
      const btPersistentManifold* manifold = dispatcher_->getManifoldByIndexInternal(m);
      for (int p = 0; p < manifold->getNumContacts(); ++p)
        worst = std::max(worst, -static_cast<double>(manifold->getContactPoint(p).getDistance()));
    }
    return worst;
  }

  /// Kinetic energy, escaped bodies, the highest centre and the fastest body of the current state.
  void measure(Quality& q) const {
    q.kinetic = 0.0;
    CentreTally tally(wall_);
    for (const btRigidBody* body : bodies_) {
      const Vec3 v = fromBt(body->getLinearVelocity());
      const btMatrix3x3& basis = body->getWorldTransform().getBasis();
      const Vec3 wLocal = fromBt(basis.transpose() * body->getAngularVelocity());  // body frame
      const Vec3 inertia = fromBt(body->getLocalInertia());
      q.kinetic += 0.5 * kBodyMass * v.squaredNorm() + 0.5 * wLocal.dot(inertia.cwiseProduct(wLocal));
      tally.add(fromBt(body->getWorldTransform().getOrigin()), v);
    }
    tally.into(q);
    q.finite = q.finite && std::isfinite(q.kinetic);
  }

  /// World centres of body i's 27 spheres (the compound setups' children; the lattice sites for boxes) [m].
  [[nodiscard]] Sites sphereCentres(std::size_t i) const {
    const btTransform& x = bodies_[i]->getWorldTransform();
    Sites out;
    const auto offsets = latticeOffsets();
    for (std::size_t c = 0; c < out.size(); ++c) out[c] = fromBt(x * toBt(offsets[c]));
    return out;
  }
  [[nodiscard]] Mat3 localInertia(std::size_t i) const { return fromBt(bodies_[i]->getLocalInertia()).asDiagonal(); }
  [[nodiscard]] double mass(std::size_t i) const { return 1.0 / static_cast<double>(bodies_[i]->getInvMass()); }

 private:
  template <class Shape>
  Shape* own(std::unique_ptr<Shape> shape) {
    Shape* raw = shape.get();
    shapes_.push_back(std::move(shape));
    return raw;
  }

  btRigidBody* addBody(const btRigidBody::btRigidBodyConstructionInfo& info) {
    auto body = std::make_unique<btRigidBody>(info);
    body->setFriction(static_cast<btScalar>(std::sqrt(kFriction)));
    body->setRestitution(static_cast<btScalar>(std::sqrt(kRestitution)));
    body->setActivationState(DISABLE_DEACTIVATION);
    world_->addRigidBody(body.get());
    objects_.push_back(std::move(body));
    return objects_.back().get();
  }

  void addStaticPlane(const Vec3& normal, double offset) {
    auto* shape = own(std::make_unique<btStaticPlaneShape>(toBt(normal), static_cast<btScalar>(offset)));
    addBody(btRigidBody::btRigidBodyConstructionInfo(0, nullptr, shape));
  }

  void addStaticBox(const Vec3& halfExtents, const Vec3& centre) {
    auto* shape = own(std::make_unique<btBoxShape>(toBt(halfExtents)));
    btRigidBody::btRigidBodyConstructionInfo info(0, nullptr, shape);
    info.m_startWorldTransform = btTransform(btQuaternion::getIdentity(), toBt(centre));
    addBody(info);
  }

  double wall_ = 0.0;
  // destroyed in reverse order: bodies (removed from the world first), shapes, then the world and its parts
  std::unique_ptr<btDefaultCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btDbvtBroadphase> broadphase_;
  std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
  std::unique_ptr<btDiscreteDynamicsWorld> world_;
  std::vector<std::unique_ptr<btCollisionShape>> shapes_;
  std::vector<std::unique_ptr<btRigidBody>> objects_;  // static ground and walls, then the bodies
  std::vector<btRigidBody*> bodies_;                   // [N] the dynamic bodies, in pile order
};

BulletPile::BulletPile(const PileLayout& pile, BulletSetup setup) : impl_(std::make_unique<Impl>(pile, setup)) {}
BulletPile::~BulletPile() = default;
void BulletPile::step() { impl_->step(); }
double BulletPile::deepest() { return impl_->deepest(); }
void BulletPile::measure(Quality& q) const { impl_->measure(q); }
Sites BulletPile::sphereCentres(std::size_t i) const { return impl_->sphereCentres(i); }
double BulletPile::mass(std::size_t i) const { return impl_->mass(i); }
Mat3 BulletPile::localInertia(std::size_t i) const { return impl_->localInertia(i); }

std::string bulletDescription() {
  std::array<char, 160> buf{};
  std::snprintf(buf.data(), buf.size(), "Bullet %d.%02d (btScalar: %zu-byte floats), btBoxShape margin %.3f m",
                btGetVersion() / 100, btGetVersion() % 100, sizeof(btScalar),
                static_cast<double>(CONVEX_DISTANCE_MARGIN));
  return buf.data();
}

}  // namespace pile
