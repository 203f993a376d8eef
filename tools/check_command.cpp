// volpar check: runs a scene and cross-checks every step's collision results against FCL.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>

#include "volpar/collision/normal_estimation.hpp"
#include "volpar/collision/reference/fcl_adapter.hpp"
#include "volpar/engine/scene/scene_build.hpp"
#include "volpar/engine/core/percentile.hpp"
#include "volpar/engine/scene/scene_loader.hpp"
#include "tools/commands.hpp"
#include "tools/json_writer.hpp"

namespace volpar::cli {

namespace {

/// Angles [deg] between patch normals and the exact reference, by where the normals came from.
struct NormalErrors {
  std::vector<double> all;
  std::array<std::vector<double>, kPlaneCaseCount> byCase;
  void add(double angle, PlaneCase c) {
    all.push_back(angle);
    byCase[static_cast<std::size_t>(c)].push_back(angle);
  }
};
struct PlaneErrors {
  NormalErrors shape;       ///< both bodies keep their solid and its exact normals
  NormalErrors estimated;   ///< both keep their solid, at least one with estimated normals
  NormalErrors deformable;  ///< a deformable body: against normals estimated on its current geometry
  std::size_t withoutReference = 0;  ///< patches of bodies without a convex solid (meshes that are not
                                     ///< convex, fragments, explicit lists) or whose cores overlap
};

double angleDeg(const Vec3& a, const Vec3& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

/// The exact reference for the patches of a world: for two bodies that keep their convex solid (rigid or
/// static, not fragments), FCL's closest-point direction between their cores (fitted solids the particle
/// centres fill; the rounded bodies touch along it); where a deformable body takes part, the normals of its
/// surface estimated afresh on its current particles (normal_estimation.hpp): against a convex solid, the
/// direction from that solid's core to the deformable side's contact particles, otherwise the mean of the
/// two sides' surface normals at their contact particles.
class PlaneReference {
 public:
  void measure(const World& w, PlaneErrors& out) {
    const BodyStore& bodies = w.bodies();
    const PatchSet& ps = w.patches();
    for (const ContactPatch& p : ps.patches) {
      if (p.plane.valid()) continue;  // a plane's normal is its own, exactly
      const BodyInfo& ia = bodies.info[p.a.index()];
      const BodyInfo& ib = bodies.info[p.b.index()];
      const bool deformA = ia.kind == BodyKind::Deformable, deformB = ib.kind == BodyKind::Deformable;
      const bool solidA = !deformA && ia.core.isConvexSolid(), solidB = !deformB && ib.core.isConvexSolid();
      if (!deformA && !deformB) {
        if (!solidA || !solidB || p.a == p.b) {
          ++out.withoutReference;
          continue;
        }
        const reference::CoreContact ref = reference::coreContact(ia.core, bodies.shapeOrigin(p.a), bodies.shapeOrientation(p.a),
                                                                   ib.core, bodies.shapeOrigin(p.b), bodies.shapeOrientation(p.b));
        if (!ref.valid) {
          ++out.withoutReference;
          continue;
        }
        const bool estimated = ia.source.estimatedNormals || ib.source.estimatedNormals;
        (estimated ? out.estimated : out.shape).add(angleDeg(p.normal, ref.normal), p.planeCase);
        continue;
      }
      // a deformable side: its surface estimated afresh on the current geometry
      Vec3 sumA = Vec3::Zero(), sumB = Vec3::Zero(), centreA = Vec3::Zero(), centreB = Vec3::Zero();
      const Vec3 along = p.normal;
      side(w, ps, p, true, deformA, along, sumA, centreA);
      side(w, ps, p, false, deformB, -along, sumB, centreB);
      Vec3 n = (sumA.normalized() - sumB.normalized());
      if (!(sumA.normalized().dot(-sumB.normalized()) > 0.0)) {
        // the two sides' surfaces do not face each other (particles of one layer pressed together side by
        // side): the contacts' own centre lines are all the geometry says
        n = Vec3::Zero();
        for (std::uint32_t k = p.first; k < p.first + p.count; ++k) {
          const std::uint32_t ci = ps.contacts[k];
          n += (ps.flipped[ci] ? -1.0 : 1.0) * w.contacts().contacts[ci].normal;
        }
      }
      const auto towardsPoint = [&](BodyId solid, const BodyInfo& info, const Vec3& point, bool solidIsA) {
        SourceShape dot;
        dot.kind = SourceShape::Kind::Sphere;
        const reference::CoreContact c =
            solidIsA ? reference::coreContact(info.core, bodies.shapeOrigin(solid), bodies.shapeOrientation(solid), dot, point, Quat::Identity())
                     : reference::coreContact(dot, point, Quat::Identity(), info.core, bodies.shapeOrigin(solid), bodies.shapeOrientation(solid));
        if (c.valid) n = c.normal;
      };
      if (solidA && deformB) towardsPoint(p.a, ia, centreB, true);
      if (solidB && deformA) towardsPoint(p.b, ib, centreA, false);
      if (!(n.norm() > 1e-9)) {
        ++out.withoutReference;
        continue;
      }
      out.deformable.add(angleDeg(p.normal, n), p.planeCase);
    }
  }

 private:
  /// The patch's particles on one side: the sum of their surface normals facing `towards` (estimated
  /// afresh for a deformable body, cached otherwise) and their centroid.
  void side(const World& w, const PatchSet& ps, const ContactPatch& p, bool sideA, bool fresh, const Vec3& towards,
            Vec3& sum, Vec3& centre) {
    ids_.clear();
    for (std::uint32_t k = p.first; k < p.first + p.count; ++k) {
      const std::uint32_t ci = ps.contacts[k];
      const ParticleContact& c = w.contacts().contacts[ci];
      const bool onA = sideA != (ps.flipped[ci] != 0);
      ids_.push_back(onA ? c.a : c.b);
    }
    std::sort(ids_.begin(), ids_.end());
    ids_.erase(std::unique(ids_.begin(), ids_.end()), ids_.end());
    const ParticleStore& particles = w.particles();
    for (const ParticleId q : ids_) centre += particles.position[q.index()];
    centre /= static_cast<double>(ids_.size());
    if (fresh) {
      const ContactFinder& f = w.contactFinder();
      kinds_.clear();
      for (const ParticleId q : ids_) kinds_.push_back(particles.flags[q.index()]);
      estimator_.estimate({particles.position, f.adjacencyStart(), f.adjacencyList(), {}}, ids_, estimates_, kinds_,
                          kDeformingSurfaceReach);
      for (const SurfaceEstimate& e : estimates_)
        sum += facingNormal(e.flags, e.normal, std::span<const Vec3>(e.faces.data(), e.faceCount), towards);
      return;
    }
    for (const ParticleId q : ids_) {
      const std::int32_t k = particles.normalIndex[q.index()];
      if (k < 0) continue;
      const Quat& r = w.bodies().state[particles.body[q.index()].index()].orientation;
      sum += r * facingNormal(particles.flags[q.index()], w.normals()[k], w.normals().faces(k), r.conjugate() * towards);
    }
  }

  SurfaceEstimator estimator_;
  std::vector<ParticleId> ids_;
  std::vector<SurfaceEstimate> estimates_;
  std::vector<std::uint8_t> kinds_;
};

void printErrors(const char* title, const NormalErrors& e) {
  if (e.all.empty()) {
    std::printf("  %-28s none compared\n", title);
    return;
  }
  std::printf("  %-28s n %8zu  median %6.2f  p95 %6.2f  p99 %6.2f  max %6.2f deg\n", title, e.all.size(), percentile(e.all, 0.5),
              percentile(e.all, 0.95), percentile(e.all, 0.99), e.all.empty() ? 0.0 : *std::max_element(e.all.begin(), e.all.end()));
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k)
    if (!e.byCase[k].empty())
      std::printf("    %-26s n %8zu  median %6.2f  p95 %6.2f deg\n", planeCaseName(static_cast<PlaneCase>(k)), e.byCase[k].size(),
                  percentile(e.byCase[k], 0.5), percentile(e.byCase[k], 0.95));
}

void jsonErrors(JsonWriter& j, const char* key, const NormalErrors& e) {
  j.begin(key)
      .field("n", e.all.size())
      .field("median", percentile(e.all, 0.5))
      .field("p95", percentile(e.all, 0.95))
      .field("p99", percentile(e.all, 0.99))
      .field("max", e.all.empty() ? 0.0 : *std::max_element(e.all.begin(), e.all.end()));
  j.begin("by_case");
  for (std::size_t k = 0; k < kPlaneCaseCount; ++k) {
    if (e.byCase[k].empty()) continue;
    j.begin(planeCaseName(static_cast<PlaneCase>(k)))
        .field("n", e.byCase[k].size())
        .field("median", percentile(e.byCase[k], 0.5))
        .field("p95", percentile(e.byCase[k], 0.95))
        .field("max", *std::max_element(e.byCase[k].begin(), e.byCase[k].end()))
        .end();
  }
  j.end().end();
}

}  // namespace

int check(const CheckArgs& args) {
  auto desc = loadScene(args.scene, args.limits.load());
  if (!desc) return fail(desc.error());
  auto built = buildScene(*desc, args.limits.build());
  if (!built) return fail(built.error());
  World& world = built->world;
  const auto stepCount = stepsFor(desc->stepCount(), desc->dt, args.steps, args.duration);
  if (!stepCount) return fail(stepCount.error());
  const std::int64_t steps = stepCount.value();

  reference::FclWorldReference fcl;
  const ContactFinder& finder = world.contactFinder();
  const reference::SelfContactFilter self = [&](ParticleId a, ParticleId b) { return !finder.connected(a, b); };
  reference::Comparison total;
  std::int64_t checkedStates = 0;
  std::size_t patches = 0, unvalidated = 0, contactLines = 0, lookAheads = 0;
  PlaneErrors errors;
  PlaneReference planes;
  for (std::int64_t i = 0; i <= steps; ++i) {
    // the contacts of the current state against FCL's, from scratch
    const reference::FclReport report =
        fcl.collide(world.particles(), world.bodies(), world.bodyBoxes(), world.planes(), self);
    reference::Comparison c = reference::compareContacts(report, world.bodyPairs(), world.planePairs(),
                                                         world.contacts(), world.particles(), static_cast<std::size_t>(args.details));
    for (auto& d : c.details) d = "step " + std::to_string(world.stepIndex()) + ": " + d;
    total += c;
    ++checkedStates;
    patches += world.patches().stats.patches;
    unvalidated += world.patches().stats.unvalidated;
    contactLines += world.patches().stats.contactLines;
    lookAheads += world.patches().stats.lookAheadsDecided;
    planes.measure(world, errors);
    if (i == steps) break;
    if (hasFlag(world.step(), StepStatus::NonFinite))
      return fail(Error{args.scene, 0, 0, "the simulation became non-finite at step " + std::to_string(world.stepIndex())});
  }
  const bool ok = total.mismatches() == 0;
  const double unvalidatedShare = patches ? static_cast<double>(unvalidated) / static_cast<double>(patches) : 0.0;
  if (args.json) {
    JsonWriter j;
    j.begin()
        .field("scene", desc->name)
        .field("steps", steps)
        .field("states_checked", checkedStates)
        .field("body_pair_mismatches", total.bodyPairMismatches)
        .field("particle_pair_mismatches", total.particlePairMismatches)
        .field("plane_contact_mismatches", total.planeContactMismatches)
        .field("contacts_checked", total.contactsChecked)
        .field("grazing_pairs", total.grazing)
        .field("patches", patches)
        .field("unvalidated_patches", unvalidated)
        .field("unvalidated_share", unvalidatedShare)
        .field("contact_line_patches", contactLines)
        .field("look_ahead_patches", lookAheads)
        .field("patches_without_reference", errors.withoutReference);
    j.begin("normal_error_deg");
    jsonErrors(j, "shape", errors.shape);
    jsonErrors(j, "estimated", errors.estimated);
    jsonErrors(j, "deformable", errors.deformable);
    j.end();
    j.field("contacts_agree", ok).field("details", total.details).end();
    std::cout << j.str() << std::endl;
  } else {
    std::printf("scene                     %s (%s)\n", desc->name.c_str(), args.scene.c_str());
    std::printf("states checked            %lld (steps 0..%lld)\n", static_cast<long long>(checkedStates),
                static_cast<long long>(steps));
    std::printf("contacts checked          %zu (plus %zu grazing pairs left out)\n", total.contactsChecked, total.grazing);
    std::printf("body pair mismatches      %zu\n", total.bodyPairMismatches);
    std::printf("particle pair mismatches  %zu\n", total.particlePairMismatches);
    std::printf("plane contact mismatches  %zu\n", total.planeContactMismatches);
    std::printf("patches                   %zu (%zu unvalidated, %.3f %%; %zu resolved along contact lines; %zu decided by a look-ahead)\n",
                patches, unvalidated, 100.0 * unvalidatedShare, contactLines, lookAheads);
    std::printf("plane normals against the exact reference (%zu patches have none: a body without a convex solid, or overlapping cores):\n",
                errors.withoutReference);
    printErrors("shape normals", errors.shape);
    printErrors("estimated normals", errors.estimated);
    printErrors("deformable (current shape)", errors.deformable);
    for (const auto& d : total.details) std::printf("  %s\n", d.c_str());
    // the verdict is about which particles touch (what FCL decides); the plane normals above are measured, not judged
    std::printf("%s\n", ok ? "contacts: every touching pair and plane contact agrees with FCL (plane normals: see above)"
                           : "contacts DISAGREE with FCL");
  }
  return ok ? 0 : 1;
}

}  // namespace volpar::cli
