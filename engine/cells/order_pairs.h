// The cells order's pairs: the nodes' screen rectangles binned, and every two that overlap
// met once and related (an order, none, or a merge). Internal to the order's stages.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include <utility>
#include "engine/cells/cell_order.h"
#include "kernels/strata_shared.h"

#include "engine/cells/order_projection.h"
#include "preprocess/core/threads.h"

namespace strata::cellorder {

// The visible nodes of every screen bin their rectangle touches (a counting sort by bin).
struct ScreenBins {
  int bin = 8, bins_x = 0, bins_y = 0;
  std::vector<uint32_t> first;  // bins + 1 offsets into nodes
  std::vector<uint32_t> nodes;

  ScreenBins(const std::vector<ScreenExtent>& ext, int width, int height, int bin_size)
      : bin(bin_size),
        bins_x((width + bin_size - 1) / bin_size),
        bins_y((height + bin_size - 1) / bin_size) {
    first.assign(size_t(bins_x) * bins_y + 1, 0);
    forEachBin(ext, [&](uint32_t, size_t b) { ++first[b + 1]; });
    for (size_t b = 1; b < first.size(); ++b) first[b] += first[b - 1];
    nodes.resize(first.back());
    std::vector<uint32_t> cursor(first.begin(), first.end() - 1);
    forEachBin(ext, [&](uint32_t n, size_t b) { nodes[cursor[b]++] = n; });
  }

 private:
  template <typename F>
  void forEachBin(const std::vector<ScreenExtent>& ext, F f) const {
    for (uint32_t n = 0; n < ext.size(); ++n) {
      const ScreenExtent& e = ext[n];
      if (!e.visible()) continue;
      for (int by = e.y0 / bin; by <= e.y1 / bin; ++by)
        for (int bx = e.x0 / bin; bx <= e.x1 / bin; ++bx) f(n, size_t(by) * bins_x + bx);
    }
  }
};

// What the pair tests found: ordering constraints (before, after) and pairs to merge.
struct Constraints {
  std::vector<std::pair<uint32_t, uint32_t>> edges, merges;
  uint64_t pairs = 0;

  // One examined pair and its relation (findConstraints).
  void add(uint32_t u, uint32_t v, int relation) {
    ++pairs;
    if (relation == 1)
      edges.emplace_back(u, v);
    else if (relation == -1)
      edges.emplace_back(v, u);
    else if (relation == 2)
      merges.emplace_back(u, v);
  }
};

// Every pair of overlapping rectangles of bin (bx, by) whose intersection's corner lies in it (so
// each pair once over the bins), swept along x, to visit(u, v) until it returns false; false then.
template <typename Visit>
inline bool forEachOverlapInBin(const std::vector<ScreenExtent>& ext, const ScreenBins& bins,
                                int bx, int by, std::vector<uint32_t>& list, Visit&& visit) {
  const size_t b = size_t(by) * bins.bins_x + bx;
  list.assign(bins.nodes.begin() + bins.first[b], bins.nodes.begin() + bins.first[b + 1]);
  std::sort(list.begin(), list.end(), [&](uint32_t p, uint32_t q) {
    return ext[p].x0 < ext[q].x0 || (ext[p].x0 == ext[q].x0 && p < q);
  });
  for (size_t i = 0; i < list.size(); ++i) {
    const uint32_t u = list[i];
    const ScreenExtent& eu = ext[u];
    for (size_t j = i + 1; j < list.size() && ext[list[j]].x0 <= eu.x1; ++j) {
      const uint32_t v = list[j];
      const ScreenExtent& ev = ext[v];
      if (!rectsOverlap(eu, ev)) continue;
      if (std::max(eu.x0, ev.x0) / bins.bin != bx || std::max(eu.y0, ev.y0) / bins.bin != by)
        continue;
      if (!visit(u, v)) return false;
    }
  }
  return true;
}

// Every pair of overlapping rectangles, examined once (in the bin holding the corner of their
// intersection), bin rows split over threads (relation() only reads); each thread's list.
template <typename Relation>
inline std::vector<Constraints> findConstraints(const std::vector<ScreenExtent>& ext,
                                                const ScreenBins& bins, Relation relation) {
  const unsigned threads = cellOrderThreads();
  std::vector<Constraints> found(threads);
  auto work = [&](unsigned t) {
    Constraints f;  // the thread's own (neighbouring elements of found share cache lines)
    std::vector<uint32_t> list;
    for (int by = int(t); by < bins.bins_y; by += int(threads))
      for (int bx = 0; bx < bins.bins_x; ++bx)
        forEachOverlapInBin(ext, bins, bx, by, list, [&](uint32_t u, uint32_t v) {
          f.add(u, v, relation(u, v));
          return true;
        });
    found[t] = std::move(f);
  };
  if (threads == 1 || bins.nodes.size() < 2048) {
    for (unsigned t = 0; t < threads; ++t) work(t);
  } else {
    runOnPool(threads, work);
  }
  return found;
}

// Whether more than `limit` pairs of rectangles overlap (findConstraints' enumeration, counting
// only, stopping at the limit).
inline bool rectOverlapsPast(const std::vector<ScreenExtent>& ext, const ScreenBins& bins,
                             uint64_t limit) {
  uint64_t count = 0;
  std::vector<uint32_t> list;
  for (int by = 0; by < bins.bins_y; ++by)
    for (int bx = 0; bx < bins.bins_x; ++bx)
      if (!forEachOverlapInBin(ext, bins, bx, by, list,
                               [&](uint32_t, uint32_t) { return ++count <= limit; }))
        return true;
  return false;
}

}  // namespace strata::cellorder
