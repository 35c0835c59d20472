#include "engine/features/draw_sort.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>

#include "preprocess/scene/scene.h"

namespace strata {
namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

int lowestBit(uint64_t m) { return __builtin_ctzll(m); }
int popcount(uint64_t m) { return __builtin_popcountll(m); }
uint64_t lowMask(int bits) { return bits >= 64 ? ~0ull : (1ull << bits) - 1; }

std::string hex(uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%llx", static_cast<unsigned long long>(v));
  return buf;
}

// An affine map over GF(2) from a 64-bit state to a 64-bit value, evaluated a byte at a time:
// value = constant XOR (XOR over set state bits b of contribution[b]). Compacting the varying
// bits, permuting them into a Gray layout and converting Gray to binary are all such maps, so a
// unit's rank costs one table look-up per state byte that matters.
class ByteMap {
 public:
  void build(const uint64_t (&contribution)[64], uint64_t constant) {
    constant_ = constant;
    active_count_ = 0;
    for (int j = 0; j < 8; ++j) {
      bool any = false;
      for (int k = 0; k < 8; ++k) any |= contribution[8 * j + k] != 0;
      if (!any) continue;
      active_[active_count_++] = j;
      uint64_t* t = table_[j];
      t[0] = 0;
      for (int v = 1; v < 256; ++v) t[v] = t[v & (v - 1)] ^ contribution[8 * j + __builtin_ctz(v)];
    }
  }
  uint64_t operator()(uint64_t s) const {
    uint64_t r = constant_;
    for (int a = 0; a < active_count_; ++a) {
      const int j = active_[a];
      r ^= table_[j][(s >> (8 * j)) & 0xff];
    }
    return r;
  }

 private:
  uint64_t table_[8][256];
  int active_[8] = {};
  int active_count_ = 0;
  uint64_t constant_ = 0;
};

// Rank in Gray order under `layout`: code bit i contributes gray_to_binary(1 << i) = bits i..0.
void buildRankMap(const GrayLayout& layout, ByteMap& map) {
  uint64_t contribution[64] = {};
  for (size_t i = 0; i < layout.bits.size(); ++i)
    contribution[layout.bits[i]] = lowMask(int(i) + 1);
  map.build(contribution, grayToBinary(layout.polarity));
}

uint64_t removeBit(uint64_t v, int p) {
  const uint64_t below = v & lowMask(p);
  const uint64_t above = p >= 63 ? 0 : (v >> (p + 1)) << p;
  return below | above;
}

template <int kDigitBits>
void radixPasses(std::vector<KeyIndex>& items, std::vector<KeyIndex>& scratch) {
  constexpr int kBuckets = 1 << kDigitBits;
  constexpr int kPasses = (64 + kDigitBits - 1) / kDigitBits;
  const size_t n = items.size();
  static thread_local std::vector<uint32_t> hist;
  hist.assign(size_t(kPasses) * kBuckets, 0);
  uint64_t all_or = 0, all_and = ~0ull;
  for (const KeyIndex& it : items) {
    all_or |= it.key;
    all_and &= it.key;
    for (int p = 0; p < kPasses; ++p)
      ++hist[size_t(p) * kBuckets + ((it.key >> (p * kDigitBits)) & (kBuckets - 1))];
  }
  const uint64_t varying = all_or ^ all_and;
  scratch.resize(n);
  KeyIndex* src = items.data();
  KeyIndex* dst = scratch.data();
  for (int p = 0; p < kPasses; ++p) {
    const int shift = p * kDigitBits;
    if (((varying >> shift) & (kBuckets - 1)) == 0) continue;  // every key has this digit
    uint32_t* h = &hist[size_t(p) * kBuckets];
    uint32_t sum = 0;
    for (int b = 0; b < kBuckets; ++b) {
      const uint32_t c = h[b];
      h[b] = sum;
      sum += c;
    }
    for (size_t i = 0; i < n; ++i) dst[h[(src[i].key >> shift) & (kBuckets - 1)]++] = src[i];
    std::swap(src, dst);
  }
  if (src != items.data()) items.swap(scratch);
}

double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// ---------------------------------------------------------------------------------------------

uint32_t MaterialRegistry::registerMaterial(std::string_view description) {
  auto [it, inserted] = by_description_.try_emplace(std::string(description), next_id_);
  if (inserted) ++next_id_;
  return it->second;
}

uint32_t MaterialRegistry::registerMaterial(uint64_t description_hash) {
  auto [it, inserted] = by_hash_.try_emplace(description_hash, next_id_);
  if (inserted) ++next_id_;
  return it->second;
}

uint32_t MaterialRegistry::find(std::string_view description) const {
  auto it = by_description_.find(std::string(description));
  return it == by_description_.end() ? kNone : it->second;
}

// ---------------------------------------------------------------------------------------------

static const char* const kSortNames[] = {"none", "material", "depth", "gray", "key"};

DrawSort parseDrawSort(const std::string& name) {
  for (int i = 0; i < 5; ++i)
    if (name == kSortNames[i]) return DrawSort(i);
  throw Error("unknown draw sort '" + std::string(name) +
              "' (expected none, material, depth, gray or key)");
}

const char* drawSortName(DrawSort sort) {
  const int i = int(sort);
  return i >= 0 && i < 5 ? kSortNames[i] : "?";
}

const char* optionName(DrawSort value) { return drawSortName(value); }

std::vector<std::string> drawSortNames() { return {std::begin(kSortNames), std::end(kSortNames)}; }

DrawSortStats measureDrawOrder(const std::vector<DrawUnit>& units,
                               const std::vector<uint32_t>& order) {
  DrawSortStats s;
  s.draw_units = order.size();
  uint64_t all_or = 0, all_and = ~0ull;
  for (const DrawUnit& u : units) {
    all_or |= u.state;
    all_and &= u.state;
  }
  s.set_once_mask = units.empty() ? 0 : ~(all_or ^ all_and);
  s.set_once_values = all_and & s.set_once_mask;
  for (size_t i = 0; i < order.size(); ++i) {
    const DrawUnit& u = units[order[i]];
    if (i == 0) {
      s.launches = 1;
      continue;
    }
    const DrawUnit& prev = units[order[i - 1]];
    const uint64_t diff = u.state ^ prev.state;
    s.state_changes += popcount(diff);
    s.launches += diff != 0;
    s.material_changes += u.material != prev.material;
  }
  if (order.size() > 1)
    s.wrap_state_changes = popcount(units[order.front()].state ^ units[order.back()].state);
  return s;
}

// ---------------------------------------------------------------------------------------------

uint64_t GrayLayout::stateMask() const {
  uint64_t m = 0;
  for (uint8_t b : bits) m |= 1ull << b;
  return m;
}

uint64_t GrayLayout::code(uint64_t state) const {
  uint64_t c = 0;
  for (size_t i = 0; i < bits.size(); ++i) c |= ((state >> bits[i]) & 1ull) << i;
  return c ^ polarity;
}

uint64_t GrayLayout::rank(uint64_t state) const { return grayToBinary(code(state)); }

uint64_t varyingStateBits(const std::vector<uint64_t>& states) {
  uint64_t all_or = 0, all_and = ~0ull;
  for (uint64_t s : states) {
    all_or |= s;
    all_and &= s;
  }
  return states.empty() ? 0 : all_or ^ all_and;
}

GrayLayout canonicalGrayLayout(uint64_t varying_mask) {
  GrayLayout l;
  for (uint64_t m = varying_mask; m; m &= m - 1) l.bits.push_back(uint8_t(lowestBit(m)));
  return l;
}

uint32_t sort_key::quantizeDepth(float depth) {
  uint32_t u;
  std::memcpy(&u, &depth, sizeof u);
  u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);  // order-preserving for every float but NaN
  return u >> (32 - kDepthBits);
}

void radixSortKeys(std::vector<KeyIndex>& items, std::vector<KeyIndex>& scratch) {
  if (items.size() < 2) return;
  if (items.size() < (1u << 16))
    radixPasses<8>(items, scratch);
  else
    radixPasses<16>(items, scratch);
}

// ---------------------------------------------------------------------------------------------

void DrawSorter::sortNone(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order) {
  order.resize(units.size());
  for (size_t i = 0; i < units.size(); ++i) order[i] = uint32_t(i);
}

void DrawSorter::sortMaterial(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order) {
  const size_t n = units.size();
  order.resize(n);
  uint32_t max_id = 0;
  for (const DrawUnit& u : units) max_id = std::max(max_id, u.material);
  if (size_t(max_id) < 4 * n + 256) {
    // Registry ids are dense: one counting pass, stable.
    counts_.assign(size_t(max_id) + 2, 0);
    for (const DrawUnit& u : units) ++counts_[u.material + 1];
    for (size_t b = 1; b < counts_.size(); ++b) counts_[b] += counts_[b - 1];
    for (size_t i = 0; i < n; ++i) order[counts_[units[i].material]++] = uint32_t(i);
    return;
  }
  items_.resize(n);
  for (size_t i = 0; i < n; ++i) items_[i] = {units[i].material, uint32_t(i)};
  radixSortKeys(items_, scratch_);
  for (size_t i = 0; i < n; ++i) order[i] = items_[i].index;
}

void DrawSorter::sortDepth(const std::vector<DrawUnit>& units, const DrawSortView& view,
                           std::vector<uint32_t>& order) {
  const size_t n = units.size();
  items_.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const DrawUnit& u = units[i];
    const float d = glm::dot(u.center - view.eye, view.forward);
    uint32_t q;
    std::memcpy(&q, &d, sizeof q);
    q = (q & 0x80000000u) ? ~q : (q | 0x80000000u);
    if (u.transparent) q = ~q;  // back to front
    items_[i] = {(uint64_t(u.transparent) << 32) | q, uint32_t(i)};
  }
  radixSortKeys(items_, scratch_);
  order.resize(n);
  for (size_t i = 0; i < n; ++i) order[i] = items_[i].index;
}

namespace {
template <class Units>
uint64_t varyingOf(const Units& units, size_t n) {
  uint64_t all_or = 0, all_and = ~0ull;
  for (size_t i = 0; i < n; ++i) {
    all_or |= units(i);
    all_and &= units(i);
  }
  return n ? all_or ^ all_and : 0;
}
uint64_t unitState(const DrawUnit& u) { return u.state; }
}  // namespace

// The patent's step 4: each unit's Gray code -> binary rank -> bucket; equal codes keep their
// input order; collecting the buckets in rank order gives the queue.
template <class StateOf>
void DrawSorter::grayBuckets(size_t n, const StateOf& state_of, const GrayLayout& layout,
                             std::vector<uint32_t>& order) {
  order.resize(n);
  const int code_bits = int(layout.bits.size());
  if (code_bits == 0 || n < 2) {
    for (size_t i = 0; i < n; ++i) order[i] = uint32_t(i);
    return;
  }
  static thread_local ByteMap rank_of;
  buildRankMap(layout, rank_of);

  if (code_bits <= 24 && (size_t(1) << code_bits) <= std::max<size_t>(4 * n, 256)) {
    // One bucket per rank. O(N + 2^bits).
    const size_t buckets = size_t(1) << code_bits;
    if (gray_chained_buckets) {
      // Literally the patent: bucket array of chain heads; a unit whose bucket is taken is
      // linked after the bucket's last unit.
      head_.assign(buckets, kNone);
      tail_.resize(buckets);
      next_.resize(n);
      for (size_t i = 0; i < n; ++i) {
        const uint64_t r = rank_of(state_of(i));
        next_[i] = kNone;
        if (head_[r] == kNone)
          head_[r] = uint32_t(i);
        else
          next_[tail_[r]] = uint32_t(i);
        tail_[r] = uint32_t(i);
      }
      size_t k = 0;
      for (size_t r = 0; r < buckets; ++r)
        for (uint32_t i = head_[r]; i != kNone; i = next_[i]) order[k++] = i;
      return;
    }
    // The same buckets laid out contiguously (counting sort): each bucket's chain is a run of
    // the output, found by a prefix sum of the bucket sizes. Same order, no pointer chasing.
    counts_.assign(buckets + 1, 0);
    ranks_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      ranks_[i] = rank_of(state_of(i));
      ++counts_[ranks_[i] + 1];
    }
    for (size_t b = 1; b <= buckets; ++b) counts_[b] += counts_[b - 1];
    for (size_t i = 0; i < n; ++i) order[counts_[ranks_[i]]++] = uint32_t(i);
    return;
  }
  // Wide, sparse codes: the same bucketing a digit at a time (LSD radix, stable).
  items_.resize(n);
  for (size_t i = 0; i < n; ++i) items_[i] = {rank_of(state_of(i)), uint32_t(i)};
  radixSortKeys(items_, scratch_);
  for (size_t i = 0; i < n; ++i) order[i] = items_[i].index;
}

void DrawSorter::sortGray(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order) {
  const auto state_of = [&](size_t i) { return unitState(units[i]); };
  grayBuckets(units.size(), state_of, canonicalGrayLayout(varyingOf(state_of, units.size())),
              order);
}

void DrawSorter::sortGray(const std::vector<DrawUnit>& units, const GrayLayout& layout,
                          std::vector<uint32_t>& order) {
  const auto state_of = [&](size_t i) { return unitState(units[i]); };
  const uint64_t uncovered = varyingOf(state_of, units.size()) & ~layout.stateMask();
  if (uncovered)
    throw Error("gray sort: state bits " + hex(uncovered) +
                " differ between units but are not in the layout");
  grayBuckets(units.size(), state_of, layout, order);
}

void DrawSorter::sortGrayStates(const std::vector<uint64_t>& states, const GrayLayout& layout,
                                std::vector<uint32_t>& order) {
  const auto state_of = [&](size_t i) { return states[i]; };
  const uint64_t uncovered = varyingOf(state_of, states.size()) & ~layout.stateMask();
  if (uncovered)
    throw Error("gray sort: state bits " + hex(uncovered) +
                " differ between units but are not in the layout");
  grayBuckets(states.size(), state_of, layout, order);
}

void DrawSorter::makeSortKeys(const std::vector<DrawUnit>& units, const DrawSortView& view,
                              std::vector<uint64_t>& keys) {
  const size_t n = units.size();
  keys.resize(n);
  uint64_t all_or = 0, all_and = ~0ull;
  for (const DrawUnit& u : units) {
    all_or |= u.state;
    all_and &= u.state;
  }
  const uint64_t varying = n ? all_or ^ all_and : 0;
  // The state field: the varying state bits, compacted (binary order), when they fit; otherwise
  // a dense id per distinct state, ids in ascending state order.
  static thread_local ByteMap compact;
  std::unordered_map<uint64_t, uint32_t> dense;
  const bool fits = popcount(varying) <= sort_key::kStateBits;
  if (fits) {
    uint64_t contribution[64] = {};
    int k = 0;
    for (uint64_t m = varying; m; m &= m - 1) contribution[lowestBit(m)] = 1ull << k++;
    compact.build(contribution, 0);
  } else {
    for (const DrawUnit& u : units) dense.emplace(u.state, 0);
    std::vector<uint64_t> distinct;
    distinct.reserve(dense.size());
    for (const auto& kv : dense) distinct.push_back(kv.first);
    std::sort(distinct.begin(), distinct.end());
    for (size_t i = 0; i < distinct.size(); ++i) dense[distinct[i]] = uint32_t(i);
  }
  for (size_t i = 0; i < n; ++i) {
    const DrawUnit& u = units[i];
    const float d = glm::dot(u.center - view.eye, view.forward);
    uint32_t q = sort_key::quantizeDepth(d);
    if (u.transparent) q = uint32_t(sort_key::fieldMask(sort_key::kDepthBits)) - q;
    const uint64_t state = fits ? compact(u.state) : dense.find(u.state)->second;
    keys[i] = sort_key::pack(u.layer, u.transparent, state, u.material, q);
  }
}

void DrawSorter::sortKey(const std::vector<DrawUnit>& units, const DrawSortView& view,
                         std::vector<uint32_t>& order) {
  const size_t n = units.size();
  makeSortKeys(units, view, ranks_);
  items_.resize(n);
  for (size_t i = 0; i < n; ++i) items_[i] = {ranks_[i], uint32_t(i)};
  radixSortKeys(items_, scratch_);
  order.resize(n);
  for (size_t i = 0; i < n; ++i) order[i] = items_[i].index;
}

DrawSortStats DrawSorter::sort(const std::vector<DrawUnit>& units, DrawSort method,
                               const DrawSortView& view, std::vector<uint32_t>& order) {
  const auto t0 = std::chrono::steady_clock::now();
  switch (method) {
    case DrawSort::None:
      sortNone(units, order);
      break;
    case DrawSort::Material:
      sortMaterial(units, order);
      break;
    case DrawSort::Depth:
      sortDepth(units, view, order);
      break;
    case DrawSort::Gray:
      sortGray(units, order);
      break;
    case DrawSort::Key:
      sortKey(units, view, order);
      break;
  }
  const double ms = msSince(t0);
  DrawSortStats s = measureDrawOrder(units, order);
  s.sort_ms = ms;
  return s;
}

DrawSortStats sortDrawUnits(const std::vector<DrawUnit>& units, DrawSort method,
                            const DrawSortView& view, std::vector<uint32_t>& order) {
  DrawSorter sorter;
  return sorter.sort(units, method, view, order);
}

// ---------------------------------------------------------------------------------------------
// GrayQueue

GrayQueue::GrayQueue() : queue_(ByRank{this}) {}

void GrayQueue::build(const std::vector<uint64_t>& states) {
  queue_.clear();
  states_ = states;
  ranks_.assign(states.size(), 0);
  alive_.assign(states.size(), 1);
  ones_.fill(0);
  live_ = 0;
  for (uint64_t s : states) count(s, +1);
  layout_ = canonicalGrayLayout(varyingNow());
  for (size_t i = 0; i < states.size(); ++i) ranks_[i] = layout_.rank(states[i]);
  DrawSorter sorter;
  std::vector<uint32_t> order;
  sorter.sortGrayStates(states_, layout_, order);
  for (uint32_t h : order) queue_.emplace_hint(queue_.end(), h);  // already in order: O(N)
  last_placement_ = 0;
}

void GrayQueue::count(uint64_t state, int delta) {
  for (uint64_t m = state; m; m &= m - 1) ones_[lowestBit(m)] += delta;
  live_ += delta;
}

uint64_t GrayQueue::varyingNow() const {
  uint64_t v = 0;
  for (int b = 0; b < 64; ++b)
    if (ones_[b] != 0 && ones_[b] != live_) v |= 1ull << b;
  return v;
}

uint64_t GrayQueue::setOnceValues() const {
  uint64_t v = 0;
  if (live_ == 0) return 0;
  for (int b = 0; b < 64; ++b)
    if (ones_[b] == live_) v |= 1ull << b;
  return v;
}

// The newcomer differs from every other unit in state bit `bit`; it becomes the new most
// significant code bit n with polarity 0 (the patent's rule). Newcomer bit 1: everyone else has
// code bit n = 0, their ranks are unchanged, and the newcomer ranks above all: tail. Newcomer
// bit 0: everyone else has code bit n = 1, which in a reflected Gray code would reverse their
// order (binary bits n-1..0 all complemented); flipping the polarity of code bit n-1 complements
// them back, so their order is kept and they all rank above the newcomer: head.
void GrayQueue::addBitAtTop(int bit, uint64_t newcomer_state) {
  const int n = int(layout_.bits.size());
  const bool value = (newcomer_state >> bit) & 1ull;
  if (!value && n > 0) layout_.polarity ^= 1ull << (n - 1);
  layout_.bits.push_back(uint8_t(bit));
  last_placement_ = value ? 2 : 1;
}

// Every unit now has the same value in state bit `bit` (code bit p): clear it and shift the
// higher code bits down. If the shared code value was 1, removing it complements binary bits
// p-1..0 of every rank (reversing the order within each group of equal higher bits); flipping the
// polarity of code bit p-1 complements them back, so no unit moves.
void GrayQueue::dropBit(int bit) {
  const auto it = std::find(layout_.bits.begin(), layout_.bits.end(), uint8_t(bit));
  const int p = int(it - layout_.bits.begin());
  const bool state_value = ones_[bit] != 0;
  const bool code_value = state_value ^ bool((layout_.polarity >> p) & 1ull);
  if (code_value && p > 0) layout_.polarity ^= 1ull << (p - 1);
  layout_.bits.erase(it);
  layout_.polarity = removeBit(layout_.polarity, p);
}

void GrayQueue::refreshRanks() {
  ++rank_refreshes_;
  static thread_local ByteMap rank_of;
  buildRankMap(layout_, rank_of);
  for (Handle h : queue_) ranks_[h] = rank_of(states_[h]);
}

GrayQueue::Handle GrayQueue::add(uint64_t state) {
  const Handle h = Handle(states_.size());
  states_.push_back(state);
  ranks_.push_back(0);
  alive_.push_back(1);
  const uint64_t before = layout_.stateMask();
  count(state, +1);
  const uint64_t added = varyingNow() & ~before;
  last_placement_ = 0;
  for (uint64_t m = added; m; m &= m - 1) addBitAtTop(lowestBit(m), state);
  if (added) refreshRanks();
  ranks_[h] = layout_.rank(state);
  queue_.insert(h);
  return h;
}

void GrayQueue::remove(Handle h) {
  if (!contains(h)) throw Error("gray queue: no unit " + std::to_string(h));
  queue_.erase(h);
  alive_[h] = 0;
  const uint64_t before = layout_.stateMask();
  count(states_[h], -1);
  const uint64_t dropped = before & ~varyingNow();
  last_placement_ = 0;
  for (uint64_t m = dropped; m; m &= m - 1) dropBit(lowestBit(m));
  if (dropped) refreshRanks();
}

void GrayQueue::setState(Handle h, uint64_t state) {
  if (!contains(h)) throw Error("gray queue: no unit " + std::to_string(h));
  last_placement_ = 0;
  if (state == states_[h]) return;
  queue_.erase(h);
  const uint64_t before = layout_.stateMask();
  count(states_[h], -1);
  states_[h] = state;
  count(state, +1);
  const uint64_t now = varyingNow();
  const uint64_t dropped = before & ~now, added = now & ~before;
  for (uint64_t m = dropped; m; m &= m - 1) dropBit(lowestBit(m));
  for (uint64_t m = added; m; m &= m - 1) addBitAtTop(lowestBit(m), state);
  if (dropped | added) refreshRanks();
  ranks_[h] = layout_.rank(state);
  queue_.insert(h);
}

std::vector<GrayQueue::Handle> GrayQueue::order() const { return {queue_.begin(), queue_.end()}; }

std::vector<GrayQueue::Handle> GrayQueue::handles() const {
  std::vector<Handle> hs;
  hs.reserve(live_);
  for (size_t h = 0; h < alive_.size(); ++h)
    if (alive_[h]) hs.push_back(Handle(h));
  return hs;
}

}  // namespace strata
