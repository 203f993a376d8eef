// The Jolt Physics world of pile-N (pile_jolt.hpp; the variants are specified at the top of pile_bench.cpp).

#include "tools/bench/pile_jolt.hpp"

// Jolt.h comes first in every file that uses Jolt
#include <Jolt/Jolt.h>

#include <Jolt/ConfigurationString.h>
#include <Jolt/Core/Factory.h>
#include <Jolt/Core/IssueReporting.h>
#include <Jolt/Core/JobSystemThreadPool.h>
#include <Jolt/Core/TempAllocator.h>
#include <Jolt/Physics/Body/BodyCreationSettings.h>
#include <Jolt/Physics/Body/BodyFilter.h>
#include <Jolt/Physics/Collision/CollideShape.h>
#include <Jolt/Physics/Collision/CollisionCollectorImpl.h>
#include <Jolt/Physics/Collision/NarrowPhaseQuery.h>
#include <Jolt/Physics/Collision/Shape/BoxShape.h>
#include <Jolt/Physics/Collision/Shape/PlaneShape.h>
#include <Jolt/Physics/Collision/Shape/SphereShape.h>
#include <Jolt/Physics/Collision/Shape/StaticCompoundShape.h>
#include <Jolt/Physics/PhysicsSettings.h>
#include <Jolt/Physics/PhysicsSystem.h>
#include <Jolt/RegisterTypes.h>

#include <algorithm>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace pile {
namespace {

// ---------------------------------------------------------------------------------------------------
// Jolt's set-up, as in its HelloWorld: two object layers (statics, moving bodies) in two broad phase layers

constexpr JPH::ObjectLayer kNonMoving = 0;
constexpr JPH::ObjectLayer kMoving = 1;
constexpr JPH::BroadPhaseLayer kBroadNonMoving(0);
constexpr JPH::BroadPhaseLayer kBroadMoving(1);
constexpr JPH::uint kBroadPhaseLayers = 2;

/// Statics collide with moving bodies only; moving bodies with everything.
class ObjectLayerPairs final : public JPH::ObjectLayerPairFilter {
 public:
  [[nodiscard]] bool ShouldCollide(JPH::ObjectLayer a, JPH::ObjectLayer b) const override {
    return a == kMoving || b == kMoving;
  }
};

/// Object layer -> broad phase layer.
class BroadPhaseLayers final : public JPH::BroadPhaseLayerInterface {
 public:
  [[nodiscard]] JPH::uint GetNumBroadPhaseLayers() const override { return kBroadPhaseLayers; }
  [[nodiscard]] JPH::BroadPhaseLayer GetBroadPhaseLayer(JPH::ObjectLayer layer) const override {
    return layer == kMoving ? kBroadMoving : kBroadNonMoving;
  }
#if defined(JPH_EXTERNAL_PROFILE) || defined(JPH_PROFILE_ENABLED)
  [[nodiscard]] const char* GetBroadPhaseLayerName(JPH::BroadPhaseLayer layer) const override {
    return layer == kBroadMoving ? "moving" : "non-moving";
  }
#endif
};

/// Which object layer collides with which broad phase layer.
class ObjectVsBroadPhase final : public JPH::ObjectVsBroadPhaseLayerFilter {
 public:
  [[nodiscard]] bool ShouldCollide(JPH::ObjectLayer layer, JPH::BroadPhaseLayer broad) const override {
    return layer == kMoving || broad == kBroadMoving;
  }
};

/// Jolt's warnings (a full buffer, an allocator out of memory) on stderr.
void traceToStderr(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::fputs("jolt: ", stderr);
  std::vfprintf(stderr, format, args);
  std::fputs("\n", stderr);
  va_end(args);
}

/// Jolt's allocator, factory and types, registered once for the program (and released at its end).
struct JoltRuntime {
  JoltRuntime() {
    JPH::RegisterDefaultAllocator();
    JPH::Trace = traceToStderr;
    JPH::Factory::sInstance = new JPH::Factory();
    JPH::RegisterTypes();
  }
  ~JoltRuntime() {
    JPH::UnregisterTypes();
    delete JPH::Factory::sInstance;
    JPH::Factory::sInstance = nullptr;
  }
  JoltRuntime(const JoltRuntime&) = delete;
  JoltRuntime& operator=(const JoltRuntime&) = delete;
};

void registerJolt() { static const JoltRuntime runtime; }

JPH::Vec3 toJolt(const Vec3& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}
Vec3 fromJolt(JPH::Vec3Arg v) {
  return {static_cast<double>(v.GetX()), static_cast<double>(v.GetY()), static_cast<double>(v.GetZ())};
}
JPH::Quat toJolt(const Quat& q) {
  return JPH::Quat(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z()),
                   static_cast<float>(q.w()))
      .Normalized();
}
/// The upper 3 x 3 of a Jolt matrix.
Mat3 fromJolt(const JPH::Mat44& m) {
  Mat3 out;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      out(r, c) = static_cast<double>(m(static_cast<JPH::uint>(r), static_cast<JPH::uint>(c)));
  return out;
}

// Capacities of the PhysicsSystem, per body, with room to spare. A crate touches up to a dozen others and the
// walls; a compound pair gives several manifolds (contacts whose normals differ by more than 5 degrees are not
// merged), each a contact constraint: at most 1.7 per body for boxes and 10.4 for compounds in
// pile-1000's 2000 steps (7.4 in pile-125's; a taller pile has more interior bodies). An Update that runs out
// reports it, and the run stops with that error.
constexpr JPH::uint kBodyPairsPerBody = 16;
constexpr JPH::uint kContactConstraintsPerBody = 16;
constexpr JPH::uint kSpare = 4096;
// The temporary allocator holds a step's contact constraint buffer, which Jolt takes whole every step (its
// ContactConstraint: 864 bytes in 5.5.0), and its islands: 1 kB per constraint, plus 1 kB per body and 16 MB
// (pile-27000: about 470 MB of address space, of which a step writes what its contacts use)
constexpr std::size_t kTempBytesPerConstraint = 1024;
constexpr std::size_t kTempBytesPerBody = 1024;
constexpr std::size_t kTempBytesBase = std::size_t{16} << 20;

}  // namespace

struct JoltPile::Impl {
  // the layer set-up outlives the system that refers to it
  BroadPhaseLayers broadPhaseLayers;
  ObjectVsBroadPhase objectVsBroadPhase;
  ObjectLayerPairs objectLayerPairs;
  std::unique_ptr<JPH::TempAllocatorImpl> temp;
  std::unique_ptr<JPH::JobSystemThreadPool> jobs;
  JPH::PhysicsSystem system;
  JPH::RefConst<JPH::Shape> bodyShape;
  std::vector<JPH::BodyID> statics;  ///< ground and walls
  std::vector<JPH::BodyID> bodies;   ///< [N] the dynamic bodies, in pile order
  double wall = 0.0;                 ///< [m]
  bool compound = false;
  std::uint32_t errors = 0;          ///< EPhysicsUpdateError bits of every Update so far

  ~Impl() {
    JPH::BodyInterface& bi = system.GetBodyInterfaceNoLock();
    for (std::vector<JPH::BodyID>* ids : {&bodies, &statics}) {
      bi.RemoveBodies(ids->data(), static_cast<int>(ids->size()));
      bi.DestroyBodies(ids->data(), static_cast<int>(ids->size()));
    }
  }

  [[nodiscard]] const JPH::Body& body(std::size_t i) const {
    return *system.GetBodyLockInterfaceNoLock().TryGetBody(bodies[i]);
  }

  /// A static plane n . x = offset (normal inward, the solid half space behind it; Jolt's Plane holds
  /// n . x + c = 0, so c = -offset) of Jolt's default half extent: its bounding box reaches 1000 m along the
  /// plane and 1000 m behind it, so only bodies at the plane meet it in the broad phase.
  void addStaticPlane(const Vec3& normal, double offset) {
    const JPH::Plane plane(toJolt(normal), static_cast<float>(-offset));
    JPH::BodyCreationSettings s(new JPH::PlaneShape(plane), JPH::RVec3::sZero(), JPH::Quat::sIdentity(),
                                JPH::EMotionType::Static, kNonMoving);
    s.mFriction = static_cast<float>(kFriction);
    s.mRestitution = static_cast<float>(kRestitution);
    statics.push_back(system.GetBodyInterfaceNoLock().CreateAndAddBody(s, JPH::EActivation::DontActivate));
  }
};

JoltPile::JoltPile(const PileLayout& pile, JoltShape shape, int threads) : impl_(std::make_unique<Impl>()) {
  registerJolt();
  Impl& w = *impl_;
  w.wall = pile.wall;
  w.compound = shape == JoltShape::Compound;
  const auto n = static_cast<JPH::uint>(pile.n);
  const JPH::uint maxConstraints = kContactConstraintsPerBody * n + kSpare;
  w.temp = std::make_unique<JPH::TempAllocatorImpl>(kTempBytesBase + kTempBytesPerBody * n +
                                                    kTempBytesPerConstraint * maxConstraints);
  w.jobs = std::make_unique<JPH::JobSystemThreadPool>(JPH::cMaxPhysicsJobs, JPH::cMaxPhysicsBarriers,
                                                      std::max(0, threads - 1));
  w.system.Init(n + 16, 0, kBodyPairsPerBody * n + kSpare, maxConstraints, w.broadPhaseLayers,
                w.objectVsBroadPhase, w.objectLayerPairs);
  w.system.SetGravity(JPH::Vec3(0.0f, 0.0f, static_cast<float>(-kGravity)));

  // ground and walls at volpar's planes
  w.addStaticPlane(Vec3::UnitZ(), 0.0);
  w.addStaticPlane(Vec3::UnitX(), -pile.wall);
  w.addStaticPlane(-Vec3::UnitX(), -pile.wall);
  w.addStaticPlane(Vec3::UnitY(), -pile.wall);
  w.addStaticPlane(-Vec3::UnitY(), -pile.wall);

  // one body shape shared by all bodies
  if (shape == JoltShape::Box) {
    w.bodyShape = new JPH::BoxShape(JPH::Vec3::sReplicate(static_cast<float>(kBoxHalf)));
  } else {
    const JPH::Ref<JPH::SphereShape> sphere = new JPH::SphereShape(static_cast<float>(kRadius));
    JPH::StaticCompoundShapeSettings compound;
    for (const Vec3& o : latticeOffsets()) compound.AddShape(toJolt(o), JPH::Quat::sIdentity(), sphere);
    const JPH::ShapeSettings::ShapeResult made = compound.Create();
    if (made.HasError()) {
      std::fprintf(stderr, "pile_bench: Jolt's compound shape: %s\n", made.GetError().c_str());
      std::exit(1);
    }
    w.bodyShape = made.Get();
  }

  // the bodies, at rest, with the crate's mass and inertia; no damping (Jolt's default is 0.05 1/s, linear and
  // angular; the scene has none), no sleeping
  JPH::MassProperties massProperties;
  massProperties.mMass = static_cast<float>(kBodyMass);
  massProperties.mInertia = JPH::Mat44::sScale(toJolt(latticeInertia()));
  JPH::BodyInterface& bi = w.system.GetBodyInterfaceNoLock();
  for (std::size_t i = 0; i < pile.centre.size(); ++i) {
    JPH::BodyCreationSettings s(w.bodyShape, JPH::RVec3(toJolt(pile.centre[i])), toJolt(pile.orientation[i]),
                                JPH::EMotionType::Dynamic, kMoving);
    s.mOverrideMassProperties = JPH::EOverrideMassProperties::MassAndInertiaProvided;
    s.mMassPropertiesOverride = massProperties;
    s.mFriction = static_cast<float>(kFriction);
    s.mRestitution = static_cast<float>(kRestitution);
    s.mLinearDamping = 0.0f;
    s.mAngularDamping = 0.0f;
    s.mAllowSleeping = false;
    w.bodies.push_back(bi.CreateAndAddBody(s, JPH::EActivation::Activate));
  }
  // as Jolt recommends after adding many bodies at once (untimed, like the rest of the construction)
  w.system.OptimizeBroadPhase();
}

JoltPile::~JoltPile() = default;

bool JoltPile::step() {
  const JPH::EPhysicsUpdateError e = impl_->system.Update(static_cast<float>(kDt), 1, impl_->temp.get(),
                                                          impl_->jobs.get());
  impl_->errors |= static_cast<std::uint32_t>(e);
  return e == JPH::EPhysicsUpdateError::None;
}

std::string JoltPile::error() const {
  std::string out;
  const auto add = [&](JPH::EPhysicsUpdateError bit, const char* what) {
    if ((impl_->errors & static_cast<std::uint32_t>(bit)) != 0) out += (out.empty() ? "" : ", ") + std::string(what);
  };
  add(JPH::EPhysicsUpdateError::ManifoldCacheFull, "Jolt's manifold cache full");
  add(JPH::EPhysicsUpdateError::BodyPairCacheFull, "Jolt's body pair cache full");
  add(JPH::EPhysicsUpdateError::ContactConstraintsFull, "Jolt's contact constraint buffer full");
  return out;
}

double JoltPile::deepest() const {
  const JPH::NarrowPhaseQuery& query = impl_->system.GetNarrowPhaseQueryNoLock();
  const JPH::CollideShapeSettings settings;  // touching or overlapping shapes only (no separation distance)
  double worst = 0.0;
  for (std::size_t i = 0; i < impl_->bodies.size(); ++i) {
    const JPH::Body& b = impl_->body(i);
    // the deepest hit: a collide-shape hit's early-out fraction is minus its penetration depth
    JPH::ClosestHitCollisionCollector<JPH::CollideShapeCollector> hit;
    const JPH::IgnoreSingleBodyFilter notItself(b.GetID());
    query.CollideShape(b.GetShape(), JPH::Vec3::sOne(), b.GetCenterOfMassTransform(), settings,
                       JPH::RVec3::sZero(), hit, {}, {}, notItself);
    if (hit.HadHit()) worst = std::max(worst, static_cast<double>(hit.mHit.mPenetrationDepth));
  }
  return worst;
}

void JoltPile::measure(Quality& q) const {
  q.kinetic = 0.0;
  CentreTally tally(impl_->wall);
  for (std::size_t i = 0; i < impl_->bodies.size(); ++i) {
    const JPH::Body& b = impl_->body(i);
    const Vec3 v = fromJolt(b.GetLinearVelocity());
    const Vec3 w = fromJolt(b.GetAngularVelocity());
    const Mat3 worldInertia = fromJolt(b.GetInverseInertia()).inverse();
    q.kinetic += 0.5 * mass(i) * v.squaredNorm() + 0.5 * w.dot(worldInertia * w);
    tally.add(fromJolt(JPH::Vec3(b.GetCenterOfMassPosition())), v);
  }
  tally.into(q);
  q.finite = q.finite && std::isfinite(q.kinetic);
  q.error = error();
}

Sites JoltPile::sphereCentres(std::size_t i) const {
  const JPH::Body& b = impl_->body(i);
  const JPH::RMat44 x = b.GetCenterOfMassTransform();
  Sites out;
  if (impl_->compound) {
    const auto& children = static_cast<const JPH::StaticCompoundShape*>(b.GetShape())->GetSubShapes();
    for (std::size_t c = 0; c < out.size() && c < children.size(); ++c)
      out[c] = fromJolt(JPH::Vec3(x * children[c].GetPositionCOM()));
    // a compound of another size leaves sites at infinity, which fail the start check
    for (std::size_t c = children.size(); c < out.size(); ++c) out[c] = Vec3::Constant(1e300);
  } else {
    const Sites offsets = latticeOffsets();
    for (std::size_t c = 0; c < out.size(); ++c) out[c] = fromJolt(JPH::Vec3(x * toJolt(offsets[c])));
  }
  return out;
}

double JoltPile::mass(std::size_t i) const {
  return 1.0 / static_cast<double>(impl_->body(i).GetMotionProperties()->GetInverseMass());
}

Mat3 JoltPile::localInertia(std::size_t i) const {
  return fromJolt(impl_->body(i).GetMotionProperties()->GetLocalSpaceInverseInertia()).inverse();
}

std::string joltDescription() {
  const JPH::PhysicsSettings defaults;
  std::array<char, 512> buf{};
  std::snprintf(buf.data(), buf.size(),
                "Jolt %d.%d.%d (%s), its default PhysicsSettings: %u velocity and %u position iterations, "
                "penetration slop %.3g m, speculative contact distance %.3g m, restitution only above %.3g m/s",
                JPH_VERSION_MAJOR, JPH_VERSION_MINOR, JPH_VERSION_PATCH, JPH::GetConfigurationString(),
                defaults.mNumVelocitySteps, defaults.mNumPositionSteps,
                static_cast<double>(defaults.mPenetrationSlop),
                static_cast<double>(defaults.mSpeculativeContactDistance),
                static_cast<double>(defaults.mMinVelocityForRestitution));
  return buf.data();
}

}  // namespace pile
