// volpar check: runs a scene and cross-checks every step's collision results against FCL.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>

#include "collision/reference/fcl_adapter.hpp"
#include "engine/scene/scene_build.hpp"
#include "engine/scene/scene_loader.hpp"
#include "tools/commands.hpp"
#include "tools/json_writer.hpp"

namespace volpar::cli {

namespace {

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * static_cast<double>(v.size() - 1);
  const auto i = static_cast<std::size_t>(pos);
  const double f = pos - static_cast<double>(i);
  return i + 1 < v.size() ? v[i] * (1 - f) + v[i + 1] * f : v[i];
}

/// Angles [deg] between each patch normal of a body pair filled from primitives and FCL's contact normal
/// between the primitives themselves.
void planeErrors(const World& w, std::vector<double>& angles, std::array<std::vector<double>, kPlaneCaseCount>& byCase) {
  const BodyStore& bodies = w.bodies();
  BodyId lastA, lastB;
  reference::PrimitiveContact ref;
  for (const ContactPatch& p : w.patches().patches) {
    if (p.plane.valid() || p.a == p.b) continue;
    const BodyInfo& ia = bodies.info[p.a.index()];
    const BodyInfo& ib = bodies.info[p.b.index()];
    if (!ia.source.isPrimitive() || !ib.source.isPrimitive()) continue;
    if (p.a != lastA || p.b != lastB) {
      ref = reference::primitiveContact(ia.source, bodies.shapeOrigin(p.a), bodies.shapeOrientation(p.a), ib.source,
                                        bodies.shapeOrigin(p.b), bodies.shapeOrientation(p.b));
      lastA = p.a;
      lastB = p.b;
    }
    if (!ref.hit || !ref.normalValid) continue;
    const double angle = std::acos(std::clamp(p.normal.dot(ref.normal), -1.0, 1.0)) * 180.0 / std::numbers::pi;
    angles.push_back(angle);
    byCase[static_cast<std::size_t>(p.planeCase)].push_back(angle);
  }
}

}  // namespace

int check(const CheckArgs& args) {
  auto desc = loadScene(args.scene);
  if (!desc) return fail(desc.error());
  auto built = buildScene(*desc);
  if (!built) return fail(built.error());
  World& world = built->world;
  const std::int64_t steps = stepsFor(desc->stepCount(), desc->dt, args.steps, args.duration);

  reference::FclWorldReference fcl;
  const ContactFinder& finder = world.contactFinder();
  const reference::SelfContactFilter self = [&](ParticleId a, ParticleId b) { return !finder.connected(a, b); };
  reference::Comparison total;
  std::int64_t checkedStates = 0;
  std::size_t patches = 0, unvalidated = 0;
  std::vector<double> angles;
  std::array<std::vector<double>, kPlaneCaseCount> byCase;
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
    planeErrors(world, angles, byCase);
    if (i == steps) break;
    if (hasFlag(world.step(), StepStatus::NonFinite))
      return fail(Error{args.scene, 0, 0, "the simulation became non-finite at step " + std::to_string(world.stepIndex())});
  }
  const bool ok = total.mismatches() == 0;
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
        .field("normals_compared", angles.size());
    j.begin("normal_error_deg")
        .field("median", percentile(angles, 0.5))
        .field("p95", percentile(angles, 0.95))
        .field("p99", percentile(angles, 0.99))
        .field("max", angles.empty() ? 0.0 : *std::max_element(angles.begin(), angles.end()))
        .end();
    j.begin("normal_error_deg_by_case");
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) {
      if (byCase[k].empty()) continue;
      j.begin(planeCaseName(static_cast<PlaneCase>(k)))
          .field("n", byCase[k].size())
          .field("median", percentile(byCase[k], 0.5))
          .field("p95", percentile(byCase[k], 0.95))
          .field("max", *std::max_element(byCase[k].begin(), byCase[k].end()))
          .end();
    }
    j.end();
    j.field("ok", ok).field("details", total.details).end();
    std::cout << j.str() << std::endl;
  } else {
    std::printf("scene                     %s (%s)\n", desc->name.c_str(), args.scene.c_str());
    std::printf("states checked            %lld (steps 0..%lld)\n", static_cast<long long>(checkedStates),
                static_cast<long long>(steps));
    std::printf("contacts checked          %zu (plus %zu grazing pairs left out)\n", total.contactsChecked, total.grazing);
    std::printf("body pair mismatches      %zu\n", total.bodyPairMismatches);
    std::printf("particle pair mismatches  %zu\n", total.particlePairMismatches);
    std::printf("plane contact mismatches  %zu\n", total.planeContactMismatches);
    std::printf("patches                   %zu (%zu unvalidated)\n", patches, unvalidated);
    std::printf("plane normals vs FCL      %zu compared (bodies filled from primitives): median %.2f, p95 %.2f, "
                "p99 %.2f, max %.2f deg\n",
                angles.size(), percentile(angles, 0.5), percentile(angles, 0.95), percentile(angles, 0.99),
                angles.empty() ? 0.0 : *std::max_element(angles.begin(), angles.end()));
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k)
      if (!byCase[k].empty())
        std::printf("  %-26s n %6zu  median %6.2f  p95 %6.2f deg\n", planeCaseName(static_cast<PlaneCase>(k)),
                    byCase[k].size(), percentile(byCase[k], 0.5), percentile(byCase[k], 0.95));
    for (const auto& d : total.details) std::printf("  %s\n", d.c_str());
    std::printf("%s\n", ok ? "agrees with FCL" : "DISAGREES with FCL");
  }
  return ok ? 0 : 1;
}

}  // namespace volpar::cli
