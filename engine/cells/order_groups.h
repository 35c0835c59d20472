// The cells order's groups (docs/cells.md, "The groups"): the constraints between nodes ordered
// by Kahn's algorithm, cycles merged as strongly connected components, and each group's pass.
// Internal to the order's stages.
#pragma once

#include <cstdint>
#include <numeric>
#include <utility>
#include <vector>

#include "engine/cells/order_pairs.h"
#include "engine/cells/order_projection.h"

namespace strata::cellorder {

// Orders `count` nodes for the view. For every two nodes that may overlap on screen (cells:
// share a pixel centre; parts: screen rectangles overlap), relation(a, b) says +1 (a first), -1
// (b first), 0 (no constraint) or 2 (no order known: draw them as one group). Nodes joined by
// 2 and strongly connected components of the constraints are merged; the merged groups come
// out in topological order, the nearest free one first. Invisible nodes come last.
struct NodeOrder {
  std::vector<uint32_t> members;      // nodes, group by group in drawing order
  std::vector<uint32_t> group_first;  // groupCount() + 1 offsets into members
  // Per group: 0 when it overlaps no earlier group, else one more than the largest level of the
  // earlier groups it overlaps (its pass, counted from the first).
  std::vector<uint32_t> level;
  std::vector<std::pair<uint32_t, uint32_t>> overlaps;  // (earlier, later) groups that overlap,
                                                        // when asked for

  uint32_t groupCount() const { return uint32_t(group_first.size() - 1); }
};

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  bool unite(uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (a > b) std::swap(a, b);
    parent[b] = a;
    return true;
  }
};

// Orders nodes from the constraints found between them (by one or more threads, in any order:
// the result depends on the set of constraints only).
NodeOrder orderConstrained(const std::vector<ScreenExtent>& ext,
                           const std::vector<Constraints>& found, bool list_overlaps,
                           uint64_t* pairs_tested, uint64_t* merged_pairs);

// Passes of groups in drawing order: a group's pass is one more than that of every earlier
// group it overlaps (at least `base`). Returns the last pass used (base - 1 if none).
int64_t assignPasses(const NodeOrder& order, int64_t base, std::vector<int64_t>& pass);

}  // namespace strata::cellorder
