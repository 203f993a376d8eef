#pragma once
// Sequential-impulse contact solver (docs/architecture.md, The step), after Erin Catto's "Iterative Dynamics with
// Temporal Coherence" (GDC 2005) and "Modeling and Solving Constraints" (GDC 2009), with split impulses
// for position correction (Catto, Box2D; Bullet's m_splitImpulse).
//
// Per contact point: a normal impulse with accumulated clamping (>= 0); Coulomb friction in two tangent
// directions, the pair clamped to the cone |lambda_t| <= mu lambda_n, acting at the point or at an offset
// from it (a reduced patch's points carry the twisting resistance of the area they stand for); restitution as a velocity target
// -e v_n for approach speeds above a threshold; warm starting from the previous step's impulses, matched by
// the point's key (the pair of particle ids, exact because ids are stable). Penetration is removed by
// separate "pseudo" velocities that move positions but carry no momentum, so position correction adds no
// energy (no Baumgarte bounce) and stacks rest without sinking or jitter.
//
// Bodies are rigid bodies (mass, world inverse inertia) or point masses (particles of deformable bodies);
// static bodies and planes are the fixed side (index kFixed).
//
// Order and threads: the bodies are split in two at their median along the longest side of their bounds,
// each half again, and so on to a fixed depth (a tree of bisections whose leaves hold about
// SolverSettings::bodiesPerLeaf bodies each; the depth depends on the number of bodies, never on the threads).
// Each point belongs to the smallest node of the tree holding both its bodies: a leaf, or the node whose cut
// it crosses. In every iteration the leaves' points are solved first, then those of the nodes one level up,
// and so on to the root's. The nodes of one level share no body, so threads can solve them at once (a spin
// barrier between the levels) with exactly the arithmetic of one thread: the result does not depend on the
// thread count, nor on which thread (or, across machines, which process) solves which node. So, where a
// level has enough nodes, a thread that is done with its share takes over nodes a slower one has not started.

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/process_group.hpp"
#include "volpar/engine/core/state_archive.hpp"
#include "volpar/engine/core/thread_pool.hpp"
#include "volpar/engine/core/types.hpp"

namespace volpar {

struct SolverSettings {
  int iterations = 10;                  ///< velocity iterations
  int positionIterations = 10;          ///< split-impulse (pseudo-velocity) iterations, at most
  /// [m/s] position iterations stop once no point's pseudo velocity changed by more than this in one
  double positionTolerance = 1e-4;
  double restitutionThreshold = 0.2;    ///< [m/s] approach speed below which contacts do not bounce
  /// [-] fraction of the penetration (beyond the slop) the pseudo velocities aim to remove per step. The
  /// position iterations rarely converge under a tall stack, so they remove less than this: 0.6 left
  /// pile-8000's deepest overlap at 1.08-1.21 mm where 0.2 left 1.24-1.58 mm (docs/benchmarks.md)
  double baumgarte = 0.6;
  double maxCorrectionSpeed = 1.0;      ///< [m/s] cap on the pseudo velocity of position correction
  bool warmStart = true;
  /// An island (bodies joined by contacts, the fixed world not joining them) in which two touching bodies'
  /// masses differ by this factor or more, with at most heavyIslandRows contact points, has its normal
  /// impulses solved exactly before the iterations: iterations alone converge at a rate set by the mass
  /// ratio (a heavy box on a light one needs hundreds). 0: never.
  double heavyIslandRatio = 10.0;
  int heavyIslandRows = 128;
  /// Bodies per leaf of the solving order's tree (see "Order and threads" above): the tree's depth is the
  /// largest d >= 1 with 2^d leaves of at least this many bodies (at most 2^8 leaves). Part of what defines
  /// the trajectory; threads (and processes) take whole nodes, so more leaves let more of them work at once.
  int bodiesPerLeaf = 128;
  /// Solve two batches of four rows at once in the eight lanes of AVX registers where the processor has AVX
  /// (ContactSolver::wideLanesAvailable()); otherwise, or when false, one batch at a time in four lanes.
  /// Each lane's arithmetic is the same either way, so the result is too, bit for bit: only the speed
  /// differs.
  bool wideLanes = true;
};

/// A body as the solver sees it.
struct SolverBody {
  Vec3 position = Vec3::Zero();  ///< centre of mass [m] (only orders the work)
  Vec3 v = Vec3::Zero();         ///< linear velocity [m/s]
  Vec3 w = Vec3::Zero();         ///< angular velocity [rad/s] (0 for point masses)
  Vec3 pv = Vec3::Zero();        ///< pseudo linear velocity (position correction only)
  Vec3 pw = Vec3::Zero();        ///< pseudo angular velocity
  Mat3 invInertia = Mat3::Zero();  ///< world [1/(kg m^2)]; zero for point masses
  double invMass = 0.0;          ///< [1/kg]
};

/// One contact point between two solver bodies (or one body and the fixed world).
struct ContactPointInput {
  static constexpr std::uint32_t kFixed = 0xffffffffu;
  std::uint32_t a = kFixed;      ///< solver body on side A
  std::uint32_t b = kFixed;      ///< solver body on side B
  Vec3 rA = Vec3::Zero();        ///< contact point minus A's centre of mass [m]
  Vec3 rB = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();   ///< unit, from A towards B
  /// [m] where the friction rows act, relative to the contact point (tangential, usually zero): a point
  /// standing for a patch's area carries its friction at the area's mean lever arm about the patch's
  /// centre, so that the patch resists twisting as the whole area does
  Vec3 frictionOffset = Vec3::Zero();
  double depth = 0.0;            ///< penetration along the normal [m] (> 0 overlapping; < 0 the gap of a
                                 ///< speculative contact, which may close but not overlap within the step)
  double slop = 0.0;             ///< penetration left uncorrected [m]
  double friction = 0.5;         ///< combined Coulomb coefficient
  double restitution = 0.0;      ///< combined coefficient
  std::uint64_t key = 0;         ///< identity for warm starting
};

class ContactSolver {
 public:
  ContactSolver();
  ~ContactSolver();
  ContactSolver(ContactSolver&&) noexcept;
  ContactSolver& operator=(ContactSolver&&) noexcept;

  void setSettings(const SolverSettings& s) { settings_ = s; }
  [[nodiscard]] const SolverSettings& settings() const { return settings_; }

  /// Solves the contacts for velocities and pseudo velocities of `bodies` over a step of dt. With a
  /// `pool` the nodes of the solving order's tree are shared among its threads; the result is the same.
  void solve(std::span<SolverBody> bodies, std::span<const ContactPointInput> points, double dt,
             ThreadPool* pool = nullptr);

  /// Optionally before solve(): plans the solve (the tree, the rows' order and, with processes, the division
  /// among the processes) from the bodies and each point's two bodies alone (`pointBodies`: per point, its
  /// solver bodies a and b, as the points will name them), which solve() would otherwise plan itself, with
  /// the same result. So the points themselves can be made while it plans (World does, on one process), or
  /// with processes only those this process reads: pointsRead() says which points this process's share of
  /// the next solve() reads; of the others, solve() reads only a and b, which must be as planned.
  void plan(std::span<const SolverBody> bodies, std::span<const std::pair<std::uint32_t, std::uint32_t>> pointBodies);
  /// Per point of the last plan(): 1 where this process's share of the solve reads it (all of them unless the
  /// processes divide the preparation: see solve()), else 0.
  [[nodiscard]] std::span<const std::uint8_t> pointsRead() const { return pointsRead_; }

  /// Shares the iterations of every solve with other processes (null: none). Every process then calls solve()
  /// with the same bodies and points and does the set-up alone; the nodes of each level of the solving
  /// tree are divided among the processes as among threads, and after each level every process hands what
  /// its nodes changed to the others. Every one returns the velocities and impulses of one process alone,
  /// bit for bit.
  void setProcesses(ProcessGroup* processes) { processes_ = processes; }

  /// Sum of the normal impulses applied in the last solve [N s].
  [[nodiscard]] double totalNormalImpulse() const { return totalNormalImpulse_; }
  [[nodiscard]] std::size_t warmStarted() const { return warmStarted_; }
  /// Whether the next solve() warm starts a point of this key: the last solve (or the checkpoint it was
  /// restored from) had one.
  [[nodiscard]] bool warmStarts(std::uint64_t key) const { return cached(key) != nullptr; }
  /// Puts the impulses the next solve warm-starts from under "solver/..." (a checkpoint).
  void saveWarmStart(StateArchive& archive) const;
  /// Takes them back; false (with the reason in `reader`) where they do not fit together.
  bool restoreWarmStart(StateReader& reader);
  /// The depth of the last solve's tree (2^depth leaves, at most 2^kMaxDepth) and its rows (contact
  /// points) at a level of it (0: the root).
  static constexpr int kMaxDepth = 8;
  [[nodiscard]] int depth() const { return depth_; }
  [[nodiscard]] std::size_t rowsAtLevel(int level) const {
    const std::size_t first = levelStart(level), end = first + (std::size_t{1} << level);
    return parts_[end] - parts_[first];
  }
  /// Sweeps over a node in the last solve that a thread took over from the thread whose share it was (one
  /// that ran slower; see solve()): 0 on one thread, and where the threads kept pace.
  [[nodiscard]] std::size_t nodesTakenOver() const { return claims_->takenOver.load(std::memory_order_relaxed); }
  /// Islands whose normal impulses the last solve found exactly (see SolverSettings::heavyIslandRatio).
  [[nodiscard]] std::size_t heavyIslandsSolved() const { return heavyIslandsSolved_; }
  /// Whether this processor runs the solver's eight-lane path (SolverSettings::wideLanes): AVX, on x86-64.
  [[nodiscard]] static bool wideLanesAvailable();
  /// The impulse [N s] each point of the last solve applied to its B side (A got the opposite), world.
  [[nodiscard]] std::span<const Vec3> impulses() const { return impulses_; }

 private:
  // The iterations run in single precision, four rows at once in SIMD lanes; the velocities go back in
  // double, recomputed from the points' impulses.
  using V4 = Eigen::Vector4f;
  using F4 = Eigen::Array4f;
  /// One constraint direction of four rows, lane by lane: the unit direction d and, per side, the angular
  /// part of the Jacobian (r x d) and the angular velocity change per unit impulse I^-1 (r x d).
  struct AxisBatch {
    F4 dx, dy, dz, ax, ay, az, bx, by, bz, tax, tay, taz, tbx, tby, tbz;  // d, crossA, crossB, turnA, turnB
  };
  /// Four rows solved at once, one in each lane, structure of arrays; the four share no body (other than a
  /// part's fixed side, which never moves). Lanes beyond a colour's rows are padding with zero
  /// coefficients on the fixed side.
  struct Batch {
    AxisBatch n, t1, t2;
    F4 massN, massT1, massT2;   // 1 / (J M^-1 J^T) per direction
    F4 invMassA, invMassB;
    F4 targetN;                 // velocity target along n (restitution, speculative gap)
    F4 friction;
    F4 biasP;                   // pseudo-velocity target
    F4 lambdaN, lambdaT1, lambdaT2, lambdaP;
    std::array<std::uint32_t, 4> a, b, row;  // slots, and the rows they came from (kNoRow: padding)
  };
  static constexpr std::uint32_t kNoRow = 0xffffffffu;
  /// A part's (a node of the tree's) rows coloured so that no two rows of a colour share a body, four of a
  /// colour to a batch; the rows no colour could take (a body in more than 64 rows) follow, one to a batch,
  /// solved one after another.
  struct PartBatches {
    LargeVector<Batch> batches;
    std::size_t restBegin = 0;               // the first one-row batch
    LargeVector<std::uint8_t> colour;        // per row of the part (64: none)
    std::array<std::uint32_t, 65> start{};   // (counting sort by colour)
    LargeVector<std::uint32_t> sorted;       // rows in batch order, four to a batch (kNoRow: padding)
  };
  /// The normal impulses of each small island of bodies whose masses differ widely, solved exactly (a
  /// dense linear complementarity problem over its normal rows, by active sets) after the warm start; the
  /// iterations then go on from there (contact_solver_islands.cpp).
  void solveHeavyIslands();
  /// Colours a part's rows and lays out its batches (rows not yet prepared).
  void colour(std::size_t part);
  /// The tree: parts are numbered level by level from the leaves (leaf k is part k) up to the root (the
  /// last part); a level's nodes are numbered along it.
  [[nodiscard]] std::size_t levelStart(int level) const { return levelStart_[static_cast<std::size_t>(level)]; }
  [[nodiscard]] std::size_t partCount() const { return levelStart_[0] + 1; }
  [[nodiscard]] int levelOf(std::size_t part) const {
    int l = depth_;
    while (l > 0 && part >= levelStart(l - 1)) --l;
    return l;
  }
  /// Splits byLeaf_[begin, end) (the bodies of node `node` at `level`) at its median along the longest side
  /// of the bodies' bounds, down to the leaves.
  void bisect(std::span<const SolverBody> bodies, std::size_t begin, std::size_t end, int level, std::size_t node);
 public:
  /// The depth of the solving order's tree for a number of bodies (SolverSettings::bodiesPerLeaf).
  [[nodiscard]] static int depthFor(std::size_t bodies, int bodiesPerLeaf);

 private:
  /// One velocity iteration over a part's batches; after(j) follows batch j.
  template <class After>
  void velocityPart(std::size_t part, const After& after);
  bool positionPart(std::size_t part);

  /// The last step's impulses, by batch lane, and an open-addressing hash table from warm-starting key to lane.
  struct Cached {
    float lambdaN;
    V4 lambdaT;  // world tangential impulse; w: the speed a point arriving at contact in that step arrived with
  };
  static constexpr std::uint32_t kEmpty = 0xffffffffu;

  SolverSettings settings_;
  /// Rows in solving order: part by part (the leaves first, the root last); `parts_` holds the parts'
  /// boundaries.
  void order(std::span<const SolverBody> bodies);
  /// Reorders a part's rows (from scratch_ into order_) so that the points of one body pair do not follow each other.
  void spread(std::size_t part);

  /// The last step's impulses for a key, or null.
  [[nodiscard]] const Cached* cached(std::uint64_t key) const;
  /// Indexes this step's keys (keys_) for the next step's warm start.
  void remember();

  int depth_ = 1;                       // the tree's leaves: 2^depth_
  LargeVector<std::size_t> levelStart_;  // per level (0: the root): its first part
  LargeVector<PartBatches> batches_;    // per part
  /// per level: the colours each slot's rows took (a node clears its own slots' entries)
  LargeVector<std::vector<std::uint64_t>> used_;
  LargeVector<std::pair<std::uint32_t, std::uint32_t>> rowSlots_;  // per row: its bodies' slots
  /// Per batch lane, each part's batches from posBase_[part]: the warm-starting key (keys_), this step's
  /// impulses (nextCache_) and the last step's (cache_, cacheKeys_)
  LargeVector<std::size_t> posBase_;
  LargeVector<std::uint64_t> keys_;
  LargeVector<std::pair<std::uint32_t, std::uint32_t>> ab_;  // per input point: its bodies
  LargeVector<std::uint32_t> order_;  // per row: the index of its input point
  LargeVector<std::uint32_t> rank_, scratch_;  // (ordering scratch)
  LargeVector<std::vector<std::uint32_t>> rankStart_;  // per part (spread() runs for several parts at once)
  LargeVector<std::size_t> parts_;     // per part: its first row (and the end)
  LargeVector<std::uint32_t> leafOf_;  // per solver body: its leaf
  LargeVector<std::size_t> leafStart_;  // per leaf: its first body in byLeaf_ (and the end)
  LargeVector<std::uint32_t> slot_;    // per solver body: its entry in the velocity arrays
  LargeVector<std::uint32_t> leafNext_;  // (ordering scratch: per leaf, its next slot)
  LargeVector<std::size_t> partNext_;    // (ordering scratch: per part, its next row)
  LargeVector<std::uint32_t> fixedSlot_;  // per part: the fixed side's entry
  LargeVector<std::uint32_t> slotBegin_, slotEnd_;  // per part: the range of its bodies' slots
  LargeVector<std::uint8_t> isFixed_;  // per slot: a part's fixed side
  std::size_t slots_ = 0;
  LargeVector<std::pair<double, std::uint32_t>> byLeaf_;  // bodies, leaf by leaf (sort keys: the cut's axis)
  SpinBarrier barrier_;
  /// How the threads share out a level's nodes (see solve()): per worker, the sweep's number and the front
  /// and back of the nodes of its range still to take (a cache line each); and the sweeps over a node that
  /// a worker took over from another's range
  struct Claims {
    struct alignas(64) Range {
      std::atomic<std::uint64_t> word{0};
    };
    std::array<Range, std::size_t{1} << kMaxDepth> range{};  // (at most one worker per leaf)
    std::atomic<std::size_t> takenOver{0};
  };
  std::unique_ptr<Claims> claims_ = std::make_unique<Claims>();
  std::uint32_t phase_ = 0;  // the last solve's last sweep
  // velocities of the solver bodies and of each part's fixed side (always zero)
  LargeVector<V4> v_, w_, pv_, pw_;
  /// per slot: the sums of the impulses and of their moments about the body's centre, in double, from which
  /// the velocities are rebuilt at the end
  LargeVector<Vec3> dp_, dl_;
  LargeVector<std::size_t> started_;  // per part: rows warm started
  LargeVector<double> normalSum_;     // per part: the normal impulses
  LargeVector<std::uint8_t> partHeavy_;  // per part: whether one of its rows joins a heavy pair (heavyPair())
  std::array<std::vector<std::uint8_t>, 2> moved_;  // per part: whether a position sweep moved (two sweeps' worth)
  ProcessGroup* processes_ = nullptr;
  LargeVector<std::size_t> shareOffset_, shareCount_;  // (the shares' ranges in bytes, per process)
  /// With processes: entries of some arrays that each process hands the others, process r's
  /// index[start[r]] up to index[start[r + 1]] (the same lists on every process, made from the same rows).
  struct Handover {
    LargeVector<std::uint32_t> index;
    LargeVector<std::size_t> start;
  };
  /// Plans this solve's handovers (below) from the tree and the rows.
  void planHandovers();
  /// The real lanes of each process's parts (lanes_) and their rows' input points (points_), once they are
  /// coloured and spread.
  void planEndHandovers();
  /// Whether a row joins two bodies whose masses differ by heavyIslandRatio or more (solveHeavyIslands()
  /// then has islands to solve, from every part's rows).
  [[nodiscard]] bool heavyPairs(std::span<const SolverBody> bodies) const;
  /// Whether two bodies of these inverse masses (neither fixed) make a row solveHeavyIslands() solves exactly.
  [[nodiscard]] static bool heavyPair(float invMassA, float invMassB, double ratio) {
    const auto ia = static_cast<double>(invMassA), ib = static_cast<double>(invMassB);
    return ia > 0.0 && ib > 0.0 && (ia >= ratio * ib || ib >= ratio * ia);
  }
  /// With the set-up divided: every process's parts' lanes (the rows in colour order) and keys to every
  /// process, for the warm start of the next solve.
  void shareLanes();
  /// The tree, the rows' order and, with processes, their division, from bodies and ab_ (the start of a solve).
  void planSolve(std::span<const SolverBody> bodies);
  bool divideSetUp_ = false;  // whether this solve's processes each prepare their own nodes alone
  bool planned_ = false;      // plan() made the next solve's plan
  LargeVector<std::uint8_t> pointsRead_;
  ExchangeBytes lanesMine_, lanesAll_;
  LargeVector<std::uint32_t> lanesScratch_;
  LargeVector<std::uint64_t> keysScratch_;
  /// Hands every process the values the others hold at their entries of `h`, of each array in turn.
  template <class... T>
  void handOver(const Handover& h, LargeVector<T>&... arrays);
  /// per level: the slots of the bodies whose rows lie in the nodes of more than one process, that this
  /// level's nodes touch (each such body's velocity, after every level that changes it, goes to every
  /// process, so the next node to read it reads its last value whichever process solves that node)
  LargeVector<Handover> boundary_;
  Handover interior_;  // the slots of the bodies the nodes of one process alone touch, handed over at the end
  Handover partsOf_, lanes_, points_;  // each process's parts, their real lanes and their rows' points
  Handover eachProcess_;               // one entry per process (its own number)
  LargeVector<std::int32_t> slotProcess_;  // (per slot: the process whose nodes touch it; -1 none, -2 several)
  LargeVector<std::uint8_t> listed_;       // (per slot: the level + 1 whose list holds it)
  LargeVector<std::size_t> interiorNext_;  // (per process: its next entry of interior_)
  LargeVector<std::uint8_t> movedBy_;      // per process: whether a node of its moved in a position sweep
  ExchangeBytes handoverBytes_;
  LargeVector<std::uint64_t> cacheKeys_;
  LargeVector<Cached> cache_;
  LargeVector<Cached> nextCache_;
  LargeVector<std::uint32_t> table_;      // lanes of the last step; a power of two long, at most half full
  int tableBits_ = 0;
  // solveHeavyIslands()'s scratch: per slot its island (union-find); the rows (part, batch, lane) grouped by
  // island; one island's dense problem
  LargeVector<std::uint32_t> islandOf_;
  LargeVector<std::uint64_t> islandRows_;
  LargeVector<std::uint32_t> islandStart_, islandFill_;
  LargeVector<std::uint8_t> islandHeavy_;
  LargeVector<double> islandA_, islandB_, islandLambda_, islandU0_;
  LargeVector<std::uint8_t> islandActive_;
  /// The active set's system and its factors (up to 128 x 128: kept off the stack, made with the first
  /// island solved and reused).
  struct IslandSystem;
  std::unique_ptr<IslandSystem> islandSystem_;
  std::size_t heavyIslandsSolved_ = 0;
  LargeVector<Vec3> impulses_;
  double totalNormalImpulse_ = 0.0;
  std::size_t warmStarted_ = 0;
};

}  // namespace volpar
