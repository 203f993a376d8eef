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

bool bit(const std::uint64_t* words, std::size_t i) { return ((words[i / 64] >> (i % 64)) & 1u) != 0; }

}  // namespace

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
  const std::size_t groups = contacts.groups.size(), words = (groups + 63) / 64;
  const auto ranks = static_cast<std::size_t>(processes_->size());
  // the groups whose patches this process can take over from the entries it keeps (the test one process
  // alone makes, on the entry it would have: every entry is as one process alone made it)
  match_.resize(groups);
  held_.assign(words, 0);
  keysInOrder_ = true;
  bool anyKey = false;
  GroupKey last;
  CacheCursor cursor = cache_.groups.cbegin();
  for (std::size_t gi = 0; gi < groups; ++gi) {
    const ContactGroup& g = contacts.groups[gi];
    const bool cacheableGroup = settings_.reuse && cacheable(in, g);
    match_[gi] = cacheableGroup ? takenOver(in, contacts, g, cursor) : kNoMatch;
    if (match_[gi] != kNoMatch) held_[gi / 64] |= std::uint64_t{1} << (gi % 64);
    if (!cacheableGroup) continue;
    const GroupKey key = keyOf(g);
    keysInOrder_ = keysInOrder_ && !(anyKey && key < last);
    last = key;
    anyKey = true;
  }
  // every process's bits: the same estimate of the cost on every process
  processes_->gather(std::as_bytes(std::span<const std::uint64_t>(held_)), all_);
  VOLPAR_ASSERT(all_.size() == ranks * words * sizeof(std::uint64_t), "processes disagree on the contact groups");
  heldBy_.resize(ranks * words);
  if (!all_.empty()) std::memcpy(static_cast<void*>(heldBy_.data()), all_.data(), all_.size());
  heldAnywhere_.assign(words, 0);
  for (std::size_t r = 0; r < ranks; ++r)
    for (std::size_t k = 0; k < words; ++k) heldAnywhere_[k] |= heldBy_[r * words + k];
  std::uint64_t total = 0;
  for (std::size_t gi = 0; gi < groups; ++gi) total += bit(heldAnywhere_.data(), gi) ? kTakenOver : kComputed;
  // process r starts at the first group before which the cost reaches r / R of the total
  groupStart_.assign(ranks + 1, groups);
  groupStart_[0] = 0;
  std::uint64_t before = 0;
  std::size_t r = 1;
  for (std::size_t gi = 0; gi < groups && r < ranks; ++gi) {
    while (r < ranks && before * ranks >= r * total) groupStart_[r++] = gi;
    before += bit(heldAnywhere_.data(), gi) ? kTakenOver : kComputed;
  }
  moveEntries(contacts, words);
}

void NarrowPhase::moveEntries(const ContactSet& contacts, std::size_t words) {
  // a group to be taken over by a process that does not keep its entry gets it from the first process that
  // does; every process sees alike from the bits whether any entry moves
  const auto ranks = static_cast<std::size_t>(processes_->size()), me = static_cast<std::size_t>(processes_->rank());
  entriesReceived_ = 0;
  mine_.clear();
  bool moves = false;
  for (std::size_t r = 0; r < ranks; ++r) {
    const std::uint64_t* own = heldBy_.data() + r * words;
    for (std::size_t gi = groupStart_[r]; gi < groupStart_[r + 1]; ++gi) {
      if (!bit(heldAnywhere_.data(), gi) || bit(own, gi)) continue;
      moves = true;
      std::size_t from = 0;
      while (!bit(heldBy_.data() + from * words, gi)) ++from;
      if (from == me) appendEntry(mine_, static_cast<std::uint32_t>(gi), cache_, match_[gi]);
    }
  }
  if (!moves) return;
  processes_->gather(mine_, all_);
  // (the entries for this process's groups, after its own: the groups' lookups are done, by match_)
  const std::size_t lo = groupStart_[me], hi = groupStart_[me + 1];
  const std::byte* at = all_.data();
  const std::byte* const end = all_.data() + all_.size();
  received_.clear();
  while (at < end) {
    const std::uint32_t gi = readEntry(at, received_);
    if (gi < lo || gi >= hi) continue;  // (another process's)
    copyEntry(received_, received_.groups.size() - 1, cache_);
    VOLPAR_ASSERT(keyOf(contacts.groups[gi]) == cache_.groups.back().key, "an entry for reuse sent for another group");
    match_[gi] = static_cast<std::uint32_t>(cache_.groups.size() - 1);
    ++entriesReceived_;
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
