// Draw-unit sorting: the order in which the renderer issues its draw units decides how
// many launches and state switches a frame costs. Four orders besides the input order:
//   material  units grouped by registered material id (stable), thesis ch. 5;
//   depth     opaque units front to back, then transparent units back to front (view-space depth
//             of each unit's bounding-box centre), thesis ch. 5;
//   gray      the render-state bits that differ between units form a code, read as a reflected
//             Gray code and bucketed by its binary rank in O(N) (patent CN105957132); GrayQueue
//             keeps that order under incremental add / remove / state change;
//   key       a bgfx-style 64-bit packed key, LSD radix-sorted every frame (the peer to compare).
// Counters (state_changes, launches, sort_ms) say what an order costs. No OpenCL here: this header
// is public.
#pragma once

#include <array>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/material_state.h"
#include "strata/strata.h"

namespace strata {

// ---------------------------------------------------------------------------------------------
// Draw units

// A unit's render-state bits are draw_state:: (preprocess/scene/material_state.h); the sorts
// treat the mask as 64 independent two-valued states, as the patent does.
struct DrawUnit {
  uint32_t first_triangle = 0;
  uint32_t triangle_count = 0;
  uint32_t material = 0;   // id from MaterialRegistry
  uint64_t state = 0;      // render-state bits (effect, textured, two-sided, alpha mode, ...)
  glm::vec3 center{0.0f};  // world-space bounding-box centre
  bool transparent = false;
  uint32_t object_id = 0;
  uint8_t layer = 0;  // pass / layer (key sort: most significant field; 0..15)
};

// ---------------------------------------------------------------------------------------------
// Materials: registered once, at creation, in a hash table; ids are dense and stable (the n-th
// distinct description gets id n, forever).

class MaterialRegistry {
 public:
  // Returns the id of `description` (what selects the program: e.g. "effect=pbr;tex=1;alpha=blend";
  // per-material parameters such as a colour should be left out), registering it if new.
  uint32_t registerMaterial(std::string_view description);
  // Same, keyed by a caller-computed hash of the description.
  uint32_t registerMaterial(uint64_t description_hash);
  // Id of a registered description, or -1 (as uint32_t max) if none.
  uint32_t find(std::string_view description) const;
  size_t size() const { return next_id_; }

 private:
  std::unordered_map<std::string, uint32_t> by_description_;
  std::unordered_map<uint64_t, uint32_t> by_hash_;
  uint32_t next_id_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Sort methods

// DrawSort and parseDrawSort ("none", "material", "depth", "gray", "key") are public:
// include/strata/strata.h.
const char* drawSortName(DrawSort sort);
std::vector<std::string> drawSortNames();  // all five, in enum order

// The camera for the depth and key sorts: view-space depth = dot(centre - eye, forward).
struct DrawSortView {
  glm::vec3 eye{0.0f};
  glm::vec3 forward{0.0f, 0.0f, -1.0f};  // need not be normalised
};

struct DrawSortStats {
  uint64_t draw_units = 0;
  uint64_t launches = 0;          // runs of consecutive units with identical state
  uint64_t state_changes = 0;     // sum over consecutive units of popcount(state ^ previous state)
  uint64_t material_changes = 0;  // consecutive units with different material ids
  uint64_t wrap_state_changes = 0;  // popcount(last ^ first): this frame's end to the next's start
  uint64_t set_once_mask = 0;       // state bits shared by every unit (set once, up front)
  uint64_t set_once_values = 0;     // their values
  double sort_ms = 0.0;             // time the sort itself took (wall clock, steady_clock)
};

// Counters of drawing `units` in `order` (indices into units). sort_ms is left 0.
DrawSortStats measureDrawOrder(const std::vector<DrawUnit>& units,
                               const std::vector<uint32_t>& order);

// ---------------------------------------------------------------------------------------------
// Gray-code layout: which state bit each code bit holds, and its polarity. The canonical layout
// (a fresh sort) puts the varying state bits in ascending order, code bit 0 = lowest varying state
// bit, polarity 0. GrayQueue's incremental updates grow their own layout (a new bit always
// becomes the most significant code bit; polarities compensate so that no existing unit moves);
// any layout is a valid Gray order (bit permutations and complements keep Hamming distances).

struct GrayLayout {
  std::vector<uint8_t> bits;  // code bit i (0 = least significant) = state bit bits[i]
  uint64_t polarity = 0;      // code bit i = state bit bits[i] XOR polarity bit i

  uint64_t stateMask() const;           // the state bits the code covers
  uint64_t code(uint64_t state) const;  // the unit's Gray code
  uint64_t rank(uint64_t state) const;  // its binary rank (position in Gray order)
  bool operator==(const GrayLayout& o) const { return bits == o.bits && polarity == o.polarity; }
};

// Binary-reflected Gray code <-> binary.
inline uint64_t grayToBinary(uint64_t g) {
  g ^= g >> 1;
  g ^= g >> 2;
  g ^= g >> 4;
  g ^= g >> 8;
  g ^= g >> 16;
  g ^= g >> 32;
  return g;
}
inline uint64_t binaryToGray(uint64_t b) { return b ^ (b >> 1); }

// Bits on which not all `states` agree.
uint64_t varyingStateBits(const std::vector<uint64_t>& states);
// The canonical layout of a set of units' states.
GrayLayout canonicalGrayLayout(uint64_t varying_mask);

// ---------------------------------------------------------------------------------------------
// bgfx-style packed sort key: [layer 4][translucent 1][state 20][material 15][depth 24].
// State first inside a layer and transparency class, so identical states are one run; depth last
// (front to back for opaque units, back to front for transparent ones: strata composites exactly,
// so transparent units need no depth order, only the state order matters).

namespace sort_key {
inline constexpr int kDepthShift = 0, kDepthBits = 24;
inline constexpr int kMaterialShift = kDepthShift + kDepthBits, kMaterialBits = 15;
inline constexpr int kStateShift = kMaterialShift + kMaterialBits, kStateBits = 20;
inline constexpr int kTranslucentShift = kStateShift + kStateBits, kTranslucentBits = 1;
inline constexpr int kLayerShift = kTranslucentShift + kTranslucentBits, kLayerBits = 4;
static_assert(kLayerShift + kLayerBits == 64, "the key fields fill 64 bits");

constexpr uint64_t fieldMask(int bits) { return bits >= 64 ? ~0ull : (1ull << bits) - 1; }
constexpr uint64_t pack(uint64_t layer, uint64_t translucent, uint64_t state, uint64_t material,
                        uint64_t depth) {
  return ((layer & fieldMask(kLayerBits)) << kLayerShift) |
         ((translucent & fieldMask(kTranslucentBits)) << kTranslucentShift) |
         ((state & fieldMask(kStateBits)) << kStateShift) |
         ((material & fieldMask(kMaterialBits)) << kMaterialShift) |
         ((depth & fieldMask(kDepthBits)) << kDepthShift);
}
constexpr uint64_t field(uint64_t key, int shift, int bits) {
  return (key >> shift) & fieldMask(bits);
}
// Depth as an order-preserving unsigned integer (top kDepthBits of the IEEE float made sortable).
uint32_t quantizeDepth(float depth);
}  // namespace sort_key

// Stable LSD radix sort of (key, index) pairs by key: 8-bit digits below 2^16 entries, 16-bit
// digits above; passes whose digit is the same for every key are skipped.
struct KeyIndex {
  uint64_t key;
  uint32_t index;
};
void radixSortKeys(std::vector<KeyIndex>& items, std::vector<KeyIndex>& scratch);

// ---------------------------------------------------------------------------------------------
// The sorter: owns its scratch buffers so per-frame sorts do not allocate after the first.

class DrawSorter {
 public:
  // Fills `order` (indices into units) and returns the counters, sort_ms included.
  DrawSortStats sort(const std::vector<DrawUnit>& units, DrawSort method, const DrawSortView& view,
                     std::vector<uint32_t>& order);

  // The individual sorts (no timing, no counters).
  void sortNone(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order);
  void sortMaterial(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order);
  void sortDepth(const std::vector<DrawUnit>& units, const DrawSortView& view,
                 std::vector<uint32_t>& order);
  // Canonical layout of the units' varying bits.
  void sortGray(const std::vector<DrawUnit>& units, std::vector<uint32_t>& order);
  // Given layout (must cover every varying bit; throws strata::Error otherwise).
  void sortGray(const std::vector<DrawUnit>& units, const GrayLayout& layout,
                std::vector<uint32_t>& order);
  void sortKey(const std::vector<DrawUnit>& units, const DrawSortView& view,
               std::vector<uint32_t>& order);
  // The keys sortKey sorts by (one per unit, in input order).
  void makeSortKeys(const std::vector<DrawUnit>& units, const DrawSortView& view,
                    std::vector<uint64_t>& keys);

  // Gray order of bare states (indices into states), by rank then input position.
  void sortGrayStates(const std::vector<uint64_t>& states, const GrayLayout& layout,
                      std::vector<uint32_t>& order);

  // Narrow codes go into one bucket per rank. true: the patent's literal bucket array of linked
  // chains (head/tail per rank, next per unit); false (default): the same buckets laid out
  // contiguously by a counting pass (same order, no pointer chasing: faster at 10^5+ units).
  bool gray_chained_buckets = false;

 private:
  template <class StateOf>
  void grayBuckets(size_t n, const StateOf& state_of, const GrayLayout& layout,
                   std::vector<uint32_t>& order);

  std::vector<uint64_t> ranks_;
  std::vector<uint32_t> head_, tail_, next_, counts_;
  std::vector<KeyIndex> items_, scratch_;
};

// One-shot convenience wrapper.
DrawSortStats sortDrawUnits(const std::vector<DrawUnit>& units, DrawSort method,
                            const DrawSortView& view, std::vector<uint32_t>& order);

// ---------------------------------------------------------------------------------------------
// The patent's incremental queue: units kept in Gray order under add, remove and state change,
// without re-sorting. The layout always covers exactly the bits on which the current units
// differ: a bit a new or changed unit brings in becomes the most significant code bit, the unit
// going to the head of the queue (its new bit 0, everyone else 1) or the tail (its bit 1), and the
// other units keep their order; a bit that all units come to share is dropped (cleared, higher
// code bits shifted down, the polarity of the code bit below it flipped if the shared value was 1
// so no unit moves). Invariant, checked by the tests: order() equals a fresh
// DrawSorter::sortGrayStates(states in handle order, layout()) of the same units.
//
// Cost: an add / remove / change that keeps the set of varying bits is O(log N); one that adds or
// drops a bit also refreshes every unit's cached rank (O(N), no comparisons, no moves).

class GrayQueue {
 public:
  using Handle = uint32_t;

  GrayQueue();
  GrayQueue(const GrayQueue&) = delete;  // the ordering functor points at its queue
  GrayQueue& operator=(const GrayQueue&) = delete;
  // Replaces the contents by `states` (handles 0..n-1) with the canonical layout.
  void build(const std::vector<uint64_t>& states);

  Handle add(uint64_t state);
  void remove(Handle h);
  void setState(Handle h, uint64_t state);  // any number of bits may change
  void flipBit(Handle h, int bit) { setState(h, state(h) ^ (1ull << bit)); }

  bool contains(Handle h) const { return h < alive_.size() && alive_[h]; }
  uint64_t state(Handle h) const { return states_[h]; }
  size_t size() const { return queue_.size(); }
  const GrayLayout& layout() const { return layout_; }
  uint64_t varyingMask() const { return layout_.stateMask(); }
  uint64_t setOnceMask() const { return ~varyingMask(); }
  uint64_t setOnceValues() const;  // values of the set-once bits (0 when empty)

  std::vector<Handle> order() const;    // handles in queue order
  std::vector<Handle> handles() const;  // live handles, ascending
  // How the last operation placed its unit: 0 = in its bucket, 1 = head (new bit), 2 = tail.
  int lastPlacement() const { return last_placement_; }
  uint64_t rankRefreshes() const { return rank_refreshes_; }

 private:
  struct ByRank {
    const GrayQueue* q;
    bool operator()(Handle a, Handle b) const {
      return q->ranks_[a] != q->ranks_[b] ? q->ranks_[a] < q->ranks_[b] : a < b;
    }
  };
  void count(uint64_t state, int delta);
  uint64_t varyingNow() const;  // from the per-bit counts
  void addBitAtTop(int bit, uint64_t newcomer_state);
  void dropBit(int bit);
  void refreshRanks();

  GrayLayout layout_;
  std::vector<uint64_t> states_, ranks_;
  std::vector<uint8_t> alive_;
  std::array<uint32_t, 64> ones_{};  // live units with each state bit set
  uint32_t live_ = 0;
  std::set<Handle, ByRank> queue_;
  int last_placement_ = 0;
  uint64_t rank_refreshes_ = 0;
};

}  // namespace strata
