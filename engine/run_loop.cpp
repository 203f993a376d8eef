#include "volpar/engine/run_loop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <csignal>
#include <filesystem>
#include <thread>

#include "volpar/engine/io/xdmf_writer.hpp"

namespace volpar {

namespace {
using Clock = std::chrono::steady_clock;
}

Result<std::int64_t> stepsFor(std::int64_t scene, double dt, std::int64_t steps, double duration) {
  if (steps > 0) return steps;
  if (duration > 0.0) {
    const double n = std::round(duration / dt);
    if (!(n <= static_cast<double>(kMaxSteps))) {
      char buf[160];
      std::snprintf(buf, sizeof buf, "--duration %g s is %.3g steps of dt = %g s; expected at most %lld steps", duration,
                    n, dt, kMaxSteps);
      return Error{"", 0, 0, buf};
    }
    return std::max<std::int64_t>(1, static_cast<std::int64_t>(n));
  }
  return scene;
}

std::optional<Error> refuseOverwrite(const std::string& output, const std::string& input,
                                     const std::vector<std::string>& inputs, const std::string& inputName) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path out(output);
  if (!fs::exists(out, ec)) return std::nullopt;
  if (fs::is_directory(out, ec)) return Error{output, 0, 0, "the output is a folder; expected a file name for the trajectory"};
  const auto same = [&](const std::string& in) {
    std::error_code e;
    return fs::equivalent(out, fs::path(in), e) && !e;
  };
  if (!input.empty() && same(input)) return Error{output, 0, 0, "the output is " + inputName + " itself; refusing to write over an input"};
  for (const std::string& in : inputs)
    if (same(in)) return Error{output, 0, 0, "the output is " + in + ", which the scene reads; refusing to write over an input"};
  return std::nullopt;
}

int defaultThreads() {
  const unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : static_cast<int>(std::min(n, 256u));
}

std::string partialPath(const std::string& output) {
  const std::filesystem::path p(output);
  return (p.parent_path() / (p.stem().string() + ".partial" + p.extension().string())).string();
}

Result<RunSummary> runWorld(World& world, const TrajectoryMeta& meta, const RunOptions& options) {
  RunSummary summary;
  summary.bodies = world.bodies().size();
  summary.particles = world.particles().size();
  summary.connectors = world.connectors().size();
  summary.energyStart = world.energy();

  // The trajectory grows under its partial name and takes its own name only when the run ends well: an
  // earlier file of that name survives a failed run, and a partial file says what it is.
  const std::string partial = options.output.empty() ? std::string() : partialPath(options.output);
  summary.output = partial;
  std::unique_ptr<H5mdWriter> writer;
  const bool together = options.fileProcesses && options.fileProcesses->size() > 1;
  const bool lead = !together || options.fileProcesses->rank() == 0;  // renames the file
  // a failure after the file exists: the complete frames stay in the partial file (with its sidecar). A failure
  // to write may be this process's alone: processes writing together then leave the file unclosed (closing is
  // collective; H5mdWriter::closeAfterFailure), and the failure ends them all; one all of them meet at once
  // (`everyProcess`, or a lack of room, which they agree on) closes it.
  const auto keepPartial = [&](const Error& e, bool everyProcess = false) {
    Error out = e;
    if (writer) {
      static_cast<void>(writer->writeSidecar(partial));
      if (everyProcess) static_cast<void>(writer->close());
      else writer->closeAfterFailure();
      out.message += "; " + std::to_string(writer->committedFrames()) + " complete frames are kept in " + partial;
    }
    return out;
  };
  if (!options.output.empty()) {
    TrajectoryMeta withCheckpoints = meta;
    withCheckpoints.checkpoints = withCheckpoints.checkpoints || options.checkpointEvery > 0;
    auto created = H5mdWriter::create(partial, world, withCheckpoints, options.fileProcesses);
    const auto removePartial = [&] {
      if (writer) writer->closeAfterFailure();
      writer.reset();
      std::error_code ignored;
      if (lead) std::filesystem::remove(partial, ignored);
    };
    if (!created) {
      removePartial();
      return created.error();
    }
    writer = std::move(created.value());
    writer->setCommitInterval(options.commitSeconds);
    if (auto ok = writer->writeFrame(world); !ok) {
      removePartial();
      return ok.error();
    }
  }

  const auto start = Clock::now();
  auto lastProgress = start;
  auto lastSidecar = start;
  if (options.progress) options.progress(0, options.steps);
  const int every = std::max(1, options.every);
  std::int64_t lastWritten = world.stepIndex();
  const std::int64_t endStep = world.stepIndex() + options.steps;
  Error failure;
  bool failed = false;
  for (std::int64_t i = 0; i < options.steps; ++i) {
    bool stop = options.stop && options.stop->load();
    if (options.stopTogether) stop = options.stopTogether(stop);
    if (stop) {
      summary.interrupted = true;
      break;
    }
    const StepStatus status = world.step();
    summary.stepSeconds += world.stats().time.total;
    summary.stageTimes += world.stats().time;
    summary.exchangeTimes += world.stats().exchangeTime;
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
                          " (t = " + std::to_string(world.time()) + " s); stopped"};
      failed = true;
      break;
    }
    if (writer && !world.breakEvents().empty()) {
      if (auto ok = writer->writeBreakEvents(world); !ok) return keepPartial(ok.error());
    }
    summary.connectorsBroken += world.breakEvents().size();
    for (const BreakEvent& e : world.breakEvents()) ++summary.breaksByMode[static_cast<std::size_t>(e.mode)];
    summary.bodiesCreated += world.stats().bodiesCreated;
    summary.normalsRecomputed += world.stats().normalsRecomputed;
    const bool last = i + 1 == options.steps;
    if (writer && (world.stepIndex() % every == 0 || last)) {
      if (auto ok = writer->writeFrame(world); !ok) return keepPartial(ok.error());
      lastWritten = world.stepIndex();
      if (options.killAfterFrames > 0 && static_cast<std::int64_t>(writer->frames()) >= options.killAfterFrames)
        std::raise(SIGKILL);
    }
    if (writer && options.checkpointEvery > 0 && (world.stepIndex() % options.checkpointEvery == 0 || last)) {
      if (auto ok = writer->writeCheckpoint(world, endStep); !ok) return keepPartial(ok.error());
    }
    const auto now = Clock::now();
    if (options.progress && now - lastProgress > std::chrono::milliseconds(100)) {
      options.progress(i + 1, options.steps);
      lastProgress = now;
    }
    // keep the sidecar usable while a long run goes on
    if (writer && now - lastSidecar > std::chrono::seconds(10)) {
      static_cast<void>(writer->writeSidecar(partial));
      lastSidecar = now;
    }
  }
  if (writer && summary.interrupted && world.stepIndex() != lastWritten) {
    if (auto ok = writer->writeFrame(world); !ok) return keepPartial(ok.error());
  }
  if (writer && summary.interrupted && options.checkpointEvery > 0) {
    if (auto ok = writer->writeCheckpoint(world, endStep); !ok) return keepPartial(ok.error());
  }
  summary.wallSeconds = std::chrono::duration<double>(Clock::now() - start).count();
  summary.stepsPerSecond = summary.stepSeconds > 0.0 ? static_cast<double>(summary.steps) / summary.stepSeconds : 0.0;
  summary.energyEnd = world.energy();
  summary.breakageEnergy = world.breakageEnergy();
  summary.fragments = world.fragments();
  if (options.progress) options.progress(summary.steps, options.steps);
  if (writer) {
    summary.frames = writer->frames();
    if (failed) return keepPartial(failure, true);
    if (auto ok = writer->close(); !ok) return keepPartial(ok.error());
    summary.outputBytes = writer->bytesWritten();
    if (!summary.interrupted) {
      std::error_code ec;
      if (lead) std::filesystem::rename(partial, options.output, ec);
      if (ec)
        return keepPartial(Error{options.output, 0, 0, "cannot rename the finished trajectory to its name: " + ec.message()});
      if (lead) std::filesystem::remove(sidecarPath(partial), ec);
      summary.output = options.output;
    }
    if (auto ok = writer->writeSidecar(summary.output); !ok) return ok.error();
  }
  if (failed) return failure;
  return summary;
}

}  // namespace volpar
