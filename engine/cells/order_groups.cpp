// The cells order's groups (order_groups.h): a compressed-row graph of the constraints, its
// ranks by Kahn's algorithm, and its strongly connected components where a cycle stops them.
#include "engine/cells/order_groups.h"

#include <algorithm>
#include <cstring>
#include <queue>

namespace strata::cellorder {

namespace {

// A directed graph in compressed rows: the successors of n are out[first[n] .. first[n + 1]).
struct Graph {
  std::vector<uint32_t> first, out;
  uint32_t size() const { return uint32_t(first.size() - 1); }
};

// Adjacency by a counting sort on the source, over the edges forEachEdge(f) passes to f(a, b)
// (twice, in the same order); edges inside one node are dropped (duplicates are harmless to the
// users below).
template <typename ForEachEdge>
Graph makeGraph(uint32_t nodes, ForEachEdge forEachEdge) {
  Graph g;
  g.first.assign(nodes + 1, 0);
  forEachEdge([&](uint32_t a, uint32_t b) {
    if (a != b) ++g.first[a + 1];
  });
  for (uint32_t n = 0; n < nodes; ++n) g.first[n + 1] += g.first[n];
  g.out.resize(g.first[nodes]);
  std::vector<uint32_t> cursor(g.first.begin(), g.first.end() - 1);
  forEachEdge([&](uint32_t a, uint32_t b) {
    if (a != b) g.out[cursor[a]++] = b;
  });
  return g;
}

// Strongly connected components (iterative Tarjan) of the nodes reachable from the roots
// (nodes n with root[n] set): their component, numbered in reverse topological order of the
// condensed graph; UINT32_MAX for the others.
std::vector<uint32_t> stronglyConnectedComponents(const Graph& g, const std::vector<char>& root,
                                                  uint32_t* count) {
  const uint32_t nodes = g.size();
  std::vector<uint32_t> comp(nodes, UINT32_MAX), index(nodes, UINT32_MAX), low(nodes, 0);
  std::vector<uint32_t> stack, call, edge_at(nodes, 0);
  std::vector<char> on_stack(nodes, 0);
  uint32_t next_index = 0, comps = 0;
  auto visit = [&](uint32_t n) {
    index[n] = low[n] = next_index++;
    edge_at[n] = g.first[n];
    stack.push_back(n);
    on_stack[n] = 1;
    call.push_back(n);
  };
  for (uint32_t r = 0; r < nodes; ++r) {
    if (!root[r] || index[r] != UINT32_MAX) continue;
    visit(r);
    while (!call.empty()) {
      const uint32_t n = call.back();
      if (edge_at[n] < g.first[n + 1]) {
        const uint32_t m = g.out[edge_at[n]++];
        if (index[m] == UINT32_MAX)
          visit(m);
        else if (on_stack[m])
          low[n] = std::min(low[n], index[m]);
        continue;
      }
      call.pop_back();
      if (!call.empty()) low[call.back()] = std::min(low[call.back()], low[n]);
      if (low[n] == index[n]) {
        uint32_t m;
        do {
          m = stack.back();
          stack.pop_back();
          on_stack[m] = 0;
          comp[m] = comps;
        } while (m != n);
        ++comps;
      }
    }
  }
  *count = comps;
  return comp;
}

// Kahn's algorithm, the free node of least key first (ties: the lower index): the rank of every
// node it reaches, and how many those are; when a cycle leaves nodes that never come free, they
// keep rank UINT32_MAX (and so does every node after one of them). Nodes are walked in key
// order (a radix sort); a heap holds only the nodes that come free after the walk has passed
// them, so a graph whose constraints mostly agree with the keys costs little more than the sort.
// `level` (per node, lower bounds on entry) is raised along the edges of every ranked node: a
// ranked node's level ends one above its highest ranked predecessor's (or at its bound).
uint32_t topologicalRanks(const Graph& g, const std::vector<float>& key,
                          std::vector<uint32_t>& rank, std::vector<uint32_t>& level) {
  const uint32_t n = g.size();
  // Order-preserving unsigned images of the keys, sorted (many: by three stable passes of 11,
  // 11 and 10 bits, whose counts stay in the first-level cache).
  std::vector<uint32_t> bits(n), by_key(n), pos(n);
  for (uint32_t i = 0; i < n; ++i) {
    uint32_t u;
    std::memcpy(&u, &key[i], sizeof(u));
    bits[i] = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
  }
  std::iota(by_key.begin(), by_key.end(), 0u);
  if (n < 8192) {
    std::sort(by_key.begin(), by_key.end(), [&](uint32_t a, uint32_t b) {
      return bits[a] < bits[b] || (bits[a] == bits[b] && a < b);
    });
  } else {
    std::vector<uint32_t> tmp(n), counts(2049);
    for (int shift : {0, 11, 22}) {
      std::fill(counts.begin(), counts.end(), 0u);
      for (uint32_t i : by_key) ++counts[((bits[i] >> shift) & 0x7FFu) + 1];
      for (size_t b = 1; b < counts.size(); ++b) counts[b] += counts[b - 1];
      for (uint32_t i : by_key) tmp[counts[(bits[i] >> shift) & 0x7FFu]++] = i;
      by_key.swap(tmp);
    }
  }
  for (uint32_t p = 0; p < n; ++p) pos[by_key[p]] = p;

  std::vector<uint32_t> indeg(n, 0);
  for (uint32_t m : g.out) ++indeg[m];
  std::priority_queue<uint32_t, std::vector<uint32_t>, std::greater<uint32_t>> late;  // positions
  rank.assign(n, UINT32_MAX);
  uint32_t scan = 0;
  for (uint32_t next = 0; next < n; ++next) {
    while (scan < n && indeg[by_key[scan]] != 0) ++scan;  // passed: pushed on coming free
    uint32_t c;
    if (!late.empty() && (scan == n || late.top() < scan)) {
      c = by_key[late.top()];
      late.pop();
    } else if (scan < n) {
      c = by_key[scan++];
    } else {
      return next;  // every node left waits on another: a cycle
    }
    rank[c] = next;
    const uint32_t above = level[c] + 1;
    for (uint32_t k = g.first[c]; k < g.first[c + 1]; ++k) {
      const uint32_t m = g.out[k];
      level[m] = std::max(level[m], above);
      if (--indeg[m] == 0 && pos[m] < scan) late.push(pos[m]);
    }
  }
  return n;
}

// The nodes Kahn's algorithm left waiting on a cycle (group_of UINT32_MAX), after the `ranked`
// ones: their cycles merged (strongly connected components) and the condensed graph of those
// nodes ordered in turn; each component starts from the highest level bound its nodes received.
// Returns the group count.
uint32_t rankCycles(const Graph& graph, const std::vector<float>& node_z,
                    const std::vector<uint32_t>& node_level, uint32_t ranked,
                    std::vector<uint32_t>& group_of, std::vector<uint32_t>& group_level) {
  const uint32_t nodes = graph.size();
  std::vector<char> waiting(nodes);
  for (uint32_t n = 0; n < nodes; ++n) waiting[n] = group_of[n] == UINT32_MAX;
  uint32_t comps = 0;
  std::vector<uint32_t> comp = stronglyConnectedComponents(graph, waiting, &comps);
  // Components numbered by their first node, not by the search's path through the edges, so
  // that the order depends on the constraints found, not on the order they were found in.
  {
    std::vector<uint32_t> renumber(comps, UINT32_MAX);
    uint32_t next = 0;
    for (uint32_t n = 0; n < nodes; ++n)
      if (waiting[n] && renumber[comp[n]] == UINT32_MAX) renumber[comp[n]] = next++;
    for (uint32_t n = 0; n < nodes; ++n)
      if (waiting[n]) comp[n] = renumber[comp[n]];
  }
  std::vector<float> comp_z(comps, 1e30f);
  std::vector<uint32_t> comp_rank, comp_level(comps, 0);
  for (uint32_t n = 0; n < nodes; ++n) {
    if (!waiting[n]) continue;
    comp_z[comp[n]] = std::min(comp_z[comp[n]], node_z[n]);
    comp_level[comp[n]] = std::max(comp_level[comp[n]], node_level[n]);
  }
  const Graph condensed = makeGraph(comps, [&](auto add) {
    for (uint32_t n = 0; n < nodes; ++n)
      if (waiting[n])
        for (uint32_t k = graph.first[n]; k < graph.first[n + 1]; ++k)
          add(comp[n], comp[graph.out[k]]);
  });
  topologicalRanks(condensed, comp_z, comp_rank, comp_level);
  for (uint32_t n = 0; n < nodes; ++n)
    if (waiting[n]) group_of[n] = ranked + comp_rank[comp[n]];
  for (uint32_t c = 0; c < comps; ++c) group_level[ranked + comp_rank[c]] = comp_level[c];
  return ranked + comps;
}

}  // namespace

NodeOrder orderConstrained(const std::vector<ScreenExtent>& ext,
                           const std::vector<Constraints>& found, bool list_overlaps,
                           uint64_t* pairs_tested, uint64_t* merged_pairs) {
  const uint32_t count = uint32_t(ext.size());
  UnionFind merged(count);
  for (const Constraints& f : found) {
    *pairs_tested += f.pairs;
    *merged_pairs += f.merges.size();
    for (auto [u, v] : f.merges) merged.unite(u, v);
  }

  // Nodes of the constraint graph: the merged sets of visible nodes.
  std::vector<uint32_t> node_of(count, UINT32_MAX);
  uint32_t nodes = 0;
  for (uint32_t g = 0; g < count; ++g) {
    if (!ext[g].visible()) continue;
    const uint32_t r = merged.find(g);
    if (node_of[r] == UINT32_MAX) node_of[r] = nodes++;
    node_of[g] = node_of[r];
  }
  // The graph between them, straight from the threads' lists.
  const Graph graph = makeGraph(nodes, [&](auto add) {
    for (const Constraints& f : found)
      for (auto [a, b] : f.edges) add(node_of[a], node_of[b]);
  });
  std::vector<float> node_z(nodes, 1e30f);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX) node_z[node_of[g]] = std::min(node_z[node_of[g]], ext[g].zmin);

  // Usually the constraints have no cycle and the nodes are the groups, in Kahn's order.
  // Otherwise Kahn's algorithm stops with the nodes that wait on a cycle: no edge leads from
  // them back to a ranked node (it would have kept that node waiting), so they come after the
  // ranked ones, their cycles merged (strongly connected components) and the condensed graph
  // of those nodes ordered in turn.
  // Levels ride along: every edge between two groups leads to a later group (Kahn's ranks,
  // then the condensed cycles after them, to which no edge leads back), so each node's level is
  // final when Kahn's algorithm reaches it, and a condensed cycle starts from the highest
  // bound its nodes received.
  std::vector<uint32_t> group_of, node_level(nodes, 0), group_level;
  const uint32_t ranked = topologicalRanks(graph, node_z, group_of, node_level);
  uint32_t groups = ranked;
  group_level.resize(nodes);
  for (uint32_t n = 0; n < nodes; ++n)
    if (group_of[n] != UINT32_MAX) group_level[group_of[n]] = node_level[n];
  if (ranked < nodes) groups = rankCycles(graph, node_z, node_level, ranked, group_of, group_level);
  group_level.resize(groups);

  // Groups in order (a counting sort), then each invisible node as a group of its own.
  NodeOrder result;
  result.group_first.assign(groups + 1, 0);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX) ++result.group_first[group_of[node_of[g]] + 1];
  for (uint32_t r = 0; r < groups; ++r) result.group_first[r + 1] += result.group_first[r];
  result.members.resize(result.group_first[groups]);
  std::vector<uint32_t> cursor(result.group_first.begin(), result.group_first.end() - 1);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX) result.members[cursor[group_of[node_of[g]]]++] = g;
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] == UINT32_MAX) {
      result.members.push_back(g);
      result.group_first.push_back(uint32_t(result.members.size()));
    }
  // Invisible nodes come last, each a group of its own at level 0.
  result.level = std::move(group_level);
  result.level.resize(result.groupCount(), 0);
  if (list_overlaps)
    for (uint32_t n = 0; n < nodes; ++n)
      for (uint32_t k = graph.first[n]; k < graph.first[n + 1]; ++k)
        if (group_of[n] != group_of[graph.out[k]])
          result.overlaps.emplace_back(group_of[n], group_of[graph.out[k]]);
  return result;
}

int64_t assignPasses(const NodeOrder& order, int64_t base, std::vector<int64_t>& pass) {
  pass.resize(order.groupCount());
  int64_t last = base - 1;
  for (uint32_t g = 0; g < order.groupCount(); ++g) {
    pass[g] = base + int64_t(order.level[g]);
    last = std::max(last, pass[g]);
  }
  return last;
}

}  // namespace strata::cellorder
