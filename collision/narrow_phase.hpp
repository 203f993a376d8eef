#pragma once
// The narrow phase driver (docs/narrow-phase.md): the contacts of each body pair,
// body-plane pair and deformable body touching itself are grouped into local patches (patch_builder.hpp:
// grown from the deepest contact over connector neighbours while the contacts' surface directions stay
// within a bound), and each patch gets a separating plane from the local particles (plane_solver.hpp) with
// its normal, point and depths. A patch whose plane does not validate is split in two, recursively; a single
// contact that still does not validate, and a deformable body's contacts with itself, are resolved along
// their centre lines (NormalSource::ContactLines, counted). Patches of rigid pairs that barely moved are
// taken over from the last step.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "volpar/engine/core/large_pages.hpp"
#include "volpar/engine/core/paced_split.hpp"
#include "volpar/collision/contact_patch.hpp"
#include "volpar/collision/normal_cache.hpp"
#include "volpar/collision/particle_contacts.hpp"
#include "volpar/collision/patch_builder.hpp"
#include "volpar/collision/plane_solver.hpp"
#include "volpar/collision/separating_plane.hpp"
#include "volpar/engine/core/body_store.hpp"
#include "volpar/engine/core/particle_store.hpp"
#include "volpar/engine/core/plane.hpp"
#include "volpar/engine/core/process_group.hpp"
#include "volpar/engine/core/thread_pool.hpp"

namespace volpar {

/// Patches and their separating planes for every contact group.
///
/// Temporal coherence: the patches of a group between two rigid or static bodies (or a rigid body and a
/// plane) depend only on the group's contact pairs and the bodies' relative pose. When a group has exactly
/// the contact pairs it had when its patches were last computed and (for body pairs) the relative pose has
/// not moved since by more than PlaneSettings::reuseAngle and reuseShift, the patches are taken over: each
/// normal is carried along in the frame of the body whose face it is (B's where it is B's face, else A's:
/// ContactPatch::normalSide), and every contact's depth along its patch normal and each patch's deepest
/// point are computed afresh. A settled stack or pile then costs almost nothing here.
///
/// Groups are independent: with a ThreadPool they are shared among its workers in contiguous ranges and
/// the results merged in group order, so the output does not depend on the number of threads.
class NarrowPhase {
 public:
  void setSettings(const PlaneSettings& s) { settings_ = s; }
  [[nodiscard]] const PlaneSettings& settings() const { return settings_; }

  /// Shares the groups of later runs with other processes (null: none): each computes a contiguous run of
  /// the groups, and every one gets every process's patches (docs/distributed.md). Every process calls run()
  /// with the same input and gets the same output, that of one process alone. Each process keeps the
  /// entries for reuse of the groups it computed; an entry goes to another process only when its group has
  /// passed to that process. The entries kept so far (by runs of this process alone, which every process made
  /// alike) are every process's until its first run with the others.
  void setProcesses(ProcessGroup* processes);
  /// Patches and planes for every contact group. `pool` (optional) shares the groups among threads.
  void run(const NarrowPhaseInput& in, const ContactSet& contacts, PatchSet& out, ThreadPool* pool = nullptr);
  /// Forgets the patches kept for reuse (the next run computes every patch).
  void clearCache();
  /// Puts the patches kept for reuse under "narrow_phase/..." (collision_state.cpp): with processes, every
  /// process's, as one process alone keeps them (so every process must call it).
  void saveCache(StateArchive& archive) const;
  /// Takes them back; false (with the reason in `reader`) where they do not fit together.
  bool restoreCache(StateReader& reader);
  /// The groups whose patches this process keeps for reuse (with processes: those of its own groups).
  [[nodiscard]] std::size_t cachedGroups() const { return cache_.groups.size(); }
  /// With processes: the entries for reuse this process received from others in the last run.
  [[nodiscard]] std::size_t entriesReceived() const { return entriesReceived_; }

 private:
  /// What identifies a group from one step to the next: kind 0 = body pair (a, b), 1 = body a and plane b.
  struct GroupKey {
    std::uint32_t kind = 0, a = 0, b = 0;
    friend auto operator<=>(const GroupKey&, const GroupKey&) = default;
  };
  /// A group's patches as last computed: normals in A's frame (planes: the world frame).
  struct CachedPatch {
    Vec3 normal = Vec3::UnitZ();  // world for a plane's group; else in the frame of normalSide's body
    double margin = 0.0;
    std::uint32_t count = 0;
    PlaneCase planeCase = PlaneCase::VertexFace11;
    NormalSource source = NormalSource::CentreLine;
    bool validated = false;
    bool lookAhead = false;
    PlaneCase lookAheadCase = PlaneCase::VertexFace11;
    std::int8_t curvedSide = -1;
    std::int8_t normalSide = 0;  // the body whose frame `normal` is in: 0 A, 1 B (ContactPatch::normalSide)
    std::array<Vec3, 2> core{Vec3::Zero(), Vec3::Zero()};  // in A's frame, about A's position
  };
  struct CachedGroup {
    GroupKey key;
    Quat relRotation = Quat::Identity();  // B's orientation in A's frame when computed
    Vec3 relPosition = Vec3::Zero();      // B's position in A's frame when computed
    std::uint32_t pairFirst = 0, pairCount = 0;    // the contact pairs, in cache pairs
    std::uint32_t patchFirst = 0, patchCount = 0;  // the patches, in cache patches
  };
  struct Cache {
    LargeVector<CachedGroup> groups;                            // sorted by key
    LargeVector<std::pair<ParticleId, ParticleId>> pairs;       // per group: its contacts' (a, b)
    LargeVector<std::uint32_t> order;                           // per group: contact order, patch by patch
    LargeVector<CachedPatch> patches;
    void clear() {
      groups.clear();
      pairs.clear();
      order.clear();
      patches.clear();
    }
  };

  /// Scratch and output of one worker thread.
  /// The output of a chunk of the groups, merged in order afterwards. (Chunks and workers start on cache
  /// lines of their own: two threads filling neighbouring ones must not share one.)
  struct alignas(64) Output {
    LargeVector<ContactPatch> patches;
    LargeVector<std::uint32_t> contacts;
    NarrowPhaseStats stats;
    LargeVector<std::uint8_t> taken;  // (with processes: per group of the chunk, 1 where its patches were taken over)
    Cache cache;
    // where it goes in the merged output
    std::size_t patchBase = 0, contactBase = 0, groupBase = 0, pairBase = 0, orderBase = 0, cachedPatchBase = 0;
  };
  struct alignas(64) Worker {
    Output* o = nullptr;  // the chunk being worked on
    // scratch, reused across patches and steps
    std::vector<std::uint32_t> order, sizes;
    LargeVector<std::pair<std::uint32_t, std::uint32_t>> ranges;  // patches to solve, as ranges of `order`
    PatchBuilder builder;
    PlaneSolver solver;
  };

  [[nodiscard]] static bool cacheable(const NarrowPhaseInput& in, const ContactGroup& g);
  [[nodiscard]] static GroupKey keyOf(const ContactGroup& g);
  /// The relative pose of B in A's frame (planes: A's own pose).
  static void relativePose(const NarrowPhaseInput& in, const ContactGroup& g, Quat& rotation, Vec3& position);
  [[nodiscard]] bool reusable(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                              const CachedGroup& c) const;
  /// The cache entry whose patches group g takes over (kNoMatch: none), found from `cursor` on (which it
  /// leaves at g's key, for the next group).
  using CacheCursor = LargeVector<CachedGroup>::const_iterator;
  static constexpr std::uint32_t kNoMatch = 0xffffffffu;
  [[nodiscard]] std::uint32_t takenOver(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g,
                                        CacheCursor& cursor) const;
  /// Takes over the patches of cache entry `entry` for group g, and keeps the entry as it is for the next run.
  void reuse(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, std::uint32_t entry,
             Worker& w, PatchSet& out) const;
  void remember(const NarrowPhaseInput& in, const ContactSet& set, const ContactGroup& g, std::size_t patchBegin,
                Worker& w) const;
  void makePatches(const NarrowPhaseInput& in, const ContactSet& contacts, const ContactGroup& g, Worker& w,
                   PatchSet& out) const;
  PlaneSettings settings_;
  LargeVector<Worker> workers_;
  Cache cache_;                        // what the last run computed or reused, for the next
  LargeVector<Output> chunks_;
  PacedSplit groupSplit_;  // the groups' ranges of the workers, and their pieces (the chunks)
  // with processes: this process's chunks as bytes, every process's, and every process's chunks again
  ProcessGroup* processes_ = nullptr;
  ExchangeBytes mine_, all_;
  LargeVector<std::size_t> shareOffset_, shareCount_;
  LargeVector<Output> gathered_;
  /// With processes: per group of this process's run, its entry in the cache (kNoMatch: none), which the
  /// workers test as one process does; and each process's first group (and the end), the groups divided in
  /// runs of equal estimated cost.
  LargeVector<std::uint32_t> match_;
  LargeVector<std::size_t> groupStart_;
  /// With processes, who keeps which entry, as every process knows it from the last run (no exchange): the
  /// keys of the last run's cacheable groups, in key order, the process whose run held each (which keeps its
  /// entry) and whether its patches were taken over. `everyKeeps_`: every process keeps the same entries
  /// (none yet, a checkpoint's, or those of runs each made alone: everyKeepsCache()), so none needs another's.
  LargeVector<GroupKey> keptKeys_;
  LargeVector<std::uint32_t> keptBy_;
  LargeVector<std::uint8_t> keptTaken_;
  bool everyKeeps_ = true;
  /// With processes, per group of this run: the process keeping its entry (kNoMatch: none), whether it is
  /// cacheable and its estimated cost.
  LargeVector<std::uint32_t> keeper_;
  LargeVector<std::uint8_t> cacheable_, cost_;
  bool keysInOrder_ = true;  // (with processes: whether the cacheable groups come in key order)
  std::size_t entriesReceived_ = 0;
  Cache received_;  // (with processes: the entries handed over in the last run, every process's)
  /// Divides the groups among the processes (groupStart_) by their costs estimated from the last run (a
  /// group whose entry some process keeps and whose patches were taken over in the last run counts as taken
  /// over again), hands each process the entries of its groups that another keeps, and finds its own
  /// groups' entries (match_). Nothing waits for a test of the entries: each process's workers test its
  /// own groups' entries as they go, as one process's do.
  void divideGroups(const NarrowPhaseInput& in, const ContactSet& contacts);
  /// Hands over the entries of the groups that passed to another process than the one keeping them.
  void moveEntries(const ContactSet& contacts);
  /// Every process keeps the entries of cache_, as they stand (all alike: none, a checkpoint's, or those of runs
  /// each process made alone).
  void everyKeepsCache();
  /// Who keeps which entry for the next run (keptKeys_, keptBy_, keptTaken_), from this run's division and
  /// every process's chunks' `taken` (listed of gathered_).
  void noteKeepers(const ContactSet& contacts, std::size_t listed);
  /// One cache entry as bytes (`tag`, the group, its pairs, order and patches), and back (appended to `to`).
  static void appendEntry(ExchangeBytes& bytes, std::uint32_t tag, const Cache& from, std::size_t entry);
  static std::uint32_t readEntry(const std::byte*& at, Cache& to);
  /// Appends entry `entry` of `from` to `to`.
  static void copyEntry(const Cache& from, std::size_t entry, Cache& to);
  /// Every process's entries as one process alone keeps them: in key order, each once.
  [[nodiscard]] Cache wholeCache() const;
  /// Every process's chunks, from each process's `count` chunks of chunks_, into gathered_ (their patches,
  /// contacts and counts: the entries for reuse stay); returns how many.
  std::size_t gatherChunks(std::size_t count);
  /// Every process's values of `values` for the contacts of its groups.
  template <class T>
  void shareContacts(const ContactSet& contacts, LargeVector<T>& values);
};

}  // namespace volpar
