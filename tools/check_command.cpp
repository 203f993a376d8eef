// volpar check: runs a scene and cross-checks every step's collision results against FCL.

#include <cstdio>
#include <iostream>

#include "collision/reference/fcl_adapter.hpp"
#include "engine/scene/scene_build.hpp"
#include "engine/scene/scene_loader.hpp"
#include "tools/commands.hpp"
#include "tools/json_writer.hpp"

namespace volpar::cli {

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
  for (std::int64_t i = 0; i <= steps; ++i) {
    // the contacts of the current state against FCL's, from scratch
    const reference::FclReport report =
        fcl.collide(world.particles(), world.bodies(), world.bodyBoxes(), world.planes(), self);
    reference::Comparison c = reference::compareContacts(report, world.bodyPairs(), world.planePairs(),
                                                         world.contacts(), world.particles(), static_cast<std::size_t>(args.details));
    for (auto& d : c.details) d = "step " + std::to_string(world.stepIndex()) + ": " + d;
    total += c;
    ++checkedStates;
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
        .field("ok", ok)
        .field("details", total.details)
        .end();
    std::cout << j.str() << std::endl;
  } else {
    std::printf("scene                     %s (%s)\n", desc->name.c_str(), args.scene.c_str());
    std::printf("states checked            %lld (steps 0..%lld)\n", static_cast<long long>(checkedStates),
                static_cast<long long>(steps));
    std::printf("contacts checked          %zu (plus %zu grazing pairs left out)\n", total.contactsChecked, total.grazing);
    std::printf("body pair mismatches      %zu\n", total.bodyPairMismatches);
    std::printf("particle pair mismatches  %zu\n", total.particlePairMismatches);
    std::printf("plane contact mismatches  %zu\n", total.planeContactMismatches);
    for (const auto& d : total.details) std::printf("  %s\n", d.c_str());
    std::printf("%s\n", ok ? "agrees with FCL" : "DISAGREES with FCL");
  }
  return ok ? 0 : 1;
}

}  // namespace volpar::cli
