#include "engine/run_loop.hpp"

#include <chrono>
#include <csignal>

namespace volpar {

namespace {
using Clock = std::chrono::steady_clock;
}

Result<RunSummary> runWorld(World& world, const TrajectoryMeta& meta, const RunOptions& options) {
  RunSummary summary;
  summary.bodies = world.bodies().size();
  summary.particles = world.particles().size();
  summary.output = options.output;
  summary.energyStart = world.energy();

  std::unique_ptr<H5mdWriter> writer;
  if (!options.output.empty()) {
    auto created = H5mdWriter::create(options.output, world, meta);
    if (!created) return created.error();
    writer = std::move(created.value());
    if (auto ok = writer->writeFrame(world); !ok) return ok.error();
  }

  const auto start = Clock::now();
  auto lastProgress = start;
  auto lastSidecar = start;
  const int every = std::max(1, options.every);
  std::int64_t lastWritten = world.stepIndex();
  Error failure;
  bool failed = false;
  for (std::int64_t i = 0; i < options.steps; ++i) {
    if (options.stop && options.stop->load()) {
      summary.interrupted = true;
      break;
    }
    const StepStatus status = world.step();
    summary.stepSeconds += world.stats().time.total;
    summary.stageTimes += world.stats().time;
    const StepStats& st = world.stats();
    summary.maxPenetration = std::max(summary.maxPenetration, st.maxPenetration);
    summary.patches += st.patches;
    for (std::size_t k = 0; k < kPlaneCaseCount; ++k) summary.patchesByCase[k] += st.patchesByCase[k];
    summary.candidates += st.candidates;
    summary.lookAheads += st.lookAheads;
    summary.unvalidatedPatches += st.unvalidatedPatches;
    summary.patchesReused += st.patchesReused;
    ++summary.steps;
    if (hasFlag(status, StepStatus::NonFinite)) {
      failure = Error{"", 0, 0,
                      "the simulation became non-finite (NaN or infinity) at step " + std::to_string(world.stepIndex()) +
                          " (t = " + std::to_string(world.time()) + " s); stopped" +
                          (writer ? "; the trajectory holds every frame before it" : "")};
      failed = true;
      break;
    }
    if (writer && !world.breakEvents().empty()) {
      if (auto ok = writer->writeBreakEvents(world); !ok) return ok.error();
    }
    summary.connectorsBroken += world.breakEvents().size();
    summary.bodiesCreated += world.stats().bodiesCreated;
    summary.normalsRecomputed += world.stats().normalsRecomputed;
    const bool last = i + 1 == options.steps;
    if (writer && (world.stepIndex() % every == 0 || last)) {
      if (auto ok = writer->writeFrame(world); !ok) return ok.error();
      lastWritten = world.stepIndex();
      if (options.killAfterFrames > 0 && static_cast<std::int64_t>(writer->frames()) >= options.killAfterFrames)
        std::raise(SIGKILL);
    }
    const auto now = Clock::now();
    if (options.progress && now - lastProgress > std::chrono::milliseconds(100)) {
      options.progress(i + 1, options.steps);
      lastProgress = now;
    }
    // keep the sidecar usable while a long run goes on
    if (writer && now - lastSidecar > std::chrono::seconds(10)) {
      static_cast<void>(writer->writeSidecar());
      lastSidecar = now;
    }
  }
  if (writer && summary.interrupted && world.stepIndex() != lastWritten) {
    if (auto ok = writer->writeFrame(world); !ok) return ok.error();
  }
  summary.wallSeconds = std::chrono::duration<double>(Clock::now() - start).count();
  summary.stepsPerSecond = summary.stepSeconds > 0.0 ? static_cast<double>(summary.steps) / summary.stepSeconds : 0.0;
  summary.energyEnd = world.energy();
  if (options.progress) options.progress(summary.steps, options.steps);
  if (writer) {
    summary.frames = writer->frames();
    if (auto ok = writer->writeSidecar(); !ok) return ok.error();
    if (auto ok = writer->close(); !ok) return ok.error();
  }
  if (failed) return failure;
  return summary;
}

}  // namespace volpar
