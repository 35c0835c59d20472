// Draw-unit sorting: material / depth / Gray-code (patent CN105957132) / packed-key
// orders, the incremental Gray queue and the counters. Nothing here is timed.
#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <tuple>

#include <gtest/gtest.h>

#include "engine/features/draw_sort.h"
#include "preprocess/scene/scene.h"
#include "test_support.h"

namespace strata {
namespace {

int bitsOf(uint64_t v) { return __builtin_popcountll(v); }

// Independent of the library: compact the varying bits in ascending order, then Gray -> binary
// bit by bit (binary bit i = XOR of Gray bits i and above).
uint64_t naiveCanonicalRank(uint64_t state, uint64_t varying) {
  uint64_t code = 0;
  int k = 0;
  for (int b = 0; b < 64; ++b)
    if ((varying >> b) & 1) code |= ((state >> b) & 1ull) << k++;
  uint64_t bin = 0, parity = 0;
  for (int i = k - 1; i >= 0; --i) {
    parity ^= (code >> i) & 1;
    bin |= parity << i;
  }
  return bin;
}

// Random render states: `common` bits shared by all, a few bits tied to a material, and
// per-unit flags with skewed probabilities.
std::vector<DrawUnit> randomUnits(std::mt19937_64& rng, size_t n, int state_bits, int materials) {
  std::uniform_int_distribution<int> mat(0, materials - 1);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f), pos(-50.0f, 50.0f);
  std::vector<uint64_t> material_state(materials);
  for (auto& s : material_state) s = rng() & ((1ull << (state_bits / 2)) - 1);
  std::vector<float> p(state_bits);
  for (auto& x : p) x = 0.05f + 0.9f * u01(rng);
  const uint64_t common = 0xA5ull << 56;
  std::vector<DrawUnit> units(n);
  for (size_t i = 0; i < n; ++i) {
    DrawUnit& u = units[i];
    u.material = uint32_t(mat(rng));
    u.state = common | material_state[u.material];
    for (int b = state_bits / 2; b < state_bits; ++b)
      if (u01(rng) < p[b]) u.state |= 1ull << b;
    u.center = {pos(rng), pos(rng), pos(rng)};
    u.transparent = u01(rng) < 0.4f;
    u.object_id = uint32_t(i);
    u.first_triangle = uint32_t(i * 10);
    u.triangle_count = 10;
  }
  return units;
}

std::vector<uint32_t> stableOrderBy(const std::vector<uint64_t>& keys) {
  std::vector<uint32_t> order(keys.size());
  std::iota(order.begin(), order.end(), 0u);
  std::stable_sort(order.begin(), order.end(),
                   [&](uint32_t a, uint32_t b) { return keys[a] < keys[b]; });
  return order;
}

TEST(DrawSortNames, ParseAndNameRoundTrip) {
  for (const std::string& name : drawSortNames())
    EXPECT_EQ(drawSortName(parseDrawSort(name)), name);
  EXPECT_EQ(parseDrawSort("gray"), DrawSort::Gray);
  EXPECT_EQ(drawSortNames().size(), 5u);
  test::expectErrorContaining([] { parseDrawSort("grey"); }, "'grey'");
}

TEST(DrawSortMaterialRegistry, IdsAreStableAndDense) {
  MaterialRegistry reg;
  EXPECT_EQ(reg.registerMaterial("pbr;tex=1"), 0u);
  EXPECT_EQ(reg.registerMaterial("pbr;tex=0"), 1u);
  EXPECT_EQ(reg.registerMaterial("pbr;tex=1"), 0u);
  EXPECT_EQ(reg.registerMaterial(uint64_t(0xdeadbeef)), 2u);
  EXPECT_EQ(reg.registerMaterial(uint64_t(0xdeadbeef)), 2u);
  EXPECT_EQ(reg.find("pbr;tex=0"), 1u);
  EXPECT_EQ(reg.find("unknown"), std::numeric_limits<uint32_t>::max());
  EXPECT_EQ(reg.size(), 3u);
}

TEST(DrawSortMaterial, GroupsByIdStably) {
  std::mt19937_64 rng(7);
  for (size_t n : {0u, 1u, 50u, 3000u}) {
    auto units = randomUnits(rng, n, 16, 9);
    std::vector<uint64_t> keys;
    for (const auto& u : units) keys.push_back(u.material);
    std::vector<uint32_t> order;
    DrawSorter().sortMaterial(units, order);
    EXPECT_EQ(order, stableOrderBy(keys));
    const DrawSortStats s = measureDrawOrder(units, order);
    std::set<uint32_t> distinct;
    for (const auto& u : units) distinct.insert(u.material);
    EXPECT_EQ(s.material_changes, distinct.empty() ? 0 : distinct.size() - 1);
  }
  // Sparse ids (not from a registry) take the radix path.
  std::vector<DrawUnit> sparse(100);
  std::vector<uint64_t> keys;
  for (size_t i = 0; i < sparse.size(); ++i) {
    sparse[i].material = uint32_t((i * 2654435761u) % 7) * 100000u;
    keys.push_back(sparse[i].material);
  }
  std::vector<uint32_t> order;
  DrawSorter().sortMaterial(sparse, order);
  EXPECT_EQ(order, stableOrderBy(keys));
}

TEST(DrawSortDepth, OpaqueFrontToBackThenTransparentBackToFront) {
  std::mt19937_64 rng(11);
  auto units = randomUnits(rng, 2000, 16, 5);
  // Some ties in depth: stable.
  for (size_t i = 0; i < 200; ++i) units[i].center = units[i + 200].center;
  DrawSortView view{{3.0f, -2.0f, 80.0f}, {0.1f, 0.05f, -1.0f}};
  std::vector<uint32_t> order;
  DrawSorter().sortDepth(units, view, order);
  ASSERT_EQ(order.size(), units.size());
  auto depth = [&](uint32_t i) { return glm::dot(units[i].center - view.eye, view.forward); };
  size_t i = 0;
  for (; i < order.size() && !units[order[i]].transparent; ++i)
    if (i > 0) {
      ASSERT_LE(depth(order[i - 1]), depth(order[i]));
      if (depth(order[i - 1]) == depth(order[i])) {
        ASSERT_LT(order[i - 1], order[i]);
      }
    }
  const size_t first_transparent = i;
  for (; i < order.size(); ++i) {
    ASSERT_TRUE(units[order[i]].transparent) << "opaque unit after a transparent one at " << i;
    if (i > first_transparent) {
      ASSERT_GE(depth(order[i - 1]), depth(order[i]));
      if (depth(order[i - 1]) == depth(order[i])) {
        ASSERT_LT(order[i - 1], order[i]);
      }
    }
  }
  size_t opaque = 0;
  for (const auto& u : units) opaque += !u.transparent;
  EXPECT_EQ(first_transparent, opaque);
  std::vector<uint32_t> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (size_t k = 0; k < sorted.size(); ++k) ASSERT_EQ(sorted[k], k);
}

TEST(DrawSortGray, OrderEqualsOrderOfGrayRanks) {
  std::mt19937_64 rng(3);
  DrawSorter sorter;
  // Narrow codes (one bucket pass) and wide ones (digit passes), small and large sets.
  for (int state_bits : {1, 4, 16, 30, 48}) {
    for (size_t n : {1u, 2u, 17u, 1000u, 20000u}) {
      SCOPED_TRACE(::testing::Message() << state_bits << " bits, " << n << " units");
      auto units = randomUnits(rng, n, state_bits, 6);
      std::vector<uint64_t> states;
      for (const auto& u : units) states.push_back(u.state);
      const uint64_t varying = varyingStateBits(states);
      std::vector<uint64_t> ranks;
      for (uint64_t s : states) ranks.push_back(naiveCanonicalRank(s, varying));
      std::vector<uint32_t> order;
      const DrawSortStats st = sorter.sort(units, DrawSort::Gray, {}, order);
      ASSERT_EQ(order, stableOrderBy(ranks));
      // The patent's literal linked-chain buckets give the same order.
      DrawSorter chained;
      chained.gray_chained_buckets = true;
      std::vector<uint32_t> chained_order;
      chained.sortGray(units, chained_order);
      ASSERT_EQ(chained_order, order);
      // The library's rank agrees with the naive one.
      const GrayLayout layout = canonicalGrayLayout(varying);
      for (size_t i = 0; i < std::min<size_t>(n, 100); ++i)
        ASSERT_EQ(layout.rank(states[i]), ranks[i]);
      // Bits common to every unit are set once and reported.
      EXPECT_EQ(st.set_once_mask, ~varying);
      EXPECT_EQ(st.set_once_values, states[0] & ~varying);
      EXPECT_EQ(st.set_once_values >> 56, n ? 0xA5u : 0u);
      // Equal states are contiguous: launches = distinct states.
      EXPECT_EQ(st.launches, std::set<uint64_t>(states.begin(), states.end()).size());
    }
  }
}

TEST(DrawSortGray, CompleteGraySequenceSwitchesOneBitPerStep) {
  std::mt19937_64 rng(5);
  DrawSorter sorter;
  for (int k = 1; k <= 10; ++k) {
    SCOPED_TRACE(::testing::Message() << "k = " << k);
    // k state bits scattered over the 64, plus bits every unit shares.
    std::vector<int> positions(64);
    std::iota(positions.begin(), positions.end(), 0);
    std::shuffle(positions.begin(), positions.end(), rng);
    const uint64_t common = (1ull << positions[k]) | (1ull << positions[k + 1]);
    std::vector<DrawUnit> units(size_t(1) << k);
    for (size_t v = 0; v < units.size(); ++v) {
      units[v].state = common;
      for (int b = 0; b < k; ++b)
        if ((v >> b) & 1) units[v].state |= 1ull << positions[b];
    }
    std::shuffle(units.begin(), units.end(), rng);
    std::vector<uint32_t> order;
    const DrawSortStats st = sorter.sort(units, DrawSort::Gray, {}, order);
    for (size_t i = 1; i < order.size(); ++i)
      ASSERT_EQ(bitsOf(units[order[i]].state ^ units[order[i - 1]].state), 1) << "step " << i;
    EXPECT_EQ(st.state_changes, units.size() - 1);
    EXPECT_EQ(st.launches, units.size());
    EXPECT_EQ(st.wrap_state_changes, 1u);  // cyclic: last unit to the next frame's first
    EXPECT_EQ(st.set_once_values, common);
  }
}

TEST(DrawSortGray, SwitchesFewerBitsThanNoneOnAverage) {
  double none_total = 0, gray_total = 0;
  int gray_not_worse = 0;
  DrawSorter sorter;
  for (int seed = 0; seed < 100; ++seed) {
    std::mt19937_64 rng(1000 + seed);
    const size_t n = 50 + rng() % 2000;
    const int bits = 2 + int(rng() % 20);
    auto units = randomUnits(rng, n, bits, 1 + int(rng() % 12));
    std::vector<uint32_t> order;
    const auto none = sorter.sort(units, DrawSort::None, {}, order);
    const auto gray = sorter.sort(units, DrawSort::Gray, {}, order);
    none_total += double(none.state_changes);
    gray_total += double(gray.state_changes);
    gray_not_worse += gray.state_changes <= none.state_changes;
    EXPECT_LE(gray.launches, none.launches) << "seed " << seed;
  }
  EXPECT_LT(gray_total / 100, none_total / 100);
  EXPECT_EQ(gray_not_worse, 100);
}

TEST(DrawSortGray, LayoutMustCoverEveryVaryingBit) {
  std::vector<DrawUnit> units(3);
  units[0].state = 1;
  units[1].state = 2;
  std::vector<uint32_t> order;
  GrayLayout layout;
  layout.bits = {0};
  EXPECT_THROW(DrawSorter().sortGray(units, layout, order), Error);
  layout.bits = {1, 0, 5};  // extra bits (shared by all) are harmless
  EXPECT_NO_THROW(DrawSorter().sortGray(units, layout, order));
}

// The queue against a fresh sort of the same units (handle order = input order) with the queue's
// layout, plus the layout = exactly the varying bits.
void expectQueueMatchesFreshSort(const GrayQueue& q, const char* what, int step) {
  const std::vector<GrayQueue::Handle> handles = q.handles();
  std::vector<uint64_t> states;
  for (auto h : handles) states.push_back(q.state(h));
  ASSERT_EQ(q.varyingMask(), varyingStateBits(states)) << what << " at step " << step;
  if (!states.empty()) {
    ASSERT_EQ(q.setOnceValues(), states[0] & ~varyingStateBits(states));
  }
  std::vector<uint32_t> fresh;
  DrawSorter().sortGrayStates(states, q.layout(), fresh);
  std::vector<GrayQueue::Handle> expected;
  for (uint32_t i : fresh) expected.push_back(handles[i]);
  ASSERT_EQ(q.order(), expected) << what << " at step " << step;
}

TEST(DrawSortGrayQueue, PatentHeadAndTailInsertionKeepTheOrder) {
  GrayQueue q;
  q.build({0b00, 0b01, 0b11, 0b10, 0b01});
  EXPECT_EQ(q.order(), (std::vector<GrayQueue::Handle>{0, 1, 4, 2, 3}));  // 00 01 01 11 10
  const auto before = q.order();
  // A unit that brings a new state bit set (others 0): the tail.
  const auto t = q.add(0b100000 | 0b01);
  EXPECT_EQ(q.lastPlacement(), 2);
  auto expected = before;
  expected.push_back(t);
  EXPECT_EQ(q.order(), expected);
  expectQueueMatchesFreshSort(q, "tail add", 0);
  // Every unit now gets bit 7 except the newcomer: the head, the rest in the same order.
  GrayQueue r;
  r.build({0x80 | 0b00, 0x80 | 0b01, 0x80 | 0b11, 0x80 | 0b10});
  const auto before_r = r.order();
  const auto h = r.add(0b11);
  EXPECT_EQ(r.lastPlacement(), 1);
  expected = {h};
  expected.insert(expected.end(), before_r.begin(), before_r.end());
  EXPECT_EQ(r.order(), expected);
  expectQueueMatchesFreshSort(r, "head add", 0);
  // Removing it drops bit 7 again (the shared value is 1): nobody moves.
  r.remove(h);
  EXPECT_EQ(r.order(), before_r);
  EXPECT_EQ(r.varyingMask(), 0b11u);
  EXPECT_EQ(r.setOnceValues(), 0x80u);
  expectQueueMatchesFreshSort(r, "drop", 0);
  // A state change that makes a bit common drops it; one that brings a bit in adds it.
  r.setState(3, 0x80 | 0b00);  // 10 -> 00: bit 1 now only in unit 2
  expectQueueMatchesFreshSort(r, "change", 1);
  r.setState(2, 0x80 | 0b01);  // bit 1 now shared (0): dropped
  EXPECT_EQ(r.varyingMask(), 0b01u);
  expectQueueMatchesFreshSort(r, "change drop", 2);
  r.flipBit(0, 40);  // a new bit: unit 0 alone has it set -> tail
  EXPECT_EQ(r.lastPlacement(), 2);
  EXPECT_EQ(r.order().back(), 0u);
  expectQueueMatchesFreshSort(r, "change add", 3);
}

TEST(DrawSortGrayQueue, EveryIncrementalOperationEqualsAFreshSort) {
  for (uint64_t seed : {1u, 2u, 3u, 4u, 5u, 6u}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    // Mostly a few common bits, sometimes rare ones (which come and go as code bits).
    auto randomState = [&]() {
      uint64_t s = 0x3ull << 60;
      for (int b = 0; b < 6; ++b)
        if (u01(rng) < 0.5) s |= 1ull << b;
      if (u01(rng) < 0.05) s |= 1ull << (10 + rng() % 40);
      if (u01(rng) < 0.03) s &= ~(1ull << (60 + rng() % 2));
      return s;
    };
    GrayQueue q;
    std::vector<uint64_t> initial;
    for (int i = 0; i < 40; ++i) initial.push_back(randomState());
    q.build(initial);
    expectQueueMatchesFreshSort(q, "build", -1);
    int heads = 0, tails = 0, drops = 0, adds = 0;
    for (int step = 0; step < 3000; ++step) {
      const auto handles = q.handles();
      const double r = u01(rng);
      const uint64_t varying_before = q.varyingMask();
      const char* what;
      if (!handles.empty() && r < 0.1) {
        // A unit leaves the consensus on a set-once bit: the patent's head (its bit 0, everyone
        // else 1) or tail (its bit 1) insertion, as a new unit or as a state change.
        const uint64_t ones = q.setOnceValues(), zeros = q.setOnceMask() & ~ones;
        const bool head = u01(rng) < 0.5 && ones;
        uint64_t pool = head ? ones : zeros;
        int pick = int(rng() % bitsOf(pool));
        while (pick--) pool &= pool - 1;
        const uint64_t bit = pool & (~pool + 1);
        const GrayQueue::Handle h = handles[rng() % handles.size()];
        if (u01(rng) < 0.5) {
          q.add(q.state(h) ^ bit);
          what = head ? "add head" : "add tail";
        } else {
          q.setState(h, q.state(h) ^ bit);
          what = head ? "change head" : "change tail";
        }
      } else if (handles.empty() || r < 0.3) {
        q.add(randomState());
        what = "add";
      } else if (r < 0.55 || handles.size() > 120) {
        q.remove(handles[rng() % handles.size()]);
        what = "remove";
      } else if (r < 0.85) {
        q.flipBit(handles[rng() % handles.size()],
                  u01(rng) < 0.8 ? int(rng() % 6) : int(rng() % 64));
        what = "flip";
      } else {
        q.setState(handles[rng() % handles.size()], randomState());
        what = "set";
      }
      heads += q.lastPlacement() == 1;
      tails += q.lastPlacement() == 2;
      drops += bitsOf(varying_before & ~q.varyingMask()) > 0;
      adds += bitsOf(q.varyingMask() & ~varying_before) > 0;
      expectQueueMatchesFreshSort(q, what, step);
      if (HasFatalFailure()) return;
    }
    // The run exercised every kind of layout change.
    EXPECT_GT(heads, 10);
    EXPECT_GT(tails, 10);
    EXPECT_GT(drops, 10);
    EXPECT_GT(adds, 10);
    // A rebuild gives the canonical layout and the same states in canonical Gray order.
    std::vector<uint64_t> states;
    for (auto h : q.handles()) states.push_back(q.state(h));
    GrayQueue fresh;
    fresh.build(states);
    EXPECT_EQ(fresh.layout(), canonicalGrayLayout(varyingStateBits(states)));
  }
}

TEST(DrawSortGrayQueue, QueueIsAGrayOrder) {
  // After incremental changes, consecutive distinct states still differ in few bits: the queue
  // switches no more bits than a fresh canonical sort would on a complete sequence.
  GrayQueue q;
  std::vector<uint64_t> all;
  for (uint64_t v = 0; v < 64; ++v) all.push_back(v);
  q.build(all);
  q.add(0b1100000);  // new bit 6, tail; its other bits equal the last unit's (Gray 63 = 100000)
  q.remove(5);
  q.add(5);  // back in its bucket
  const auto order = q.order();
  int steps_over_one = 0;
  for (size_t i = 1; i < order.size(); ++i)
    steps_over_one += bitsOf(q.state(order[i]) ^ q.state(order[i - 1])) > 1;
  EXPECT_EQ(steps_over_one, 0);
  EXPECT_THROW(q.remove(5), Error);
}

TEST(DrawSortKey, RadixSortEqualsStableSort) {
  std::mt19937_64 rng(9);
  for (size_t n : {0u, 1u, 2u, 255u, 1000u, 70000u}) {
    std::vector<KeyIndex> items(n), scratch;
    std::vector<uint64_t> keys(n);
    for (size_t i = 0; i < n; ++i) {
      // Duplicates, constant digits (skipped passes) and full-width keys.
      keys[i] = (rng() % 3 == 0) ? (rng() & 0xff00ff0000ull) : rng();
      items[i] = {keys[i], uint32_t(i)};
    }
    radixSortKeys(items, scratch);
    const auto expected = stableOrderBy(keys);
    ASSERT_EQ(items.size(), n);
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(items[i].index, expected[i]) << n << " at " << i;
  }
}

TEST(DrawSortKey, KeySortEqualsStableSortByKey) {
  std::mt19937_64 rng(13);
  DrawSorter sorter;
  for (int state_bits : {8, 16, 24}) {  // 24 > kStateBits: dense state ids
    for (size_t n : {10u, 5000u, 80000u}) {
      auto units = randomUnits(rng, n, state_bits, 20);
      for (auto& u : units) u.layer = uint8_t(rng() % 3);
      DrawSortView view{{0, 0, 100}, {0, 0, -1}};
      std::vector<uint64_t> keys;
      sorter.makeSortKeys(units, view, keys);
      std::vector<uint32_t> order;
      sorter.sortKey(units, view, order);
      ASSERT_EQ(order, stableOrderBy(keys)) << state_bits << " bits, " << n;
      // Identical states are one run within a layer and transparency class.
      const DrawSortStats st = measureDrawOrder(units, order);
      std::set<std::tuple<int, bool, uint64_t>> classes;
      for (const auto& u : units) classes.insert({u.layer, u.transparent, u.state});
      EXPECT_LE(st.launches, classes.size());
    }
  }
}

TEST(DrawSortKey, FieldsPackInOrder) {
  using namespace sort_key;
  const uint64_t k = pack(3, 1, 0xABCDE, 0x1234, 0x89ABCD);
  EXPECT_EQ(field(k, kLayerShift, kLayerBits), 3u);
  EXPECT_EQ(field(k, kTranslucentShift, kTranslucentBits), 1u);
  EXPECT_EQ(field(k, kStateShift, kStateBits), 0xABCDEu);
  EXPECT_EQ(field(k, kMaterialShift, kMaterialBits), 0x1234u);
  EXPECT_EQ(field(k, kDepthShift, kDepthBits), 0x89ABCDu);
  // Layer outranks everything, then opaque before transparent, then state, material, depth.
  EXPECT_LT(pack(0, 1, 0xFFFFF, 0x7FFF, 0xFFFFFF), pack(1, 0, 0, 0, 0));
  EXPECT_LT(pack(0, 0, 0xFFFFF, 0x7FFF, 0xFFFFFF), pack(0, 1, 0, 0, 0));
  EXPECT_LT(pack(0, 0, 1, 0x7FFF, 0xFFFFFF), pack(0, 0, 2, 0, 0));
  EXPECT_LT(pack(0, 0, 1, 1, 0xFFFFFF), pack(0, 0, 1, 2, 0));
  for (float a : {-1e6f, -3.5f, -0.0f, 0.0f, 1e-3f, 2.0f, 7.25f, 1e6f})
    for (float b : {-1e6f, -3.5f, 0.0f, 1e-3f, 2.0f, 7.25f, 1e6f})
      if (a < b) {
        EXPECT_LE(quantizeDepth(a), quantizeDepth(b)) << a << " " << b;
      }
  EXPECT_LT(quantizeDepth(1.0f), quantizeDepth(2.0f));
}

TEST(DrawSortCounters, CountSwitchedBitsLaunchesAndMaterials) {
  std::vector<DrawUnit> units(5);
  const uint64_t states[] = {0b0011, 0b0011, 0b0110, 0b0111, 0b1000};
  const uint32_t mats[] = {0, 1, 1, 2, 2};
  for (int i = 0; i < 5; ++i) {
    units[i].state = states[i] | (1ull << 50);
    units[i].material = mats[i];
  }
  const DrawSortStats s = measureDrawOrder(units, {0, 1, 2, 3, 4});
  EXPECT_EQ(s.draw_units, 5u);
  EXPECT_EQ(s.launches, 4u);  // 0011 0011 | 0110 | 0111 | 1000
  EXPECT_EQ(s.state_changes, 0u + 2 + 1 + 4);
  EXPECT_EQ(s.material_changes, 2u);
  EXPECT_EQ(s.wrap_state_changes, 3u);  // 1000 vs 0011
  EXPECT_EQ(s.set_once_values, 1ull << 50);
  EXPECT_EQ(s.set_once_mask, ~0b1111ull);
  std::vector<uint32_t> order;
  const DrawSortStats none = sortDrawUnits(units, DrawSort::None, {}, order);
  EXPECT_EQ(order, (std::vector<uint32_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(none.state_changes, s.state_changes);
  EXPECT_GE(none.sort_ms, 0.0);
  const DrawSortStats empty = measureDrawOrder({}, {});
  EXPECT_EQ(empty.launches, 0u);
}

}  // namespace
}  // namespace strata
