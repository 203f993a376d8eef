// The narrow phase shared by processes (docs/distributed.md, "The narrow phase"): the groups divided in runs
// of equal estimated cost, each process keeping the entries for reuse of its own groups, an entry handed to
// another process when its group passes there, and every process's patches gathered.

#include <algorithm>
#include <cstring>
#include <numeric>

#include "volpar/collision/narrow_phase.hpp"

namespace volpar {

namespace {

/// Calls f on each part of a chunk's output that travels between processes, in one fixed order (the entries
/// for reuse stay with the process that made them).
template <class O, class F>
void eachTravelling(O& o, const F& f) {
  f(o.patches);
  f(o.contacts);
  f(o.stats);
  f(o.taken);
}

template <class T>
void appendRange(ExchangeBytes& to, const T* from, std::size_t n) {
  const auto* data = reinterpret_cast<const std::byte*>(from);
  to.insert(to.end(), data, data + n * sizeof(T));
}

template <class T, class A>
void readRange(const std::byte*& at, std::vector<T, A>& to, std::size_t n) {
  const std::size_t first = to.size();
  to.resize(first + n);
  if (n > 0) std::memcpy(static_cast<void*>(to.data() + first), at, n * sizeof(T));
  at += n * sizeof(T);
}

}  // namespace

void NarrowPhase::setProcesses(ProcessGroup* processes) {
  processes_ = processes;
  everyKeepsCache();
}

void NarrowPhase::everyKeepsCache() {
  keptKeys_.clear();
  for (const CachedGroup& g : cache_.groups) keptKeys_.push_back(g.key);
  keptBy_.assign(keptKeys_.size(), 0);
  keptTaken_.assign(keptKeys_.size(), 1);
  everyKeeps_ = true;
}

std::size_t NarrowPhase::gatherChunks(std::size_t count) {
  // (the chunks' vectors and counts as bytes: the processes are copies of one program on one kind of machine)
  mine_.clear();
  for (std::size_t k = 0; k < count; ++k) eachTravelling(chunks_[k], [&](const auto& part) { appendBytes(mine_, part); });
  processes_->gather(mine_, all_);
  std::size_t listed = 0;
  const std::byte* at = all_.data();
  const std::byte* const end = all_.data() + all_.size();
  while (at < end) {
    if (gathered_.size() <= listed) gathered_.resize(listed + 1);
    eachTravelling(gathered_[listed++], [&](auto& part) { readBytes(at, part); });
  }
  return listed;
}

void NarrowPhase::appendEntry(ExchangeBytes& bytes, std::uint32_t tag, const Cache& from, std::size_t entry) {
  const CachedGroup& c = from.groups[entry];
  appendBytes(bytes, tag);
  appendBytes(bytes, c);
  appendRange(bytes, from.pairs.data() + c.pairFirst, c.pairCount);
  appendRange(bytes, from.order.data() + c.pairFirst, c.pairCount);
  appendRange(bytes, from.patches.data() + c.patchFirst, c.patchCount);
}

void NarrowPhase::copyEntry(const Cache& from, std::size_t entry, Cache& to) {
  CachedGroup c = from.groups[entry];
  const auto pairs = from.pairs.begin() + c.pairFirst;
  const auto order = from.order.begin() + c.pairFirst;
  const auto patches = from.patches.begin() + c.patchFirst;
  c.pairFirst = static_cast<std::uint32_t>(to.pairs.size());
  c.patchFirst = static_cast<std::uint32_t>(to.patches.size());
  to.pairs.insert(to.pairs.end(), pairs, pairs + c.pairCount);
  to.order.insert(to.order.end(), order, order + c.pairCount);
  to.patches.insert(to.patches.end(), patches, patches + c.patchCount);
  to.groups.push_back(c);
}

std::uint32_t NarrowPhase::readEntry(const std::byte*& at, Cache& to) {
  std::uint32_t tag = 0;
  CachedGroup c;
  readBytes(at, tag);
  readBytes(at, c);
  c.pairFirst = static_cast<std::uint32_t>(to.pairs.size());
  c.patchFirst = static_cast<std::uint32_t>(to.patches.size());
  readRange(at, to.pairs, c.pairCount);
  readRange(at, to.order, c.pairCount);
  readRange(at, to.patches, c.patchCount);
  to.groups.push_back(c);
  return tag;
}

void NarrowPhase::divideGroups(const NarrowPhaseInput& in, const ContactSet& contacts) {
  // a group whose patches are taken over costs about a ninth of one computed afresh (pile-1000's collapse:
  // 0.65 against 6 microseconds a patch)
  constexpr std::uint64_t kTakenOver = 1, kComputed = 9;
  const std::size_t groups = contacts.groups.size();
  const auto ranks = static_cast<std::size_t>(processes_->size());
  const auto me = static_cast<std::uint32_t>(processes_->rank());
  // per group: whether it is cacheable, the process keeping its entry (every process knows it from the last
  // run's division: the groups' keys come in order, as the kept ones do, so one cursor walks both) and its
  // cost as the last run found it
  keeper_.resize(groups);
  cacheable_.resize(groups);
  cost_.resize(groups);
  keysInOrder_ = true;
  bool anyKey = false;
  GroupKey last;
  std::uint64_t total = 0;
  std::size_t cursor = 0;
  for (std::size_t gi = 0; gi < groups; ++gi) {
    const ContactGroup& g = contacts.groups[gi];
    const bool cacheableGroup = settings_.reuse && cacheable(in, g);
    cacheable_[gi] = cacheableGroup ? 1 : 0;
    keeper_[gi] = kNoMatch;
    bool taken = false;
    if (cacheableGroup) {
      const GroupKey key = keyOf(g);
      if (anyKey && key < last) {  // (out of order: the cursor starts again; the cache will be cleared)
        keysInOrder_ = false;
        cursor = static_cast<std::size_t>(std::lower_bound(keptKeys_.begin(), keptKeys_.end(), key) -
                                          keptKeys_.begin());
      }
      last = key;
      anyKey = true;
      while (cursor < keptKeys_.size() && keptKeys_[cursor] < key) ++cursor;
      if (cursor < keptKeys_.size() && keptKeys_[cursor] == key) {
        keeper_[gi] = everyKeeps_ ? me : keptBy_[cursor];  // (every process keeps it: this one)
        taken = keptTaken_[cursor] != 0;
      }
    }
    cost_[gi] = static_cast<std::uint8_t>(taken ? kTakenOver : kComputed);
    total += cost_[gi];
  }
  // process r starts at the first group before which the estimated cost reaches r / R of the total
  groupStart_.assign(ranks + 1, groups);
  groupStart_[0] = 0;
  std::uint64_t before = 0;
  std::size_t r = 1;
  for (std::size_t gi = 0; gi < groups && r < ranks; ++gi) {
    while (r < ranks && before * ranks >= r * total) groupStart_[r++] = gi;
    before += cost_[gi];
  }
  moveEntries(contacts);
}

void NarrowPhase::moveEntries(const ContactSet& contacts) {
  // the entries of this process's own groups that it keeps (its cache is in key order, as its groups are)
  const auto ranks = static_cast<std::size_t>(processes_->size()), me = static_cast<std::size_t>(processes_->rank());
  const std::size_t lo = groupStart_[me], hi = groupStart_[me + 1];
  const auto byKey = [](const CachedGroup& c, const GroupKey& k) { return c.key < k; };
  const auto find = [&](std::size_t gi, CacheCursor& at) -> std::uint32_t {
    const GroupKey key = keyOf(contacts.groups[gi]);
    if (at == cache_.groups.cbegin() || !(std::prev(at)->key < key))
      at = std::lower_bound(cache_.groups.cbegin(), cache_.groups.cend(), key, byKey);
    while (at != cache_.groups.cend() && at->key < key) ++at;
    VOLPAR_ASSERT(at != cache_.groups.cend() && at->key == key, "an entry kept for reuse is missing");
    return static_cast<std::uint32_t>(at - cache_.groups.cbegin());
  };
  match_.resize(contacts.groups.size());
  CacheCursor at = cache_.groups.cbegin();
  for (std::size_t gi = lo; gi < hi; ++gi) match_[gi] = keeper_[gi] == me ? find(gi, at) : kNoMatch;
  entriesReceived_ = 0;
  if (everyKeeps_) return;  // (every process keeps every entry: none moves)
  // a group in another process's run than the one keeping its entry gets the entry from its keeper; every
  // process sees alike whether any entry moves
  mine_.clear();
  bool moves = false;
  at = cache_.groups.cbegin();
  for (std::size_t r = 0; r < ranks; ++r)
    for (std::size_t gi = groupStart_[r]; gi < groupStart_[r + 1]; ++gi) {
      if (keeper_[gi] == kNoMatch || keeper_[gi] == r) continue;
      moves = true;
      if (keeper_[gi] == me) appendEntry(mine_, static_cast<std::uint32_t>(gi), cache_, find(gi, at));
    }
  if (!moves) return;
  processes_->gather(mine_, all_);
  // (the entries for this process's groups, after its own: the groups' lookups are done, by match_)
  const std::byte* from = all_.data();
  const std::byte* const end = all_.data() + all_.size();
  received_.clear();
  while (from < end) {
    const std::uint32_t gi = readEntry(from, received_);
    if (gi < lo || gi >= hi) continue;  // (another process's)
    copyEntry(received_, received_.groups.size() - 1, cache_);
    VOLPAR_ASSERT(keyOf(contacts.groups[gi]) == cache_.groups.back().key, "an entry for reuse sent for another group");
    match_[gi] = static_cast<std::uint32_t>(cache_.groups.size() - 1);
    ++entriesReceived_;
  }
}

void NarrowPhase::noteKeepers(const ContactSet& contacts, std::size_t listed) {
  // every group's outcome, in group order (every process's chunks in process order, each chunk's groups in
  // order), and each cacheable group's key with the process whose run held it: that process keeps its entry
  keptKeys_.clear();
  keptBy_.clear();
  keptTaken_.clear();
  everyKeeps_ = false;
  if (!keysInOrder_) return;  // (the cache is cleared: nothing kept)
  std::size_t k = 0, j = 0, r = 0;
  for (std::size_t gi = 0; gi < contacts.groups.size(); ++gi) {
    while (k < listed && j >= gathered_[k].taken.size()) ++k, j = 0;
    VOLPAR_ASSERT(k < listed, "a group missing from the processes' chunks");
    const std::uint8_t taken = gathered_[k].taken[j++];
    while (gi >= groupStart_[r + 1]) ++r;
    if (!cacheable_[gi]) continue;
    keptKeys_.push_back(keyOf(contacts.groups[gi]));
    keptBy_.push_back(static_cast<std::uint32_t>(r));
    keptTaken_.push_back(taken);
  }
}

NarrowPhase::Cache NarrowPhase::wholeCache() const {
  if (!processes_ || processes_->size() == 1) return cache_;
  ExchangeBytes mine, all;
  for (std::size_t k = 0; k < cache_.groups.size(); ++k) appendEntry(mine, 0, cache_, k);
  processes_->gather(mine, all);
  Cache every;
  const std::byte* at = all.data();
  while (at < all.data() + all.size()) readEntry(at, every);
  // in key order, each key once (after a restore every process keeps every entry, all alike)
  std::vector<std::uint32_t> byKey(every.groups.size());
  std::iota(byKey.begin(), byKey.end(), 0u);
  std::stable_sort(byKey.begin(), byKey.end(),
                   [&](std::uint32_t x, std::uint32_t y) { return every.groups[x].key < every.groups[y].key; });
  Cache whole;
  for (std::size_t k = 0; k < byKey.size(); ++k)
    if (k == 0 || !(every.groups[byKey[k]].key == every.groups[byKey[k - 1]].key)) copyEntry(every, byKey[k], whole);
  return whole;
}

}  // namespace volpar
