// The large-page pool hands out aligned blocks that do not overlap, reuses and merges what is given back,
// returns a region to the system once all its blocks are back, and asks the system for large pages in its
// regions; a LargeVector behaves as a std::vector.
#include "volpar/engine/core/large_pages.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace volpar {
namespace {

constexpr std::size_t kKiB = 1024, kMiB = 1024 * 1024;

TEST(LargePages, BlocksAreAlignedAndDisjointAndGoBack) {
  const LargePageStats before = largePageStats();
  const std::vector<std::size_t> sizes{16 * kKiB, 100 * kKiB + 3, 3 * kMiB, 1000, 70 * kMiB, 17 * kKiB, 40 * kMiB};
  std::vector<unsigned char*> blocks;
  for (const std::size_t n : sizes) {
    auto* p = static_cast<unsigned char*>(allocateLargePages(n));
    ASSERT_EQ(reinterpret_cast<std::uintptr_t>(p) % 64, 0u) << n;
    blocks.push_back(p);
  }
  // each block filled with its own byte, then all checked: a block that overlaps another is overwritten
  for (std::size_t i = 0; i < blocks.size(); ++i) std::memset(blocks[i], static_cast<int>(i + 1), sizes[i]);
  for (std::size_t i = 0; i < blocks.size(); ++i)
    for (std::size_t k = 0; k < sizes[i]; k += 511) ASSERT_EQ(blocks[i][k], i + 1) << "block " << i << " byte " << k;
  if (largePagePoolUsed()) {
    const LargePageStats during = largePageStats();
    EXPECT_EQ(during.blocks, before.blocks + sizes.size() - 1);  // (1000 bytes come from operator new)
    EXPECT_EQ(during.handedOut, before.handedOut + sizes.size() - 1);
    std::size_t pooled = 0;
    for (const std::size_t n : sizes) pooled += n >= 16 * kKiB ? n : 0;
    EXPECT_GE(during.usedBytes, before.usedBytes + pooled);
    EXPECT_GE(during.reservedBytes, during.usedBytes);
  }
  for (std::size_t i = 0; i < blocks.size(); ++i) freeLargePages(blocks[i], sizes[i]);
  const LargePageStats after = largePageStats();
  EXPECT_EQ(after.blocks, before.blocks);
  EXPECT_EQ(after.usedBytes, before.usedBytes);
  EXPECT_EQ(after.regions, before.regions);  // every region emptied went back to the system
  EXPECT_EQ(after.reservedBytes, before.reservedBytes);
}

TEST(LargePages, BlocksGivenBackAreMergedAndReused) {
  if (!largePagePoolUsed()) GTEST_SKIP() << "this build does not use the pool (AddressSanitizer or not Linux)";
  // three neighbouring blocks; the first two given back make one free block that a block as large as both
  // fills, at the first one's address
  void* keep = allocateLargePages(kMiB);  // (holds the region while the others come and go)
  void* a = allocateLargePages(kMiB);
  void* b = allocateLargePages(kMiB);
  void* c = allocateLargePages(kMiB);
  ASSERT_EQ(static_cast<char*>(b), static_cast<char*>(a) + kMiB);
  ASSERT_EQ(static_cast<char*>(c), static_cast<char*>(b) + kMiB);
  freeLargePages(b, kMiB);
  freeLargePages(a, kMiB);
  void* both = allocateLargePages(2 * kMiB);
  EXPECT_EQ(both, a);
  freeLargePages(both, 2 * kMiB);
  freeLargePages(c, kMiB);
  // and the whole region merged again: one block as large as everything after `keep` goes there
  void* rest = allocateLargePages(3 * kMiB);
  EXPECT_EQ(rest, a);
  freeLargePages(rest, 3 * kMiB);
  freeLargePages(keep, kMiB);
}

// the VmFlags of the mapping that holds `p` in /proc/self/smaps ("hg": the program asked for large pages)
std::string mappingFlags(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  const auto at = reinterpret_cast<std::uintptr_t>(p);
  std::string line;
  bool inside = false;
  while (std::getline(smaps, line)) {
    unsigned long lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-') {
      inside = lo <= at && at < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return {};
}

TEST(LargePages, RegionsAskForLargePages) {
  if (!largePagePoolUsed()) GTEST_SKIP() << "this build does not use the pool (AddressSanitizer or not Linux)";
  void* p = allocateLargePages(4 * kMiB);
  const std::string flags = mappingFlags(p);
  ASSERT_FALSE(flags.empty()) << "no mapping in /proc/self/smaps holds the block";
  EXPECT_NE((flags + " ").find(" hg "), std::string::npos) << flags;
  // an ordinary allocation of the same size does not ask
  std::vector<char> plain(4 * kMiB);
  EXPECT_EQ((mappingFlags(plain.data()) + " ").find(" hg "), std::string::npos);
  freeLargePages(p, 4 * kMiB);
}

TEST(LargePages, LargeVectorBehavesAsAVector) {
  LargeVector<double> v;
  std::vector<double> w;
  for (int i = 0; i < 300000; ++i) {  // (grows through small blocks into the pool's)
    v.push_back(0.5 * i);
    w.push_back(0.5 * i);
  }
  ASSERT_EQ(v.size(), w.size());
  EXPECT_TRUE(std::equal(v.begin(), v.end(), w.begin()));
  LargeVector<double> copy = v;
  v.clear();
  v.shrink_to_fit();
  EXPECT_TRUE(std::equal(copy.begin(), copy.end(), w.begin()));
}

}  // namespace
}  // namespace volpar
