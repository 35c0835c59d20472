// Per-view ordering of convex cells, in two levels: instances (parts) first, then the cells of
// each group of instances whose boxes overlap. Cells of one mesh come from the preprocessing
// (decomposition and the view-independent separating planes of every pair of cells with
// overlapping boxes). For a view, the cells are rasterized into per-tile pixel masks, and every
// two cells that may share a pixel centre get an order from, in turn: disjoint view-depth
// intervals; disjoint boxes (an axis plane); their separating plane (the side the eye is on).
// Pairs with no such relation are merged into one group, and so are cycles (strongly connected
// components); the groups come out in topological order, nearest first.
// The stages, as docs/cells.md names them: the projection (order_projection.h,
// cell_projector.h), the pixel masks (order_masks.h), the pairs (order_pairs.h) and the groups
// (order_groups.h); this file runs them per group of parts and lists the tile segments. The
// scene's cells are built in cell_scene.cpp.
#include "engine/cells/cell_order.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <numeric>
#include <thread>

#include <glm/gtc/matrix_inverse.hpp>

#include "engine/cells/cell_projector.h"
#include "engine/cells/order_groups.h"
#include "engine/cells/order_pairs.h"
#include "engine/cells/order_projection.h"
#include "kernels/strata_shared.h"
#include "preprocess/core/threads.h"

namespace strata {

namespace {
std::atomic<unsigned> order_thread_limit{0};
}  // namespace

void setCellOrderThreads(unsigned threads) { order_thread_limit.store(threads); }

unsigned cellOrderThreads() {
  const unsigned limit = order_thread_limit.load();
  if (limit != 0) return limit;
  // Eight by default: the cores beyond are left to the device's driver and the application.
  return std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
}

namespace {

// The instance level is skipped (every instance ordered cell by cell) from this many visible
// instances, when their screen rectangles make more than this many overlapping pairs per
// instance (each overlapping twice as many others, on average).
constexpr uint32_t kCrowdedParts = 1024;
constexpr uint32_t kCrowdedPairsPerPart = 32;

using namespace cellorder;

ViewGeometry viewGeometryOf(const Camera& camera, int width, int height) {
  ViewGeometry vg;
  vg.view_proj = camera.projectionMatrix(float(width) / float(height)) * camera.viewMatrix();
  vg.eye = camera.eye;
  vg.forward = camera.forward();
  vg.perspective = camera.projection == Projection::Perspective;
  vg.near_distance = camera.near_distance;
  vg.width = width;
  vg.height = height;
  return vg;
}

// The copies of coincident triangles (cells s.cell_leader maps to another) as nodes after the
// paired ones, each with its first cell's extent: a chain from the first cell through its copies
// in triangle order (equal depths, each later than the one before it), and whatever must come
// after the first cell after its last copy; a first cell merged into a group takes its copies
// into the group.
// Returns, per copy node, its first cell's node.
std::vector<uint32_t> addCopies(const CellScene& s, std::vector<Constraints>& found,
                                std::vector<uint32_t>& cells, std::vector<ScreenExtent>& ext) {
  const uint32_t paired = uint32_t(cells.size());
  std::vector<uint32_t> last(paired, UINT32_MAX);  // per paired node: its last copy's node
  std::vector<uint32_t> first_copy(paired, UINT32_MAX);
  std::vector<char> copies_merged(paired, 0);  // its copies already joined to its group
  Constraints chain;
  std::vector<uint32_t> leader_node;
  for (uint32_t i = 0; i < paired; ++i) {
    const uint32_t c = cells[i];
    uint32_t prev = i;
    for (uint32_t f = c + 1; f < s.cellCount() && s.cell_leader[f] == c; ++f) {
      const uint32_t node = uint32_t(cells.size());
      if (first_copy[i] == UINT32_MAX) first_copy[i] = node;
      cells.push_back(f);
      ext.push_back(ext[i]);
      leader_node.push_back(i);
      if (!ext[i].visible()) continue;  // off screen: no constraints, drawn in no pass
      chain.edges.emplace_back(prev, node);
      prev = node;
    }
    if (prev != i) last[i] = prev;
  }
  for (Constraints& f : found) {
    const size_t edges = f.edges.size(), merges = f.merges.size();
    for (size_t k = 0; k < edges; ++k) {
      const auto [a, b] = f.edges[k];
      if (last[a] != UINT32_MAX) f.edges.emplace_back(last[a], b);
    }
    for (size_t k = 0; k < merges; ++k)
      for (uint32_t u : {f.merges[k].first, f.merges[k].second})
        if (last[u] != UINT32_MAX && !copies_merged[u]) {
          copies_merged[u] = 1;
          for (uint32_t n = first_copy[u]; n <= last[u]; ++n) f.merges.emplace_back(u, n);
        }
  }
  found.push_back(std::move(chain));
  return leader_node;
}

// The cells of a group of parts as one merged group in pass `base` (each pixel's fragments
// sorted, exact in any order), where a part's pairs passed the bound. Returns the pass.
int64_t drawAsOneGroup(const CellScene& s, const ViewGeometry& vg,
                       const std::vector<uint32_t>& part_group, int64_t base, DrawnGroups& drawn) {
  DrawnGroup d{base, uint32_t(drawn.cells.size()), 0, glm::ivec4(vg.width, vg.height, -1, -1)};
  for (uint32_t p : part_group) {
    for (uint32_t c = s.part_cell_first[p]; c < s.part_cell_first[p + 1]; ++c)
      drawn.cells.push_back(c);
    const ScreenExtent e = vg.extent(s.part_box[p]);
    if (e.visible())
      d.rect = glm::ivec4(std::min(d.rect.x, e.x0), std::min(d.rect.y, e.y0),
                          std::max(d.rect.z, e.x1), std::max(d.rect.w, e.y1));
  }
  std::sort(drawn.cells.begin() + d.first, drawn.cells.end());
  d.count = uint32_t(drawn.cells.size()) - d.first;
  if (!drawn.every_pass_a_segment && d.rect.x <= d.rect.z)
    drawn.coverRect(d.rect.x, d.rect.y, d.rect.z, d.rect.w, (vg.width + 7) / 8, uint32_t(base));
  drawn.groups.push_back(d);
  return base;
}

// Level 2: orders the cells of one group of parts; their groups start at pass `base`. Returns
// the last pass used.
int64_t orderPartGroupCells(const CellScene& s, const ViewGeometry& vg, CellProjector& projector,
                            const std::vector<uint32_t>& part_group, int64_t base,
                            DrawnGroups& drawn, CellOrder& order) {
  auto clock = std::chrono::steady_clock::now();
  // A part without pairs: every cell of the group in one merged group, in their own order.
  for (uint32_t p : part_group)
    if (s.part_unpaired[p]) return drawAsOneGroup(s, vg, part_group, base, drawn);
  // The cells ordered by their pairs: all but the copies of coincident triangles, which join
  // after the pair search (below).
  std::vector<uint32_t> cells;
  uint32_t copies = 0;
  for (uint32_t p : part_group)
    for (uint32_t c = s.part_cell_first[p]; c < s.part_cell_first[p + 1]; ++c) {
      if (s.isCopy(c))
        ++copies;
      else
        cells.push_back(c);
    }
  const bool alone = cells.size() == 1 && copies == 0;
  std::vector<ScreenExtent> ext(cells.size());
  if (alone)
    ext[0] = vg.extent(s.cell_box[cells[0]]);  // no pairs: its box will do
  else
    projector.projectAll(part_group, cells, ext);
  order.project_ms += lapMs(clock);
  auto relation = [&](uint32_t i, uint32_t j) -> int {
    // Only pairs that may share a pixel centre are asked (projector.sharedPixelPairs). A
    // constraint between cells that do not (neighbours on one sheet of the surface merely
    // touch) would be arbitrary, and arbitrary constraints form cycles that merge groups for
    // nothing.
    const uint32_t a = cells[i], b = cells[j];
    const int z = orderOf(ext[i], ext[j]);
    if (z != 2) return z;
    const int box = vg.boxOrder(s.cell_box[a], s.cell_box[b]);
    if (box != 0) return box;
    const auto first = s.neighbours.begin() + s.neighbour_first[a];
    const auto last = s.neighbours.begin() + s.neighbour_first[a + 1];
    const auto it = std::lower_bound(
        first, last, b, [](const CellNeighbour& x, uint32_t v) { return x.other < v; });
    if (it != last && it->other == b && it->separable) return vg.negativeFirst(it->plane);
    return 2;
  };
  NodeOrder local;
  const uint32_t paired = uint32_t(cells.size());
  std::vector<uint32_t> copy_leader;  // per copy node (after the paired ones): its first's node
  if (alone) {
    local.members = {0};
    local.group_first = {0, 1};
    local.level = {0};
  } else {
    std::vector<Constraints> found = projector.pairs(ext, cells, relation);
    order.pairs_ms += lapMs(clock);
    if (copies > 0) copy_leader = addCopies(s, found, cells, ext);
    local = orderConstrained(ext, found, false, &order.pairs_tested, &order.merged_pairs);
  }
  std::vector<int64_t> pass;
  const int64_t last = assignPasses(local, base, pass);
  if (!drawn.every_pass_a_segment) {  // the tile segments need each cell's coverage and pass
    std::vector<uint32_t> node_pass(cells.size());
    for (uint32_t g = 0; g < local.groupCount(); ++g)
      for (uint32_t k = local.group_first[g]; k < local.group_first[g + 1]; ++k)
        node_pass[local.members[k]] = uint32_t(pass[g]);
    if (alone) {
      if (ext[0].visible())
        drawn.coverRect(ext[0].x0, ext[0].y0, ext[0].x1, ext[0].y1, (vg.width + 7) / 8,
                        node_pass[0]);
    } else {
      projector.addCoverage(ext, paired, node_pass, drawn);
      for (uint32_t i = paired; i < cells.size(); ++i)  // a copy covers its first cell's pixels
        projector.addCoverageOf(copy_leader[i - paired], ext[i], node_pass[i], drawn);
    }
  }
  // No exact reserve here: called once per group of parts, it would copy the lists every time
  // (quadratic in the instances); push_back grows them geometrically.
  for (uint32_t g = 0; g < local.groupCount(); ++g) {
    DrawnGroup d{pass[g], uint32_t(drawn.cells.size()), 0, glm::ivec4(vg.width, vg.height, -1, -1)};
    for (uint32_t k = local.group_first[g]; k < local.group_first[g + 1]; ++k) {
      const uint32_t i = local.members[k];
      drawn.cells.push_back(cells[i]);
      if (!ext[i].visible()) continue;
      d.rect = glm::ivec4(std::min(d.rect.x, ext[i].x0), std::min(d.rect.y, ext[i].y0),
                          std::max(d.rect.z, ext[i].x1), std::max(d.rect.w, ext[i].y1));
    }
    d.count = uint32_t(drawn.cells.size()) - d.first;
    // A merged group's fragments at one depth composite in its cells' order: the cells' own
    // (copies of a triangle after their first, as they were decomposed).
    if (copies > 0 && d.count > 1) std::sort(drawn.cells.begin() + d.first, drawn.cells.end());
    drawn.groups.push_back(d);
  }
  order.graph_ms += lapMs(clock);
  return last;
}

// The passes at which each tile's composite starts a new segment: passes in ascending order
// join the current segment while no centre of the tile is covered by two of its passes.
void tileSegments(std::vector<PassTileCoverage>& coverage, uint32_t tiles, CellOrder& order) {
  // By tile (a counting sort), then by pass inside each tile's short run.
  std::vector<uint32_t> first(tiles + 1, 0);
  for (const PassTileCoverage& c : coverage) ++first[c.tile + 1];
  for (uint32_t t = 0; t < tiles; ++t) first[t + 1] += first[t];
  std::vector<PassTileCoverage> by_tile(coverage.size());
  {
    std::vector<uint32_t> cursor(first.begin(), first.end() - 1);
    for (const PassTileCoverage& c : coverage) by_tile[cursor[c.tile]++] = c;
  }
  // Tiles are independent: rows of tiles are split over threads, each listing its breaks.
  const unsigned threads = coverage.size() < 16384 ? 1u : cellOrderThreads();
  std::vector<uint32_t> range(threads + 1);  // thread w: tiles range[w] .. range[w + 1]
  for (unsigned w = 0; w <= threads; ++w) range[w] = uint32_t(uint64_t(tiles) * w / threads);
  std::vector<std::vector<uint32_t>> breaks(threads);
  std::vector<uint64_t> passes(threads, 0);
  order.tile_break_first.assign(tiles + 1, 0);
  auto work = [&](unsigned w) {
    // The thread's own list and count, stored at the end (breaks[] and passes[] share cache
    // lines between the threads).
    std::vector<uint32_t> mine;
    uint64_t seen = 0;
    for (uint32_t t = range[w]; t < range[w + 1]; ++t) {
      const auto b = by_tile.begin() + first[t], e = by_tile.begin() + first[t + 1];
      std::sort(b, e, [](const PassTileCoverage& x, const PassTileCoverage& y) {
        return x.pass < y.pass;
      });
      uint64_t segment = 0;
      bool started = false;
      for (auto it = b; it != e;) {
        const uint32_t pass = it->pass;
        uint64_t mask = 0;
        for (; it != e && it->pass == pass; ++it) mask |= it->mask;
        ++seen;
        if (!started || (segment & mask)) {
          mine.push_back(pass);
          started = true;
          segment = mask;
        } else {
          segment |= mask;
        }
      }
      order.tile_break_first[t + 1] = uint32_t(mine.size());  // within this thread's list
    }
    breaks[w] = std::move(mine);
    passes[w] = seen;
  };
  runOnPool(threads, work);
  order.tile_breaks.clear();
  order.tile_passes = 0;
  for (unsigned w = 0; w < threads; ++w) {
    const uint32_t base = uint32_t(order.tile_breaks.size());
    for (uint32_t t = range[w]; t < range[w + 1]; ++t) order.tile_break_first[t + 1] += base;
    order.tile_breaks.insert(order.tile_breaks.end(), breaks[w].begin(), breaks[w].end());
    order.tile_passes += passes[w];
  }
}

}  // namespace

CellOrder orderCells(const CellScene& s, const Camera& camera, int width, int height,
                     bool tile_segments, CellMaskDevice* device_masks) {
  auto clock = std::chrono::steady_clock::now();
  const ViewGeometry vg = viewGeometryOf(camera, width, height);
  CellOrder order;
  order.group_first.push_back(0);

  // Level 1: instances (parts). Parts ordered by depth or by a plane between their boxes;
  // parts whose boxes overlap are ordered together, cell by cell, at level 2.
  const uint32_t parts = uint32_t(s.part_box.size());
  std::vector<ScreenExtent> part_ext(parts);
  uint32_t visible = 0;
  for (uint32_t p = 0; p < parts; ++p) {
    part_ext[p] = vg.extent(s.part_box[p]);
    visible += part_ext[p].visible() ? 1 : 0;
  }
  // Many small instances crowding the screen: their rectangles overlap so often (the pairs grow
  // with the square of the instances per pixel, most covering no pixel centre of another) that
  // the instance level costs more than it saves. Then every instance is ordered at level 2, as
  // one group of parts, where only cells sharing a pixel centre are paired.
  const ScreenBins part_bins(part_ext, width, height, 64);
  const uint64_t crowd_limit = uint64_t(kCrowdedPairsPerPart) * visible;
  // (Not with a part past the pair bound, which would take every instance into its one group.)
  order.crowded = visible >= kCrowdedParts && s.unpaired_parts == 0 &&
                  rectOverlapsPast(part_ext, part_bins, crowd_limit);
  NodeOrder part_order;
  if (order.crowded) {
    part_order.members.resize(parts);
    for (uint32_t p = 0; p < parts; ++p) part_order.members[p] = p;
    part_order.group_first = {0, parts};
    part_order.level = {0};
  } else {
    const auto relation = [&](uint32_t a, uint32_t b) {
      const int z = orderOf(part_ext[a], part_ext[b]);
      if (z != 2) return z;
      const int box = vg.boxOrder(s.part_box[a], s.part_box[b]);
      return box != 0 ? box : 2;
    };
    part_order = orderConstrained(part_ext, findConstraints(part_ext, part_bins, relation), true,
                                  &order.pairs_tested, &order.merged_pairs);
  }
  // A group of parts starts after the last pass of every earlier group of parts it overlaps.
  std::vector<int64_t> part_last(part_order.groupCount(), -1);
  std::vector<std::vector<uint32_t>> part_preds(part_order.groupCount());
  for (auto [a, b] : part_order.overlaps) part_preds[b].push_back(a);

  CellProjector projector(s, vg, device_masks);
  DrawnGroups drawn;
  const uint32_t tiles = uint32_t((width + 7) / 8) * uint32_t((height + 7) / 8);
  drawn.whole_tiles_left = size_t(4) * tiles;
  drawn.every_pass_a_segment = !tile_segments;
  std::vector<uint32_t> part_group;
  order.graph_ms += lapMs(clock);
  for (uint32_t pgi = 0; pgi < part_order.groupCount(); ++pgi) {
    int64_t base = 0;
    for (uint32_t prev : part_preds[pgi]) base = std::max(base, part_last[prev] + 1);
    part_group.assign(part_order.members.begin() + part_order.group_first[pgi],
                      part_order.members.begin() + part_order.group_first[pgi + 1]);
    part_last[pgi] = orderPartGroupCells(s, vg, projector, part_group, base, drawn, order);
  }
  clock = std::chrono::steady_clock::now();  // the part groups timed their own steps
  // Pass by pass; inside a pass, in drawing order (a counting sort: passes are few).
  int64_t last_pass = -1;
  for (const DrawnGroup& d : drawn.groups) last_pass = std::max(last_pass, d.pass);
  std::vector<uint32_t> pass_first(size_t(last_pass + 2), 0);
  for (const DrawnGroup& d : drawn.groups) ++pass_first[size_t(d.pass) + 1];
  for (size_t p = 1; p < pass_first.size(); ++p) pass_first[p] += pass_first[p - 1];
  std::vector<uint32_t> by_pass(drawn.groups.size());
  for (uint32_t g = 0; g < drawn.groups.size(); ++g)
    by_pass[pass_first[size_t(drawn.groups[g].pass)]++] = g;
  order.cells.reserve(drawn.cells.size());
  order.group_first.reserve(drawn.groups.size() + 1);
  order.group_pass.reserve(drawn.groups.size());
  order.group_rect.reserve(drawn.groups.size());
  for (uint32_t g : by_pass) {
    const DrawnGroup& d = drawn.groups[g];
    order.cells.insert(order.cells.end(), drawn.cells.begin() + d.first,
                       drawn.cells.begin() + d.first + d.count);
    order.largest_group = std::max(order.largest_group, d.count);
    if (d.count > 1) {
      ++order.merged_groups;
      order.merged_cells += d.count;
    }
    order.group_first.push_back(uint32_t(order.cells.size()));
    order.group_pass.push_back(uint32_t(d.pass));
    order.group_rect.push_back(d.rect);
    order.passes = std::max(order.passes, uint32_t(d.pass + 1));
  }
  order.device_mask_cells = projector.deviceMaskCells();
  order.device_pairs = projector.devicePairs();
  order.device_ms = projector.deviceMs();
  order.graph_ms += lapMs(clock);
  if (!drawn.every_pass_a_segment) tileSegments(drawn.coverage, tiles, order);
  order.segments_ms += lapMs(clock);
  return order;
}

}  // namespace strata
