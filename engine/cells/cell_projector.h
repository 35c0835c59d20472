// The cells order's projection of a group of parts (docs/cells.md, "Which pairs need an
// order"): the scene's vertices projected once per view, each cell's screen rectangle, depth
// range and pixel masks, and the pairs of cells that share a pixel centre. Internal to the
// order's stages (engine/cells/cell_order.cpp).
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "engine/cells/cell_order.h"
#include "engine/cells/order_groups.h"
#include "engine/cells/order_masks.h"
#include "engine/cells/order_pairs.h"
#include "engine/cells/order_projection.h"
#include "preprocess/core/threads.h"

namespace strata::cellorder {

// Internal linkage, as for code of the one file that includes this (cell_order.cpp): the
// compiler then inlines the per-triangle steps as it does a file's own static functions.
namespace {

// A group of cells in drawing order with its pass and the pixels it may cover.
struct DrawnGroup {
  int64_t pass;
  uint32_t first, count;  // its cells in DrawnGroups::cells
  glm::ivec4 rect;
};
// The pixel centres a pass may cover inside one 8x8 screen tile.
struct PassTileCoverage {
  uint32_t tile, pass;
  uint64_t mask;
};
struct DrawnGroups {
  std::vector<DrawnGroup> groups;  // in drawing order
  std::vector<uint32_t> cells;
  std::vector<PassTileCoverage> coverage;  // in no particular order; a (tile, pass) may repeat
  // Whole tiles may be listed for this many (tile, pass) pairs (a few screens' worth); beyond
  // that the scene is mostly cells whose pixels were not rasterized (large convex parts), their
  // passes gain little from segments, and every pass is a segment of its own.
  size_t whole_tiles_left = 0;
  bool every_pass_a_segment = false;

  // Every centre of the tiles that pixel rectangle (x0, y0, x1, y1) touches, for `pass`: the
  // coverage of a cell whose pixels were not rasterized.
  void coverRect(int x0, int y0, int x1, int y1, int tiles_x, uint32_t pass) {
    const size_t tiles = size_t((x1 >> 3) - (x0 >> 3) + 1) * size_t((y1 >> 3) - (y0 >> 3) + 1);
    if (every_pass_a_segment || tiles > whole_tiles_left) {
      every_pass_a_segment = true;
      return;
    }
    whole_tiles_left -= tiles;
    for (int ty = y0 >> 3; ty <= y1 >> 3; ++ty)
      for (int tx = x0 >> 3; tx <= x1 >> 3; ++tx)
        coverage.push_back({uint32_t(ty) * uint32_t(tiles_x) + uint32_t(tx), pass, ~uint64_t(0)});
  }
};

// Milliseconds since `t0`, and t0 moved to now.
inline double lapMs(std::chrono::steady_clock::time_point& t0) {
  const auto now = std::chrono::steady_clock::now();
  const double ms = std::chrono::duration<double, std::milli>(now - t0).count();
  t0 = now;
  return ms;
}

// Projects the cells of one group of parts for a view: each cell's screen rectangle and depth
// range from its corners (tighter than its box), and the pixel centres its triangles may cover,
// per 8x8 screen tile (coverTriangle). A cell with a corner behind the near plane or far off the
// image covers the whole screen as far as ordering is concerned.
class CellProjector {
 public:
  // One cell's coverage of one screen tile; `node` is the cell's index in the projected list.
  struct TileCoverage {
    uint32_t tile, node;
    uint64_t mask;
  };

  CellProjector(const CellScene& s, const ViewGeometry& vg, CellMaskDevice* device)
      : s_(s),
        vg_(vg),
        device_(device),
        tiles_x_((vg.width + 7) / 8),
        tile_count_(size_t(tiles_x_) * size_t((vg.height + 7) / 8), 0),
        tile_begin_(tile_count_.size()),
        tile_end_(tile_count_.size()) {}

  // Projects the vertices of `parts` and then their `cells` (their extents into ext), and
  // gathers the cells' tile coverage, on all cores when there are many.
  void projectAll(const std::vector<uint32_t>& parts, const std::vector<uint32_t>& cells,
                  std::vector<ScreenExtent>& ext) {
    projectVertices(parts);
    const size_t n = cells.size();
    whole_screen_.assign(n, 0);
    node_first_.assign(n + 1, 0);
    // Most cells' masks on the device, if there is one and enough cells to pay for a call.
    on_device_.assign(n, 0);
    use_device_ = device_ && n >= device_->minCells();
    // Cells are dealt to threads in contiguous runs of about equal triangle counts, so each
    // thread's coverage is already in node order.
    size_t triangles = 0;
    for (uint32_t c : cells) triangles += s_.cell_first[c + 1] - s_.cell_first[c];
    const unsigned threads = triangles < 2048 ? 1u : cellOrderThreads();
    std::vector<size_t> run(threads + 1, n);
    run[0] = 0;
    for (size_t i = 0, t = 1, seen = 0; i < n && t < threads; ++i) {
      seen += s_.cell_first[cells[i] + 1] - s_.cell_first[cells[i]];
      if (seen * threads >= triangles * t) run[t++] = i + 1;
    }
    std::vector<std::vector<TileCoverage>> found(threads);
    auto work = [&](unsigned t) {
      std::vector<glm::vec2> corners;
      std::vector<uint64_t> masks;
      std::vector<uint32_t> touched;
      // The thread's own list, moved into found[t] at the end: the vectors' headers in found
      // share a cache line, which every push would pass between the cores.
      std::vector<TileCoverage> mine;
      mine.reserve((run[t + 1] - run[t]) * 4);  // a fine mesh's cells touch 2-3 tiles
      for (size_t i = run[t]; i < run[t + 1]; ++i) {
        const size_t before = mine.size();
        project(uint32_t(i), cells[i], ext[i], corners, masks, touched, mine);
        node_first_[i + 1] = uint32_t(mine.size() - before);
      }
      found[t] = std::move(mine);
    };
    runOnPool(threads, work);
    by_node_.clear();
    if (use_device_) {
      mergeDeviceMasks(parts, cells, ext, found);
    } else {
      for (size_t i = 0; i < n; ++i) node_first_[i + 1] += node_first_[i];
      by_node_.reserve(node_first_[n]);
      for (const auto& f : found) by_node_.insert(by_node_.end(), f.begin(), f.end());
    }
    // The same coverage grouped by tile, for the pairs sharing a tile. Only the tiles covered
    // are visited (a group of parts may cover a few of the screen's tiles): each gets a range
    // of by_tile_, and its count is cleared again for the next group.
    std::vector<uint32_t> covered;
    for (const TileCoverage& c : by_node_)
      if (tile_count_[c.tile]++ == 0) covered.push_back(c.tile);
    uint32_t next = 0;
    for (uint32_t t : covered) {
      tile_begin_[t] = tile_end_[t] = next;
      next += tile_count_[t];
      tile_count_[t] = 0;
    }
    by_tile_.resize(by_node_.size());
    tile_position_.resize(by_node_.size());
    for (size_t k = 0; k < by_node_.size(); ++k) {
      const TileCoverage& c = by_node_[k];
      tile_position_[k] = tile_end_[c.tile]++;
      by_tile_[tile_position_[k]] = c;
    }
  }

  // Cells whose masks the device computed, and the pairs it found, over every call.
  uint32_t deviceMaskCells() const { return device_mask_cells_; }
  uint64_t devicePairs() const { return device_pair_count_; }
  double deviceMs() const { return device_ms_; }

  // The pairs of nodes that may share a pixel centre with relation(u, v) as in findConstraints: on
  // the device when it made the masks (the same pairs and relations: the rules are shared),
  // else sharedPixelPairs on the host.
  template <typename Relation>
  std::vector<Constraints> pairs(const std::vector<ScreenExtent>& ext,
                                 const std::vector<uint32_t>& cells, Relation relation) {
    if (!use_device_ || by_node_.empty()) return sharedPixelPairs(ext, relation);
    static_assert(sizeof(TileCoverage) == 16, "four 32-bit words per entry");
    const size_t n = ext.size();
    node_depth_.resize(n);
    for (size_t i = 0; i < n; ++i) node_depth_[i] = glm::vec2(ext[i].zmin, ext[i].zmax);
    CellMaskDevice::PairRequest r;
    r.by_node = reinterpret_cast<const uint32_t*>(by_node_.data());
    r.by_tile = reinterpret_cast<const uint32_t*>(by_tile_.data());
    r.tile_position = tile_position_.data();
    r.tile_end = tile_end_.data();
    r.node_first = node_first_.data();
    r.entries = uint32_t(by_node_.size());
    r.tiles = uint32_t(tile_end_.size());
    r.nodes = uint32_t(n);
    r.node_cell = cells.data();
    r.node_depth = node_depth_.data();
    r.eye = vg_.eye;
    r.forward = vg_.forward;
    r.perspective = vg_.perspective;
    auto t0 = std::chrono::steady_clock::now();
    device_->pairs(r, device_pairs_);
    device_ms_ += lapMs(t0);
    // The nodes covering the whole screen have no tile entries: their pairs are the host's.
    std::vector<Constraints> found;
    if (std::find(whole_screen_.begin(), whole_screen_.end(), 1) != whole_screen_.end())
      found = sharedPixelPairs(ext, relation, true);
    Constraints f;
    f.edges.reserve(device_pairs_.size() / 2);
    for (size_t i = 0; i + 1 < device_pairs_.size(); i += 2) {
      const uint32_t code = device_pairs_[i + 1] >> 30;
      f.add(device_pairs_[i], device_pairs_[i + 1] & 0x3FFFFFFFu,
            code == 1   ? 1
            : code == 2 ? -1
            : code == 3 ? 2
                        : 0);
    }
    device_pair_count_ += f.pairs;
    found.push_back(std::move(f));
    return found;
  }

  // Every pair of visible nodes that may share a pixel centre, each examined once (from the
  // lower node, which remembers the partners it has seen), with relation(u, v) as in
  // findConstraints. Nodes are dealt to threads in interleaved runs (relation() only reads).
  // With whole_screen_only, only the pairs of the nodes that cover the whole screen (the
  // device found the others).
  template <typename Relation>
  std::vector<Constraints> sharedPixelPairs(const std::vector<ScreenExtent>& ext, Relation relation,
                                            bool whole_screen_only = false) const {
    const uint32_t n = uint32_t(ext.size());
    const unsigned threads = by_node_.size() < 8192 ? 1u : cellOrderThreads();
    std::vector<Constraints> found(threads);
    auto work = [&](unsigned t) {
      Constraints f;  // the thread's own, moved into found[t] (which shares cache lines)
      std::vector<uint32_t> seen(n, UINT32_MAX);
      f.edges.reserve(by_node_.size() / threads + 1);  // about one pair per tile entry
      auto emit = [&](uint32_t u, uint32_t v) { f.add(u, v, relation(u, v)); };
      const TileCoverage* by_tile = by_tile_.data();
      for (uint32_t u = t * 64; u < n; u += threads * 64) {
        for (uint32_t w = u; w < std::min(n, u + 64); ++w) {
          if (!ext[w].visible()) continue;
          if (whole_screen_[w]) {  // paired with every visible node
            for (uint32_t v = 0; v < n; ++v)
              if (v != w && ext[v].visible() && !(whole_screen_[v] && v < w)) emit(w, v);
            continue;
          }
          if (whole_screen_only) continue;
          for (uint32_t k = node_first_[w]; k < node_first_[w + 1]; ++k) {
            const uint64_t mask = by_node_[k].mask;
            // A tile's list is in node order: the nodes after w's own entry are the higher ones.
            const TileCoverage* other = by_tile + tile_position_[k] + 1;
            const TileCoverage* end = by_tile + tile_end_[by_node_[k].tile];
            // The entries sharing a centre with w's gathered first without a branch (about one
            // in eight does, unpredictably), then met one by one.
            while (other < end) {
              const TileCoverage* stop = end - other > 64 ? other + 64 : end;
              uint32_t sharing[64], count = 0;
              for (; other < stop; ++other) {
                sharing[count] = other->node;
                count += (other->mask & mask) != 0;
              }
              for (uint32_t i = 0; i < count; ++i) {
                const uint32_t v = sharing[i];
                if (seen[v] == w) continue;
                seen[v] = w;
                emit(w, v);
              }
            }
          }
        }
      }
      found[t] = std::move(f);
    };
    runOnPool(threads, work);
    return found;
  }

 private:
  void project(uint32_t node, uint32_t c, ScreenExtent& e, std::vector<glm::vec2>& h,
               std::vector<uint64_t>& masks, std::vector<uint32_t>& touched,
               std::vector<TileCoverage>& out) {
    if (!extent(node, c, e, h)) return;
    const uint32_t n = s_.cell_first[c + 1] - s_.cell_first[c];
    const uint16_t* corners = &s_.cell_corners[size_t(s_.cell_first[c]) * 3];
    if (e.x1 - (e.x0 & ~7) < 64 && e.y1 - (e.y0 & ~7) < 64)
      coverSmall(node, e, h, corners, n, out);
    else
      coverLarge(node, e, h, corners, n, masks, touched, out);
  }

  // The cell's screen extent (e) and its corners on the screen (h); true when its tiles' masks
  // are for the host to compute, false when it covers no pixel centre, is taken to cover the
  // whole screen (whole_screen_) or is left to the device (on_device_).
  bool extent(uint32_t node, uint32_t c, ScreenExtent& e, std::vector<glm::vec2>& h) {
    e = ScreenExtent{};
    e.zmin = 1e30f;
    e.zmax = -1e30f;
    bool ok = true;
    float px0 = 1e30f, py0 = 1e30f, px1 = -1e30f, py1 = -1e30f;
    const uint32_t v0 = s_.cell_vertex_first[c], v1 = s_.cell_vertex_first[c + 1];
    if (h.size() < v1 - v0) h.resize(v1 - v0);  // only grown: every corner read is written below
    const float near_half = vg_.near_distance * 0.5f;
    for (uint32_t k = v0; k < v1; ++k) {
      const uint32_t v = s_.cell_vertex_index[k];
      const float z = depth_[v];
      e.zmin = std::min(e.zmin, z);
      e.zmax = std::max(e.zmax, z);
      if (z < near_half) {
        ok = false;
        h[k - v0] = glm::vec2(0.0f);
        continue;
      }
      const glm::vec2 xy = screen_[v];
      h[k - v0] = xy;
      px0 = std::min(px0, xy.x);
      px1 = std::max(px1, xy.x);
      py0 = std::min(py0, xy.y);
      py1 = std::max(py1, xy.y);
    }
    if (e.zmax < vg_.near_distance) return false;  // wholly behind the near plane: empty
    // Corners far off the image (a cell reaching towards the eye, or a huge one): the float
    // projection no longer places them within the coverage slack of the device's, so the cell
    // is taken to cover the whole screen.
    constexpr float kFarOff = 1.0e4f;
    ok = ok && px0 > -kFarOff && py0 > -kFarOff && px1 < float(vg_.width) + kFarOff &&
         py1 < float(vg_.height) + kFarOff;
    if (!ok) {
      e.x0 = e.y0 = 0;
      e.x1 = vg_.width - 1;
      e.y1 = vg_.height - 1;
      whole_screen_[node] = 1;
      return false;
    }
    // The pixels whose centres the corners' span can reach, widened by the coverage slack.
    e.x0 = std::max(0, ceilPixel(px0 - 0.5f - ST_COVER_SLACK));
    e.y0 = std::max(0, ceilPixel(py0 - 0.5f - ST_COVER_SLACK));
    e.x1 = std::min(vg_.width - 1, floorPixel(px1 - 0.5f + ST_COVER_SLACK));
    e.y1 = std::min(vg_.height - 1, floorPixel(py1 - 0.5f + ST_COVER_SLACK));
    if (e.x0 > e.x1 || e.y0 > e.y1) return false;  // covers no pixel centre
    // Every triangle of a cell this small and near takes the float setup: the device can mark
    // its centres with the host's bits.
    if (use_device_ && px1 - px0 <= ST_COVER_FLOAT_SPAN && py1 - py0 <= ST_COVER_FLOAT_SPAN &&
        px0 > -ST_COVER_FLOAT_REACH && py0 > -ST_COVER_FLOAT_REACH && px1 < ST_COVER_FLOAT_REACH &&
        py1 < ST_COVER_FLOAT_REACH) {
      on_device_[node] = 1;
      return false;
    }
    return true;
  }

  // Triangle k of the cell set up in t (false: it is near no pixel centre of the image).
  bool setUp(const std::vector<glm::vec2>& h, const uint16_t* corners, uint32_t k, CoverEdges& t) {
    return setupCover(h[corners[3 * k]], h[corners[3 * k + 1]], h[corners[3 * k + 2]], vg_.width,
                      vg_.height, t);
  }

  // A small cell (most of a fine mesh's, under 64 x 64 pixels from its 8-aligned corner): its
  // centres as rows of bits, then cut into tiles in tile order.
  void coverSmall(uint32_t node, const ScreenExtent& e, const std::vector<glm::vec2>& h,
                  const uint16_t* corners, uint32_t n, std::vector<TileCoverage>& out) {
    const int bx = e.x0 & ~7, by = e.y0 & ~7;
    CoverEdges t;
    uint64_t rows[64];
    std::fill(rows + (e.y0 - by), rows + (e.y1 - by) + 1, uint64_t(0));
#if defined(__SSE2__)
    // Four triangles at a time; the last batch repeats its first triangle in the lanes past
    // the cell's end, which are then ignored.
    for (uint32_t k = 0; k < n; k += 4) {
      const uint32_t lanes = std::min(n - k, 4u);
      alignas(16) float c[6][4];
      for (uint32_t l = 0; l < 4; ++l)
        for (int j = 0; j < 3; ++j) {
          const glm::vec2 v = h[corners[3 * (k + (l < lanes ? l : 0)) + j]];
          c[2 * j][l] = v.x;
          c[2 * j + 1][l] = v.y;
        }
      CoverEdges four[4];
      const CoverSetup4 r =
          setupCover4(c[0], c[1], c[2], c[3], c[4], c[5], vg_.width, vg_.height, four);
      for (uint32_t l = 0; l < lanes; ++l) {
        if (r.done >> l & 1u) {
          coverTriangleRows(four[l], bx, by, rows);
        } else if (!(r.empty >> l & 1u) && setUp(h, corners, k + l, t)) {
          coverTriangleRows(t, bx, by, rows);
        }
      }
    }
#else
    for (uint32_t k = 0; k < n; ++k)
      if (setUp(h, corners, k, t)) coverTriangleRows(t, bx, by, rows);
#endif
    // Byte j of a row is tile column bx / 8 + j, so a tile row's masks are its eight rows'
    // bytes transposed.
    for (int ty = e.y0 >> 3; ty <= e.y1 >> 3; ++ty) {
      const int ya = std::max(e.y0, ty * 8), yb = std::min(e.y1, ty * 8 + 7);
      alignas(16) uint64_t band[8], masks8[8];
      for (int k = 0; k < 8; ++k) {
        const int y = ty * 8 + k;
        band[k] = y >= ya && y <= yb ? rows[y - by] : 0;
      }
      transposeBytes8x8(band, masks8);
      for (int tx = e.x0 >> 3; tx <= e.x1 >> 3; ++tx) {
        const uint64_t mask = masks8[tx - (bx >> 3)];
        if (mask) out.push_back({uint32_t(ty) * uint32_t(tiles_x_) + uint32_t(tx), node, mask});
      }
    }
  }

  // A larger cell: its masks gathered per tile of its rectangle, then emitted in tile order.
  void coverLarge(uint32_t node, const ScreenExtent& e, const std::vector<glm::vec2>& h,
                  const uint16_t* corners, uint32_t n, std::vector<uint64_t>& masks,
                  std::vector<uint32_t>& touched, std::vector<TileCoverage>& out) {
    CoverEdges t;
    // The masks stay zero between cells: only the tiles a cell touched are read and cleared.
    CoverageSink sink{e.x0 >> 3, e.y0 >> 3, (e.x1 >> 3) - (e.x0 >> 3) + 1, nullptr, &touched};
    const int tiles_h = (e.y1 >> 3) - (e.y0 >> 3) + 1;
    if (masks.size() < size_t(sink.tiles_w) * tiles_h) masks.resize(size_t(sink.tiles_w) * tiles_h);
    sink.masks = masks.data();
    touched.clear();
    for (uint32_t k = 0; k < n; ++k)
      if (setUp(h, corners, k, t)) coverTriangle(t, sink);
    // In tile order: a scan of the rectangle when the cell touched much of it, else a sort.
    const size_t rect_tiles = size_t(sink.tiles_w) * size_t(tiles_h);
    auto emit = [&](uint32_t i) {
      const uint32_t tx = i % uint32_t(sink.tiles_w) + uint32_t(sink.tx0);
      const uint32_t ty = i / uint32_t(sink.tiles_w) + uint32_t(sink.ty0);
      out.push_back({ty * uint32_t(tiles_x_) + tx, node, masks[i]});
      masks[i] = 0;
    };
    if (rect_tiles <= 4 * touched.size()) {
      for (uint32_t i = 0; i < rect_tiles; ++i)
        if (masks[i]) emit(i);
    } else {
      std::sort(touched.begin(), touched.end());
      for (uint32_t i : touched) emit(i);
    }
  }

  // The masks of the cells left to the device (on_device_), computed there, and the host's
  // (`found`, per thread in node order, node_first_[i + 1] entries for node i) merged into
  // by_node_ in node order; the device's empty tiles are dropped, as the host never lists them.
  void mergeDeviceMasks(const std::vector<uint32_t>& parts, const std::vector<uint32_t>& cells,
                        const std::vector<ScreenExtent>& ext,
                        const std::vector<std::vector<TileCoverage>>& found) {
    const size_t n = cells.size();
    device_cells_.clear();
    device_rects_.clear();
    entry_first_.assign(1, 0);
    for (size_t i = 0; i < n; ++i) {
      if (!on_device_[i]) continue;
      const ScreenExtent& e = ext[i];
      device_cells_.push_back(cells[i]);
      device_rects_.emplace_back(e.x0, e.y0, e.x1, e.y1);
      const uint32_t tiles =
          uint32_t((e.x1 >> 3) - (e.x0 >> 3) + 1) * uint32_t((e.y1 >> 3) - (e.y0 >> 3) + 1);
      entry_first_.push_back(entry_first_.back() + tiles);
    }
    if (!device_cells_.empty()) {
      uint32_t first = UINT32_MAX, last = 0;
      for (uint32_t p : parts) {
        first = std::min(first, s_.part_vertex_begin[p]);
        last = std::max(last, s_.part_vertex_end[p]);
      }
      CellMaskDevice::Request request;
      request.screen = screen_.data() + first;
      request.first_vertex = first;
      request.vertex_count = last - first;
      request.cells = &device_cells_;
      request.rects = &device_rects_;
      request.entry_first = &entry_first_;
      request.width = vg_.width;
      request.height = vg_.height;
      auto t0 = std::chrono::steady_clock::now();
      device_->cover(request, device_masks_);
      device_ms_ += lapMs(t0);
      device_mask_cells_ += uint32_t(device_cells_.size());
    }
    size_t host_total = 0;
    for (const auto& f : found) host_total += f.size();
    by_node_.reserve(host_total + device_masks_.size());
    size_t thread = 0, next = 0, device_node = 0;
    for (size_t i = 0; i < n; ++i) {
      const size_t before = by_node_.size();
      if (on_device_[i]) {
        const glm::ivec4& r = device_rects_[device_node];
        const uint32_t tiles_w = uint32_t((r.z >> 3) - (r.x >> 3) + 1);
        for (uint32_t k = entry_first_[device_node]; k < entry_first_[device_node + 1]; ++k) {
          const uint64_t mask = device_masks_[k];
          if (!mask) continue;
          const uint32_t j = k - entry_first_[device_node];
          const uint32_t tx = uint32_t(r.x >> 3) + j % tiles_w,
                         ty = uint32_t(r.y >> 3) + j / tiles_w;
          by_node_.push_back({ty * uint32_t(tiles_x_) + tx, uint32_t(i), mask});
        }
        ++device_node;
      } else {
        for (uint32_t k = 0; k < node_first_[i + 1]; ++k) {
          while (next == found[thread].size()) {
            ++thread;
            next = 0;
          }
          by_node_.push_back(found[thread][next++]);
        }
      }
      node_first_[i + 1] = node_first_[i] + uint32_t(by_node_.size() - before);
    }
  }

  // The view depth and the pixel position of every vertex of `parts` (a vertex within half the
  // near distance of the eye's plane or behind it gets no position: its cells are taken to
  // cover the whole screen).
  void projectVertices(const std::vector<uint32_t>& parts) {
    if (screen_.size() != s_.vertices.size()) {
      screen_.resize(s_.vertices.size());
      depth_.resize(s_.vertices.size());
    }
    // The rows of the view-projection matrix (glm's is column-major), written out so the
    // multiply is inlined.
    const glm::mat4& m = vg_.view_proj;
    const float half_w = 0.5f * float(vg_.width), half_h = 0.5f * float(vg_.height);
    const float near_half = vg_.near_distance * 0.5f;
    auto range = [&](uint32_t begin, uint32_t end) {
      uint32_t v = begin;
#if defined(__SSE2__)
      // Four at a time, every value rounded as the loop below rounds it (the same operations in
      // the same order; glm's dot adds x, y, then z). A vertex behind gets a position too, unread.
      const __m128 fx = _mm_set1_ps(vg_.forward.x), fy = _mm_set1_ps(vg_.forward.y),
                   fz = _mm_set1_ps(vg_.forward.z);
      const __m128 ex = _mm_set1_ps(vg_.eye.x), ey = _mm_set1_ps(vg_.eye.y),
                   ez = _mm_set1_ps(vg_.eye.z);
      const __m128 one = _mm_set1_ps(1.0f), hw = _mm_set1_ps(half_w), hh = _mm_set1_ps(half_h);
      auto row = [&](int r, __m128 x, __m128 y, __m128 z) {
        return _mm_add_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(m[0][r]), x),
                                                _mm_mul_ps(_mm_set1_ps(m[1][r]), y)),
                                     _mm_mul_ps(_mm_set1_ps(m[2][r]), z)),
                          _mm_set1_ps(m[3][r]));
      };
      for (; v + 4 <= end; v += 4) {
        const glm::vec3* p = &s_.vertices[v];
        const __m128 x = _mm_setr_ps(p[0].x, p[1].x, p[2].x, p[3].x);
        const __m128 y = _mm_setr_ps(p[0].y, p[1].y, p[2].y, p[3].y);
        const __m128 z = _mm_setr_ps(p[0].z, p[1].z, p[2].z, p[3].z);
        const __m128 d = _mm_add_ps(
            _mm_add_ps(_mm_mul_ps(fx, _mm_sub_ps(x, ex)), _mm_mul_ps(fy, _mm_sub_ps(y, ey))),
            _mm_mul_ps(fz, _mm_sub_ps(z, ez)));
        _mm_storeu_ps(&depth_[v], d);
        const __m128 qw = row(3, x, y, z);
        const __m128 sx = _mm_mul_ps(_mm_add_ps(_mm_div_ps(row(0, x, y, z), qw), one), hw);
        const __m128 sy = _mm_mul_ps(_mm_sub_ps(one, _mm_div_ps(row(1, x, y, z), qw)), hh);
        float* out = &screen_[v].x;
        _mm_storeu_ps(out, _mm_unpacklo_ps(sx, sy));
        _mm_storeu_ps(out + 4, _mm_unpackhi_ps(sx, sy));
      }
#endif
      for (; v < end; ++v) {
        const glm::vec3& p = s_.vertices[v];
        const float z = glm::dot(vg_.forward, p - vg_.eye);
        depth_[v] = z;
        if (z < near_half) continue;
        const float qx = m[0][0] * p.x + m[1][0] * p.y + m[2][0] * p.z + m[3][0];
        const float qy = m[0][1] * p.x + m[1][1] * p.y + m[2][1] * p.z + m[3][1];
        const float qw = m[0][3] * p.x + m[1][3] * p.y + m[2][3] * p.z + m[3][3];
        screen_[v] = glm::vec2((qx / qw + 1.0f) * half_w, (1.0f - qy / qw) * half_h);
      }
    };
    size_t total = 0;
    for (uint32_t p : parts) total += s_.part_vertex_end[p] - s_.part_vertex_begin[p];
    const unsigned threads = total < 32768 ? 1u : cellOrderThreads();
    if (threads == 1) {
      for (uint32_t p : parts) range(s_.part_vertex_begin[p], s_.part_vertex_end[p]);
      return;
    }
    // Each thread takes its share of every part's vertices.
    runOnPool(threads, [&](unsigned t) {
      for (uint32_t p : parts) {
        const uint64_t b = s_.part_vertex_begin[p], count = s_.part_vertex_end[p] - b;
        range(uint32_t(b + count * t / threads), uint32_t(b + count * (t + 1) / threads));
      }
    });
  }

  const CellScene& s_;
  const ViewGeometry& vg_;
  CellMaskDevice* device_;
  bool use_device_ = false;
  std::vector<char> on_device_;  // per node: its masks are the device's
  std::vector<uint32_t> device_cells_, entry_first_;
  std::vector<glm::ivec4> device_rects_;
  std::vector<uint64_t> device_masks_;
  uint32_t device_mask_cells_ = 0;
  double device_ms_ = 0.0;
  std::vector<glm::vec2> node_depth_;
  std::vector<uint32_t> device_pairs_;
  uint64_t device_pair_count_ = 0;
  int tiles_x_;
  std::vector<glm::vec2> screen_;  // per scene vertex, for the parts being ordered
  std::vector<float> depth_;

 public:
  // Adds the coverage of the projected nodes to `drawn`, node n drawn in pass node_pass[n]; a
  // node that covers the whole screen as far as ordering is concerned covers every tile.
  void addCoverage(const std::vector<ScreenExtent>& ext, uint32_t nodes,
                   const std::vector<uint32_t>& node_pass, DrawnGroups& drawn) const {
    for (const TileCoverage& c : by_node_)
      drawn.coverage.push_back({c.tile, node_pass[c.node], c.mask});
    for (uint32_t n = 0; n < nodes; ++n)
      if (whole_screen_[n] && ext[n].visible())
        drawn.coverRect(0, 0, vg_.width - 1, vg_.height - 1, tiles_x_, node_pass[n]);
  }
  // Node n's coverage once more, drawn in `pass` (a copy of a coincident triangle).
  void addCoverageOf(uint32_t n, const ScreenExtent& e, uint32_t pass, DrawnGroups& drawn) const {
    for (uint32_t k = node_first_[n]; k < node_first_[n + 1]; ++k)
      drawn.coverage.push_back({by_node_[k].tile, pass, by_node_[k].mask});
    if (whole_screen_[n] && e.visible())
      drawn.coverRect(0, 0, vg_.width - 1, vg_.height - 1, tiles_x_, pass);
  }

 private:
  std::vector<char> whole_screen_;    // per node: a corner behind the near plane or far off
  std::vector<uint32_t> node_first_;  // nodes + 1 offsets into by_node_
  std::vector<TileCoverage> by_node_, by_tile_;
  std::vector<uint32_t> tile_position_;  // per entry of by_node_: its index in by_tile_
  // Per screen tile: a count kept zero between groups, and the range of by_tile_ of a tile the
  // current group covers (stale for the others, which are never read).
  std::vector<uint32_t> tile_count_, tile_begin_, tile_end_;
};

}  // namespace

}  // namespace strata::cellorder
