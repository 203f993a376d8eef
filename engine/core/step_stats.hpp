#pragma once
// Counters and timings of one World::step(). They feed the run summary and /observables.

#include <array>
#include <cstddef>
#include <cstdint>

namespace volpar {

/// Wall-clock seconds spent in each stage of the step.
struct StageTimes {
  double integrateVelocities = 0.0;
  double integratePositions = 0.0;
  double broadphase = 0.0;
  double particleContacts = 0.0;
  double narrowPhase = 0.0;
  double solver = 0.0;
  double breakage = 0.0;
  double total = 0.0;

  StageTimes& operator+=(const StageTimes& o) {
    integrateVelocities += o.integrateVelocities;
    integratePositions += o.integratePositions;
    broadphase += o.broadphase;
    particleContacts += o.particleContacts;
    narrowPhase += o.narrowPhase;
    solver += o.solver;
    breakage += o.breakage;
    total += o.total;
    return *this;
  }
};

struct StepStats {
  std::int64_t step = 0;            ///< index of the step just taken (1 after the first step)
  StageTimes time;                  ///< [s]
  /// Of `time`, what each stage spent in exchanges among processes, the waits for the others included
  /// (docs/distributed.md) [s]; zeros without processes.
  StageTimes exchangeTime;
  std::size_t bodyPairs = 0;        ///< candidate body pairs from the broadphase
  std::size_t planePairs = 0;       ///< candidate body-plane pairs
  std::size_t proxyMoves = 0;       ///< broadphase proxies reinserted (left their fat boxes)
  std::size_t contacts = 0;         ///< touching particle pairs (particle-particle and particle-plane), not
                                    ///< counting speculative ones
  std::size_t contactGroups = 0;    ///< body pairs, body-plane pairs and self-contacting bodies in contact
  double maxPenetration = 0.0;      ///< deepest particle overlap [m]
  std::size_t patches = 0;          ///< contact patches (one separating plane each)
  std::array<std::size_t, 10> patchesByCase{};  ///< by PlaneCase
  std::size_t candidates = 0;       ///< candidate normals tried
  std::size_t lookAheads = 0;       ///< look-aheads for single-contact patches
  std::size_t unvalidatedPatches = 0;  ///< patches whose plane no candidate could validate
  std::size_t contactLinePatches = 0;  ///< of them, resolved contact by contact along centre lines
  std::size_t lookAheadsDecided = 0;   ///< patches whose plane a look-ahead decided
  std::size_t patchesReused = 0;    ///< patches taken over from an earlier step (temporal coherence)
  std::size_t normalsRecomputed = 0;   ///< cached surface normals recomputed this step
  std::size_t contactPoints = 0;       ///< solver contact points (patches reduced to at most 4 points)
  /// Of them, those this process made in full and its share of the solve read: with processes, the points of
  /// its own nodes of the solver's tree (the others' are left unmade), unless every process prepares every
  /// node (docs/distributed.md); without, all of them. Not saved: it depends on the number of processes.
  std::size_t contactPointsRead = 0;
  std::size_t warmStarted = 0;         ///< of them, warm started from the previous step
  std::size_t heavyIslands = 0;        ///< islands whose normal impulses were solved exactly (mass ratios)
  /// sweeps over a node of the solver's tree that a thread took over from a slower one (no effect on the
  /// result: a sign of threads running at uneven speeds). Not saved: it depends on the threads' timing.
  std::size_t solverNodesTakenOver = 0;
  /// Solver contact points per level of the solver's tree, the root first (levels past its depth: 0).
  /// With processes, a node's points are solved by one process: the upper levels are the solve's
  /// critical path (docs/distributed.md).
  std::array<std::size_t, 9> solverRowsByLevel{};
  std::size_t connectorsBroken = 0;    ///< rods and springs that broke this step
  std::size_t bodiesCreated = 0;       ///< fragments made by bodies breaking apart this step
};

}  // namespace volpar
