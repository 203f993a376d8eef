#pragma once
// Counters and timings of one World::step(). They feed the run summary and /observables.

#include <cstdint>

namespace volpar {

/// Wall-clock seconds spent in each stage of the step.
struct StageTimes {
  double integrateVelocities = 0.0;
  double integratePositions = 0.0;
  double total = 0.0;

  StageTimes& operator+=(const StageTimes& o) {
    integrateVelocities += o.integrateVelocities;
    integratePositions += o.integratePositions;
    total += o.total;
    return *this;
  }
};

struct StepStats {
  std::int64_t step = 0;       ///< index of the step just taken (1 after the first step)
  StageTimes time;             ///< [s]
};

}  // namespace volpar
