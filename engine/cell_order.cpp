// Per-view ordering of convex cells, in two levels: instances (parts) first, then the cells of
// each group of instances whose boxes overlap. Cells of one mesh come from the preprocessing
// (decomposition and the view-independent separating planes of every pair of cells with
// overlapping boxes). For a view, every two cells whose screen rectangles overlap get an order
// from, in turn: disjoint view-depth intervals; no overlap of their projected hulls (no
// constraint); disjoint boxes (an axis plane); their separating plane (the side the eye is on).
// Overlapping cells with no such relation are merged into one group, and so are cycles (strongly
// connected components); the groups come out in topological order, nearest first.
#include "engine/cell_order.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <numeric>
#include <queue>
#include <thread>

#include <glm/gtc/matrix_inverse.hpp>

namespace strata {

namespace {

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

}  // namespace

MeshView cellMeshView(const WorldGeometry& geo, const GeometryPart& part,
                      std::vector<uint32_t>& local_indices, bool* object_space) {
  const uint32_t m = part.mesh;
  MeshView view;
  if (!geo.mesh_positions.empty() && size_t(m) + 1 < geo.mesh_first_vertex.size() &&
      size_t(m) + 1 < geo.mesh_first_triangle.size() &&
      geo.mesh_first_triangle[m + 1] - geo.mesh_first_triangle[m] == part.triangle_count &&
      geo.mesh_first_vertex[m + 1] - geo.mesh_first_vertex[m] == part.vertex_count) {
    view.positions = geo.mesh_positions.data() + geo.mesh_first_vertex[m];
    view.vertex_count = part.vertex_count;
    view.indices = geo.mesh_indices.data() + size_t(geo.mesh_first_triangle[m]) * 3;
    view.triangle_count = part.triangle_count;
    *object_space = true;
    return view;
  }
  local_indices.resize(size_t(part.triangle_count) * 3);
  for (size_t i = 0; i < local_indices.size(); ++i)
    local_indices[i] = geo.indices[size_t(part.first_triangle) * 3 + i] - part.first_vertex;
  view.positions = geo.positions.data() + part.first_vertex;
  view.vertex_count = part.vertex_count;
  view.indices = local_indices.data();
  view.triangle_count = part.triangle_count;
  *object_space = false;
  return view;
}

CellScene CellScene::build(const WorldGeometry& geo, const DecomposeOptions& options,
                           const std::string& cache_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  CellScene s;
  s.mode = options.mode;
  std::vector<GeometryPart> parts = geo.parts;
  if (parts.empty())
    parts.push_back(
        {0, 0, geo.triangleCount(), 0, uint32_t(geo.positions.size()), glm::mat4(1.0f)});

  // One decomposition per mesh, in the mesh's own space when the geometry has it (so moving an
  // instance neither re-decomposes it nor writes a new cache file), else on its first
  // instance. Convexity and plane sides are invariant under the affine maps between them.
  struct MeshCells {
    CellPreprocess prep;
    glm::mat4 inverse_first{1.0f};     // world space of first_part -> the decomposed space
    uint32_t first_part = UINT32_MAX;  // the part decomposed in its own world space, if any
  };
  std::map<uint32_t, MeshCells> meshes;
  size_t largest = 0;
  std::vector<uint32_t> local;
  for (uint32_t pi = 0; pi < parts.size(); ++pi) {
    const GeometryPart& part = parts[pi];
    if (meshes.count(part.mesh)) continue;
    bool object_space = false;
    const MeshView view = cellMeshView(geo, part, local, &object_space);
    bool cached = false;
    MeshCells mc;
    mc.prep = loadOrBuildCells(view, options, cache_dir, &cached);
    s.from_cache = s.from_cache && cached;
    if (!object_space) {
      mc.inverse_first = glm::inverse(part.transform);
      mc.first_part = pi;
    }
    if (part.triangle_count >= largest) {
      largest = part.triangle_count;
      s.grid = mc.prep.grid;
    }
    meshes.emplace(part.mesh, std::move(mc));
  }

  s.cell_first.push_back(0);
  s.cell_vertex_first.push_back(0);
  s.part_cell_first.push_back(0);
  s.triangle_flip.assign(geo.triangleCount(), 0);
  std::vector<std::vector<CellNeighbour>> neighbours;
  for (uint32_t pi = 0; pi < parts.size(); ++pi) {
    const GeometryPart& part = parts[pi];
    const MeshCells& mc = meshes.at(part.mesh);
    const CellDecomposition& cells = mc.prep.cells;
    const uint32_t base = s.cellCount();
    Bounds part_box;
    std::vector<uint32_t> corners;
    for (uint32_t c = 0; c < cells.cellCount(); ++c) {
      Bounds box;
      corners.clear();
      for (uint32_t k = cells.cell_begin[c]; k < cells.cell_begin[c + 1]; ++k) {
        const uint32_t t = part.first_triangle + cells.triangle_order[k];
        s.cell_triangles.push_back(t);
        for (int v = 0; v < 3; ++v) {
          corners.push_back(geo.indices[size_t(t) * 3 + v]);
          box.extend(geo.positions[corners.back()]);
        }
      }
      std::vector<uint32_t> distinct = corners;
      std::sort(distinct.begin(), distinct.end());
      distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
      for (uint32_t v : corners)
        s.cell_corners.push_back(
            uint16_t(std::lower_bound(distinct.begin(), distinct.end(), v) - distinct.begin()));
      glm::dvec3 centre(0.0);
      for (uint32_t v : distinct) {
        s.cell_vertices.push_back(geo.positions[v]);
        centre += glm::dvec3(geo.positions[v]);
      }
      centre /= double(std::max<size_t>(1, distinct.size()));
      s.cell_vertex_first.push_back(uint32_t(s.cell_vertices.size()));
      // The cell's own facing: a convex cell's inside is behind each of its faces, so a face whose
      // winding normal looks towards the cell's centre is wound inwards (flipped).
      for (uint32_t k = cells.cell_begin[c]; k < cells.cell_begin[c + 1]; ++k) {
        const uint32_t t = part.first_triangle + cells.triangle_order[k];
        const glm::dvec3 p0(geo.positions[geo.indices[size_t(t) * 3]]);
        const glm::dvec3 p1(geo.positions[geo.indices[size_t(t) * 3 + 1]]);
        const glm::dvec3 p2(geo.positions[geo.indices[size_t(t) * 3 + 2]]);
        const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
        s.triangle_flip[t] =
            glm::dot(n, centre - p0) >
                    1e-9 * glm::length(n) * glm::length(glm::dvec3(box.max - box.min))
                ? 1
                : 0;
      }
      s.cell_first.push_back(uint32_t(s.cell_triangles.size()));
      s.cell_part.push_back(pi);
      s.cell_box.push_back(box);
      if (!box.empty()) {
        part_box.extend(box.min);
        part_box.extend(box.max);
      }
    }
    s.part_cell_first.push_back(s.cellCount());
    s.part_box.push_back(part_box);
    neighbours.resize(s.cellCount());
    const bool first = pi == mc.first_part;
    const glm::mat4 plane_map =
        first ? glm::mat4(1.0f) : glm::transpose(glm::inverse(part.transform * mc.inverse_first));
    for (const CellPair& pair : mc.prep.pairs) {
      if (!pair.separable) {
        ++s.inseparable_pairs;
        neighbours[base + pair.a].push_back({base + pair.b, false, CellPlane{}});
        neighbours[base + pair.b].push_back({base + pair.a, false, CellPlane{}});
        continue;
      }
      ++s.separable_pairs;
      glm::vec4 p(pair.plane.n, pair.plane.d);
      if (!first) p = plane_map * p;
      CellPlane plane{glm::vec3(p), p.w};
      neighbours[base + pair.a].push_back({base + pair.b, true, plane});
      neighbours[base + pair.b].push_back({base + pair.a, true, CellPlane{-plane.n, -plane.d}});
    }
  }
  s.neighbour_first.push_back(0);
  for (auto& list : neighbours) {
    std::sort(list.begin(), list.end(),
              [](const CellNeighbour& x, const CellNeighbour& y) { return x.other < y.other; });
    s.neighbours.insert(s.neighbours.end(), list.begin(), list.end());
    s.neighbour_first.push_back(uint32_t(s.neighbours.size()));
  }
  s.preprocess_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return s;
}

namespace {

struct ScreenExtent {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive pixel rectangle; empty when x0 > x1
  float zmin = 0.0f, zmax = 0.0f;        // view distance
  bool visible() const { return x0 <= x1 && y0 <= y1; }
};

bool rectsOverlap(const ScreenExtent& a, const ScreenExtent& b) {
  return a.x0 <= b.x1 && b.x0 <= a.x1 && a.y0 <= b.y1 && b.y0 <= a.y1;
}

// View-dependent helpers: the projection of a box and the side of a plane the eye is on.
struct ViewGeometry {
  glm::mat4 view_proj;
  glm::vec3 eye, forward;
  bool perspective;
  float near_distance;
  int width, height;

  ScreenExtent extent(const Bounds& b) const {
    ScreenExtent e;
    e.zmin = 1e30f;
    e.zmax = -1e30f;
    float px0 = 1e30f, py0 = 1e30f, px1 = -1e30f, py1 = -1e30f;
    bool behind = false;
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 p((k & 1) ? b.max.x : b.min.x, (k & 2) ? b.max.y : b.min.y,
                        (k & 4) ? b.max.z : b.min.z);
      const float z = glm::dot(forward, p - eye);
      e.zmin = std::min(e.zmin, z);
      e.zmax = std::max(e.zmax, z);
      if (z < near_distance * 0.5f) {
        behind = true;
        continue;
      }
      const glm::vec4 c = view_proj * glm::vec4(p, 1.0f);
      const float x = (c.x / c.w * 0.5f + 0.5f) * float(width);
      const float y = (0.5f - c.y / c.w * 0.5f) * float(height);
      px0 = std::min(px0, x);
      px1 = std::max(px1, x);
      py0 = std::min(py0, y);
      py1 = std::max(py1, y);
    }
    if (e.zmax < near_distance) return e;  // wholly behind the near plane: empty
    if (behind) {
      e.x0 = 0;
      e.y0 = 0;
      e.x1 = width - 1;
      e.y1 = height - 1;
      return e;
    }
    // One pixel of margin covers snapping and the pixel-centre rule.
    e.x0 = std::max(0, int(std::floor(px0)) - 1);
    e.y0 = std::max(0, int(std::floor(py0)) - 1);
    e.x1 = std::min(width - 1, int(std::ceil(px1)) + 1);
    e.y1 = std::min(height - 1, int(std::ceil(py1)) + 1);
    return e;
  }

  // +1: the cell on the plane's negative side can only be in front (draw it first); -1: the
  // one on the positive side; 0: the eye is on the plane (their projections cannot overlap).
  int negativeFirst(const CellPlane& p) const {
    if (!perspective) {
      const float s = glm::dot(p.n, forward);
      return s > 0.0f ? 1 : (s < 0.0f ? -1 : 0);
    }
    const float s = glm::dot(p.n, eye) + p.d;
    return s < 0.0f ? 1 : (s > 0.0f ? -1 : 0);
  }

  // Order from disjoint boxes: +1 a first, -1 b first, 0 none found (boxes overlap).
  int boxOrder(const Bounds& a, const Bounds& b) const {
    for (int k = 0; k < 3; ++k) {
      CellPlane p;
      p.n[k] = 1.0f;
      if (a.max[k] < b.min[k]) {
        p.d = -0.5f * (a.max[k] + b.min[k]);
        return negativeFirst(p);
      }
      if (b.max[k] < a.min[k]) {
        p.d = -0.5f * (b.max[k] + a.min[k]);
        return -negativeFirst(p);
      }
    }
    return 0;
  }
};

// A cell's projection bounded along 8 directions (a 16-sided discrete oriented polytope): a
// conservative outline whose overlap test costs 8 interval comparisons.
constexpr int kDopAxes = 8;
struct ScreenDop {
  float lo[kDopAxes], hi[kDopAxes];
  static const glm::vec2& axis(int k) {
    static const glm::vec2 axes[kDopAxes] = {{1.0f, 0.0f},
                                             {0.92387953f, 0.38268343f},
                                             {0.70710678f, 0.70710678f},
                                             {0.38268343f, 0.92387953f},
                                             {0.0f, 1.0f},
                                             {-0.38268343f, 0.92387953f},
                                             {-0.70710678f, 0.70710678f},
                                             {-0.92387953f, 0.38268343f}};
    return axes[k];
  }
  void set(const std::vector<glm::vec2>& points) {
    for (int k = 0; k < kDopAxes; ++k) {
      lo[k] = 1e30f;
      hi[k] = -1e30f;
      for (const glm::vec2& p : points) {
        const float d = glm::dot(axis(k), p);
        lo[k] = std::min(lo[k], d);
        hi[k] = std::max(hi[k], d);
      }
    }
  }
  // Overlap deeper than eps along every axis (touching outlines do not overlap).
  bool overlaps(const ScreenDop& o, float eps) const {
    for (int k = 0; k < kDopAxes; ++k)
      if (hi[k] - o.lo[k] < eps || o.hi[k] - lo[k] < eps) return false;
    return true;
  }
};

// A projected triangle for overlap tests: corners counter-clockwise and, per edge, the inward
// unit normal and offset (n . p + c >= 0 inside). Edge-on triangles are not valid (no area, so
// no pixel centre).
struct ScreenTriangle {
  float x[3], y[3], nx[3], ny[3], c[3];
  float x0, y0, x1, y1;  // bounds
  bool valid = false;

  void set(glm::vec2 a, glm::vec2 b, glm::vec2 d) {
    const float area = (b.x - a.x) * (d.y - a.y) - (d.x - a.x) * (b.y - a.y);
    valid = std::fabs(area) > 1e-6f;
    if (!valid) return;
    if (area < 0.0f) std::swap(b, d);
    const glm::vec2 p[3] = {a, b, d};
    x0 = std::min(a.x, std::min(b.x, d.x));
    x1 = std::max(a.x, std::max(b.x, d.x));
    y0 = std::min(a.y, std::min(b.y, d.y));
    y1 = std::max(a.y, std::max(b.y, d.y));
    for (int i = 0; i < 3; ++i) {
      x[i] = p[i].x;
      y[i] = p[i].y;
      const glm::vec2 e = p[(i + 1) % 3] - p[i];
      const float len = glm::length(e);
      nx[i] = -e.y / len;
      ny[i] = e.x / len;
      c[i] = -(nx[i] * p[i].x + ny[i] * p[i].y);
    }
  }
  // Whether `o` reaches deeper than eps past every edge line of this triangle.
  bool reachedBy(const ScreenTriangle& o, float eps) const {
    for (int i = 0; i < 3; ++i) {
      const float d0 = nx[i] * o.x[0] + ny[i] * o.y[0] + c[i];
      const float d1 = nx[i] * o.x[1] + ny[i] * o.y[1] + c[i];
      const float d2 = nx[i] * o.x[2] + ny[i] * o.y[2] + c[i];
      if (std::max(d0, std::max(d1, d2)) < eps) return false;
    }
    return true;
  }
  bool overlaps(const ScreenTriangle& o, float eps) const {
    if (!valid || !o.valid) return false;
    if (x1 - o.x0 < eps || o.x1 - x0 < eps || y1 - o.y0 < eps || o.y1 - y0 < eps) return false;
    return reachedBy(o, eps) && o.reachedBy(*this, eps);
  }
};

// +1 a before b, -1 b before a, 0 any order, 2 unknown.
int orderOf(const ScreenExtent& ea, const ScreenExtent& eb) {
  if (ea.zmax <= eb.zmin) return 1;
  if (eb.zmax <= ea.zmin) return -1;
  return 2;
}

}  // namespace

// Orders `count` nodes for the view. For every two nodes whose screen rectangles overlap (found
// through screen bins of `bin` pixels, each pair examined once), relation(a, b) says +1 (a
// first), -1 (b first), 0 (no constraint) or 2 (no order known: draw them as one group). Nodes
// joined by 2 and strongly connected components of the constraints are merged; the merged
// groups come out in topological order, the nearest free one first. Invisible nodes come last.
struct NodeOrder {
  std::vector<std::vector<uint32_t>> groups;            // in drawing order
  std::vector<std::pair<uint32_t, uint32_t>> overlaps;  // (earlier, later) groups that overlap
};

namespace {

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
};

// Every pair of overlapping rectangles, examined once (in the bin holding the corner of their
// intersection), bin rows split over threads (relation() only reads).
template <typename Relation>
Constraints findConstraints(const std::vector<ScreenExtent>& ext, const ScreenBins& bins,
                            Relation relation) {
  const unsigned threads = std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
  std::vector<Constraints> found(threads);
  auto work = [&](unsigned t) {
    Constraints& f = found[t];
    std::vector<uint32_t> list;
    for (int by = int(t); by < bins.bins_y; by += int(threads)) {
      for (int bx = 0; bx < bins.bins_x; ++bx) {
        const size_t b = size_t(by) * bins.bins_x + bx;
        // Sweep along x: only nodes whose spans can overlap are paired.
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
            ++f.pairs;
            const int rel = relation(u, v);
            if (rel == 1)
              f.edges.emplace_back(u, v);
            else if (rel == -1)
              f.edges.emplace_back(v, u);
            else if (rel == 2)
              f.merges.emplace_back(u, v);
          }
        }
      }
    }
  };
  if (threads == 1 || bins.nodes.size() < 2048) {
    for (unsigned t = 0; t < threads; ++t) work(t);
  } else {
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t) pool.emplace_back(work, t);
    for (std::thread& th : pool) th.join();
  }
  Constraints all;
  for (Constraints& f : found) {
    all.pairs += f.pairs;
    all.merges.insert(all.merges.end(), f.merges.begin(), f.merges.end());
    all.edges.insert(all.edges.end(), f.edges.begin(), f.edges.end());
  }
  return all;
}

// A directed graph in compressed rows: the successors of n are out[first[n] .. first[n + 1]).
struct Graph {
  std::vector<uint32_t> first, out;
  uint32_t size() const { return uint32_t(first.size() - 1); }
};

// Adjacency by a counting sort on the source; edges inside one node are dropped (duplicates
// are harmless to the users below).
Graph makeGraph(uint32_t nodes, const std::vector<std::pair<uint32_t, uint32_t>>& edges) {
  Graph g;
  g.first.assign(nodes + 1, 0);
  for (auto [a, b] : edges)
    if (a != b) ++g.first[a + 1];
  for (uint32_t n = 0; n < nodes; ++n) g.first[n + 1] += g.first[n];
  g.out.resize(g.first[nodes]);
  std::vector<uint32_t> cursor(g.first.begin(), g.first.end() - 1);
  for (auto [a, b] : edges)
    if (a != b) g.out[cursor[a]++] = b;
  return g;
}

// Strongly connected components (iterative Tarjan): the component of every node; components
// are numbered in reverse topological order of the condensed graph.
std::vector<uint32_t> stronglyConnectedComponents(const Graph& g, uint32_t* count) {
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
  for (uint32_t root = 0; root < nodes; ++root) {
    if (index[root] != UINT32_MAX) continue;
    visit(root);
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

// Kahn's algorithm on a DAG, the free node of least key first: the rank of every node.
std::vector<uint32_t> topologicalRanks(const Graph& dag, const std::vector<float>& key) {
  const uint32_t n = dag.size();
  std::vector<uint32_t> indeg(n, 0);
  for (uint32_t m : dag.out) ++indeg[m];
  using Item = std::pair<float, uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> ready;
  for (uint32_t c = 0; c < n; ++c)
    if (indeg[c] == 0) ready.emplace(key[c], c);
  std::vector<uint32_t> rank(n, 0);
  uint32_t next = 0;
  while (!ready.empty()) {
    const uint32_t c = ready.top().second;
    ready.pop();
    rank[c] = next++;
    for (uint32_t k = dag.first[c]; k < dag.first[c + 1]; ++k)
      if (--indeg[dag.out[k]] == 0) ready.emplace(key[dag.out[k]], dag.out[k]);
  }
  return rank;
}

}  // namespace

template <typename Relation>
NodeOrder orderNodes(const std::vector<ScreenExtent>& ext, int width, int height, int bin,
                     Relation relation, uint64_t* pairs_tested, uint64_t* merged_pairs) {
  const uint32_t count = uint32_t(ext.size());
  const Constraints found = findConstraints(ext, ScreenBins(ext, width, height, bin), relation);
  *pairs_tested += found.pairs;
  *merged_pairs += found.merges.size();
  UnionFind merged(count);
  for (auto [u, v] : found.merges) merged.unite(u, v);

  // Nodes of the constraint graph: the merged sets of visible nodes.
  std::vector<uint32_t> node_of(count, UINT32_MAX);
  uint32_t nodes = 0;
  for (uint32_t g = 0; g < count; ++g) {
    if (!ext[g].visible()) continue;
    const uint32_t r = merged.find(g);
    if (node_of[r] == UINT32_MAX) node_of[r] = nodes++;
    node_of[g] = node_of[r];
  }
  std::vector<std::pair<uint32_t, uint32_t>> edges;
  edges.reserve(found.edges.size());
  for (auto [a, b] : found.edges) edges.emplace_back(node_of[a], node_of[b]);
  const Graph graph = makeGraph(nodes, edges);

  // Cycles merge into one group; the condensed graph is ordered nearest free component first.
  uint32_t comps = 0;
  const std::vector<uint32_t> comp = stronglyConnectedComponents(graph, &comps);
  std::vector<float> comp_z(comps, 1e30f);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX)
      comp_z[comp[node_of[g]]] = std::min(comp_z[comp[node_of[g]]], ext[g].zmin);
  std::vector<std::pair<uint32_t, uint32_t>> comp_edges;
  for (uint32_t n = 0; n < nodes; ++n)
    for (uint32_t k = graph.first[n]; k < graph.first[n + 1]; ++k)
      comp_edges.emplace_back(comp[n], comp[graph.out[k]]);
  const Graph condensed = makeGraph(comps, comp_edges);
  const std::vector<uint32_t> rank = topologicalRanks(condensed, comp_z);

  NodeOrder result;
  result.groups.resize(comps);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX) result.groups[rank[comp[node_of[g]]]].push_back(g);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] == UINT32_MAX) result.groups.push_back({g});
  for (uint32_t c = 0; c < comps; ++c)
    for (uint32_t k = condensed.first[c]; k < condensed.first[c + 1]; ++k)
      result.overlaps.emplace_back(rank[c], rank[condensed.out[k]]);
  return result;
}

// Passes of groups in drawing order: a group's pass is one more than that of every earlier
// group it overlaps (at least `base`). Returns the last pass used (base - 1 if none).
int64_t assignPasses(const NodeOrder& order, int64_t base, std::vector<int64_t>& pass) {
  pass.assign(order.groups.size(), base);
  std::vector<std::pair<uint32_t, uint32_t>> by_later(order.overlaps);
  std::sort(by_later.begin(), by_later.end(),
            [](const auto& x, const auto& y) { return x.second < y.second; });
  size_t k = 0;
  int64_t last = base - 1;
  for (uint32_t g = 0; g < order.groups.size(); ++g) {
    for (; k < by_later.size() && by_later[k].second == g; ++k)
      pass[g] = std::max(pass[g], pass[by_later[k].first] + 1);
    last = std::max(last, pass[g]);
  }
  return last;
}

namespace {

// Projects cells for one view and tests whether two cells' projections overlap. A cell is
// projected once: its screen rectangle and depth range from its corners (tighter than its box),
// its outline and, for small cells, its triangles.
class CellProjector {
 public:
  CellProjector(const CellScene& s, const ViewGeometry& vg)
      : s_(s),
        vg_(vg),
        projected_(s.cellCount()),
        outlines_(s.cellCount()),
        triangle_first_(s.cellCount(), UINT32_MAX),
        usable_(s.cellCount(), 0) {}

  // Projects `cells` (their extents into ext), in parallel when there are many.
  void projectAll(const std::vector<uint32_t>& cells, std::vector<ScreenExtent>& ext) {
    // Slots for the triangles of small cells first, so cells project in parallel.
    size_t total = triangles_.size();
    for (uint32_t c : cells) {
      const uint32_t n = s_.cell_first[c + 1] - s_.cell_first[c];
      if (n > 16) continue;
      triangle_first_[c] = uint32_t(total);
      total += n;
    }
    triangles_.resize(total);
    const unsigned threads =
        cells.size() < 4096 ? 1u : std::max(1u, std::min(8u, std::thread::hardware_concurrency()));
    auto work = [&](unsigned t) {
      for (size_t i = t; i < cells.size(); i += threads) project(cells[i], ext[i]);
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t);
    work(0);
    for (std::thread& th : pool) th.join();
  }

  // Whether two cells' projected triangles overlap (interiors, beyond 1e-3 pixel): their
  // outlines first, then triangle by triangle when the cells are small (else the outlines
  // decide, which only errs towards overlap).
  bool overlap(uint32_t a, uint32_t b) const {
    if (!usable_[a] || !usable_[b]) return true;
    if (!outlines_[a].overlaps(outlines_[b], 1e-3f)) return false;
    if (triangle_first_[a] == UINT32_MAX || triangle_first_[b] == UINT32_MAX)
      return true;  // big cells
    const ScreenTriangle* ta = &triangles_[triangle_first_[a]];
    const ScreenTriangle* tb = &triangles_[triangle_first_[b]];
    const uint32_t na = s_.cell_first[a + 1] - s_.cell_first[a],
                   nb = s_.cell_first[b + 1] - s_.cell_first[b];
    const ScreenDop& ob = outlines_[b];  // axes 0 and 4 are x and y
    for (uint32_t i = 0; i < na; ++i) {
      const ScreenTriangle& t = ta[i];
      if (!t.valid || t.x1 - ob.lo[0] < 1e-3f || ob.hi[0] - t.x0 < 1e-3f ||
          t.y1 - ob.lo[4] < 1e-3f || ob.hi[4] - t.y0 < 1e-3f)
        continue;
      for (uint32_t j = 0; j < nb; ++j)
        if (t.overlaps(tb[j], 1e-3f)) return true;
    }
    return false;
  }

 private:
  void project(uint32_t c, ScreenExtent& e) {
    std::vector<glm::vec2>& h = projected_[c];
    h.clear();
    e = ScreenExtent{};
    e.zmin = 1e30f;
    e.zmax = -1e30f;
    bool ok = true;
    float px0 = 1e30f, py0 = 1e30f, px1 = -1e30f, py1 = -1e30f;
    for (uint32_t k = s_.cell_vertex_first[c]; k < s_.cell_vertex_first[c + 1]; ++k) {
      const glm::vec3& p = s_.cell_vertices[k];
      const float z = glm::dot(vg_.forward, p - vg_.eye);
      e.zmin = std::min(e.zmin, z);
      e.zmax = std::max(e.zmax, z);
      if (z < vg_.near_distance * 0.5f) {
        ok = false;
        continue;
      }
      const glm::vec4 q = vg_.view_proj * glm::vec4(p, 1.0f);
      const glm::vec2 xy((q.x / q.w * 0.5f + 0.5f) * float(vg_.width),
                         (0.5f - q.y / q.w * 0.5f) * float(vg_.height));
      h.push_back(xy);
      px0 = std::min(px0, xy.x);
      px1 = std::max(px1, xy.x);
      py0 = std::min(py0, xy.y);
      py1 = std::max(py1, xy.y);
    }
    if (e.zmax < vg_.near_distance) return;  // wholly behind the near plane: empty
    if (!ok) {
      e.x0 = e.y0 = 0;
      e.x1 = vg_.width - 1;
      e.y1 = vg_.height - 1;
      return;
    }
    // The pixels whose centres (i + 0.5) the corners' span can reach, widened by more than the
    // snapping error (1/512 pixel) of the rasterizer.
    constexpr float kSlack = 1.0f / 64.0f;
    e.x0 = std::max(0, int(std::ceil(px0 - 0.5f - kSlack)));
    e.y0 = std::max(0, int(std::ceil(py0 - 0.5f - kSlack)));
    e.x1 = std::min(vg_.width - 1, int(std::floor(px1 - 0.5f + kSlack)));
    e.y1 = std::min(vg_.height - 1, int(std::floor(py1 - 0.5f + kSlack)));
    if (e.x0 > e.x1 || e.y0 > e.y1) return;  // covers no pixel centre
    usable_[c] = 1;
    outlines_[c].set(h);
    const uint32_t n = s_.cell_first[c + 1] - s_.cell_first[c];
    if (triangle_first_[c] != UINT32_MAX) {  // small cells are tested triangle by triangle
      for (uint32_t k = 0; k < n; ++k) {
        const uint16_t* idx = &s_.cell_corners[size_t(s_.cell_first[c] + k) * 3];
        triangles_[triangle_first_[c] + k].set(h[idx[0]], h[idx[1]], h[idx[2]]);
      }
    }
  }

  const CellScene& s_;
  const ViewGeometry& vg_;
  std::vector<std::vector<glm::vec2>> projected_;
  std::vector<ScreenDop> outlines_;
  std::vector<ScreenTriangle> triangles_;  // of small cells, at triangle_first_[c]
  std::vector<uint32_t> triangle_first_;   // UINT32_MAX: not made
  std::vector<char> usable_;               // all corners in front of the near plane
};

// A group of cells in drawing order with its pass and the pixels it may cover.
struct DrawnGroup {
  int64_t pass;
  uint32_t sequence;
  std::vector<uint32_t> cells;
  glm::ivec4 rect;
};

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

// Level 2: orders the cells of one group of parts; their groups start at pass `base`. Returns
// the last pass used.
int64_t orderPartGroupCells(const CellScene& s, const ViewGeometry& vg, CellProjector& projector,
                            const std::vector<uint32_t>& part_group, int64_t base,
                            std::vector<DrawnGroup>& drawn, CellOrder& order) {
  std::vector<uint32_t> cells;
  for (uint32_t p : part_group)
    for (uint32_t c = s.part_cell_first[p]; c < s.part_cell_first[p + 1]; ++c) cells.push_back(c);
  std::vector<ScreenExtent> ext(cells.size());
  if (cells.size() == 1)
    ext[0] = vg.extent(s.cell_box[cells[0]]);  // no pairs: its box will do
  else
    projector.projectAll(cells, ext);
  auto relation = [&](uint32_t i, uint32_t j) -> int {
    const uint32_t a = cells[i], b = cells[j];
    // Only pairs that really overlap on screen constrain the order. A constraint between
    // cells that do not (neighbours on one sheet of the surface merely touch) is arbitrary,
    // and arbitrary constraints form cycles that merge groups for nothing.
    if (!projector.overlap(a, b)) return 0;
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
  if (cells.size() == 1)
    local.groups = {{0}};
  else
    local =
        orderNodes(ext, vg.width, vg.height, 8, relation, &order.pairs_tested, &order.merged_pairs);
  std::vector<int64_t> pass;
  const int64_t last = assignPasses(local, base, pass);
  for (size_t g = 0; g < local.groups.size(); ++g) {
    DrawnGroup d{pass[g], uint32_t(drawn.size()), {}, glm::ivec4(vg.width, vg.height, -1, -1)};
    for (uint32_t i : local.groups[g]) {
      d.cells.push_back(cells[i]);
      if (!ext[i].visible()) continue;
      d.rect = glm::ivec4(std::min(d.rect.x, ext[i].x0), std::min(d.rect.y, ext[i].y0),
                          std::max(d.rect.z, ext[i].x1), std::max(d.rect.w, ext[i].y1));
    }
    drawn.push_back(std::move(d));
  }
  return last;
}

}  // namespace

CellOrder orderCells(const CellScene& s, const Camera& camera, int width, int height) {
  const ViewGeometry vg = viewGeometryOf(camera, width, height);
  CellOrder order;
  order.group_first.push_back(0);

  // Level 1: instances (parts). Parts ordered by depth or by a plane between their boxes;
  // parts whose boxes overlap are ordered together, cell by cell, at level 2.
  const uint32_t parts = uint32_t(s.part_box.size());
  std::vector<ScreenExtent> part_ext(parts);
  for (uint32_t p = 0; p < parts; ++p) part_ext[p] = vg.extent(s.part_box[p]);
  const NodeOrder part_order = orderNodes(
      part_ext, width, height, 64,
      [&](uint32_t a, uint32_t b) {
        const int z = orderOf(part_ext[a], part_ext[b]);
        if (z != 2) return z;
        const int box = vg.boxOrder(s.part_box[a], s.part_box[b]);
        return box != 0 ? box : 2;
      },
      &order.pairs_tested, &order.merged_pairs);
  // A group of parts starts after the last pass of every earlier group of parts it overlaps.
  std::vector<int64_t> part_last(part_order.groups.size(), -1);
  std::vector<std::vector<uint32_t>> part_preds(part_order.groups.size());
  for (auto [a, b] : part_order.overlaps) part_preds[b].push_back(a);

  CellProjector projector(s, vg);
  std::vector<DrawnGroup> drawn;
  for (uint32_t pgi = 0; pgi < part_order.groups.size(); ++pgi) {
    int64_t base = 0;
    for (uint32_t prev : part_preds[pgi]) base = std::max(base, part_last[prev] + 1);
    part_last[pgi] =
        orderPartGroupCells(s, vg, projector, part_order.groups[pgi], base, drawn, order);
  }
  // Pass by pass; inside a pass, in drawing order.
  std::stable_sort(drawn.begin(), drawn.end(),
                   [](const DrawnGroup& x, const DrawnGroup& y) { return x.pass < y.pass; });
  for (const DrawnGroup& d : drawn) {
    order.cells.insert(order.cells.end(), d.cells.begin(), d.cells.end());
    order.largest_group = std::max(order.largest_group, uint32_t(d.cells.size()));
    order.group_first.push_back(uint32_t(order.cells.size()));
    order.group_pass.push_back(uint32_t(d.pass));
    order.group_rect.push_back(d.rect);
    order.passes = std::max(order.passes, uint32_t(d.pass + 1));
  }
  return order;
}

}  // namespace strata
