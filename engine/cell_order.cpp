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
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <numeric>
#include <map>
#include <queue>

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

bool boxesOverlap(const Bounds& a, const Bounds& b) {
  return a.min.x <= b.max.x && b.min.x <= a.max.x && a.min.y <= b.max.y && b.min.y <= a.max.y &&
         a.min.z <= b.max.z && b.min.z <= a.max.z;
}

}  // namespace

CellScene CellScene::build(const WorldGeometry& geo, const DecomposeOptions& options,
                           const std::string& cache_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  CellScene s;
  s.mode = options.mode;
  std::vector<GeometryPart> parts = geo.parts;
  if (parts.empty())
    parts.push_back({0, 0, geo.triangleCount(), 0, uint32_t(geo.positions.size()), glm::mat4(1.0f)});

  // One decomposition per mesh, computed on its first instance (convexity and plane sides are
  // invariant under the affine maps between instances).
  struct MeshCells {
    CellPreprocess prep;
    glm::mat4 inverse_first{1.0f};
    uint32_t first_part = 0;
  };
  std::map<uint32_t, MeshCells> meshes;
  size_t largest = 0;
  for (uint32_t pi = 0; pi < parts.size(); ++pi) {
    const GeometryPart& part = parts[pi];
    if (meshes.count(part.mesh)) continue;
    std::vector<uint32_t> local(size_t(part.triangle_count) * 3);
    for (size_t i = 0; i < local.size(); ++i)
      local[i] = geo.indices[size_t(part.first_triangle) * 3 + i] - part.first_vertex;
    MeshView view;
    view.positions = geo.positions.data() + part.first_vertex;
    view.vertex_count = part.vertex_count;
    view.indices = local.data();
    view.triangle_count = part.triangle_count;
    bool cached = false;
    MeshCells mc;
    mc.prep = loadOrBuildCells(view, options, cache_dir, &cached);
    s.from_cache = s.from_cache && cached;
    mc.inverse_first = glm::inverse(part.transform);
    mc.first_part = pi;
    if (part.triangle_count >= largest) {
      largest = part.triangle_count;
      s.grid = mc.prep.grid;
    }
    meshes.emplace(part.mesh, std::move(mc));
  }

  s.cell_first.push_back(0);
  s.cell_vertex_first.push_back(0);
  s.part_cell_first.push_back(0);
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
        s.cell_corners.push_back(uint16_t(std::lower_bound(distinct.begin(), distinct.end(), v) - distinct.begin()));
      for (uint32_t v : distinct) s.cell_vertices.push_back(geo.positions[v]);
      s.cell_vertex_first.push_back(uint32_t(s.cell_vertices.size()));
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
    const glm::mat4 plane_map = first ? glm::mat4(1.0f)
                                      : glm::transpose(glm::inverse(part.transform * mc.inverse_first));
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

// Convex hull (counter-clockwise, Andrew's monotone chain) of points, in place.
void convexHull(std::vector<glm::vec2>& p) {
  if (p.size() < 3) return;
  std::sort(p.begin(), p.end(), [](const glm::vec2& a, const glm::vec2& b) {
    return a.x < b.x || (a.x == b.x && a.y < b.y);
  });
  std::vector<glm::vec2> h(2 * p.size());
  size_t k = 0;
  auto cross = [](const glm::vec2& o, const glm::vec2& a, const glm::vec2& b) {
    return double(a.x - o.x) * double(b.y - o.y) - double(a.y - o.y) * double(b.x - o.x);
  };
  for (size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0) --k;
    h[k++] = p[i];
  }
  for (size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0) --k;
    h[k++] = p[i - 1];
  }
  h.resize(k > 1 ? k - 1 : k);
  p.swap(h);
}

// Whether the interiors of two convex polygons overlap by more than `eps` pixels along every
// separating-axis candidate (their edge normals). Cells that only touch (neighbours on one
// sheet of the surface share an edge) do not overlap: no pixel centre is covered by both, since
// their shared edges are snapped identically and the fill rule gives each centre to one side.
bool hullsOverlap(const std::vector<glm::vec2>& a, const std::vector<glm::vec2>& b, float eps) {
  if (a.size() < 3 || b.size() < 3) return false;  // a point or a segment covers no area
  for (int pass = 0; pass < 2; ++pass) {
    const std::vector<glm::vec2>& p = pass ? b : a;
    for (size_t i = 0; i < p.size(); ++i) {
      const glm::vec2 e = p[(i + 1) % p.size()] - p[i];
      const float len = glm::length(e);
      if (len <= 0.0f) continue;
      const glm::vec2 n(e.y / len, -e.x / len);
      float a0 = 1e30f, a1 = -1e30f, b0 = 1e30f, b1 = -1e30f;
      for (const glm::vec2& q : a) {
        const float d = glm::dot(n, q);
        a0 = std::min(a0, d);
        a1 = std::max(a1, d);
      }
      for (const glm::vec2& q : b) {
        const float d = glm::dot(n, q);
        b0 = std::min(b0, d);
        b1 = std::max(b1, d);
      }
      if (a1 - b0 < eps || b1 - a0 < eps) return false;
    }
  }
  return true;
}

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
template <typename Relation>
std::vector<std::vector<uint32_t>> orderNodes(const std::vector<ScreenExtent>& ext, int width,
                                              int height, int bin, Relation relation,
                                              uint64_t* pairs_tested, uint64_t* merged_pairs) {
  const uint32_t count = uint32_t(ext.size());
  const int bins_x = (width + bin - 1) / bin, bins_y = (height + bin - 1) / bin;
  std::vector<uint32_t> bin_count(size_t(bins_x) * bins_y + 1, 0);
  for (uint32_t n = 0; n < count; ++n) {
    const ScreenExtent& e = ext[n];
    if (!e.visible()) continue;
    for (int by = e.y0 / bin; by <= e.y1 / bin; ++by)
      for (int bx = e.x0 / bin; bx <= e.x1 / bin; ++bx) ++bin_count[size_t(by) * bins_x + bx + 1];
  }
  for (size_t b = 1; b < bin_count.size(); ++b) bin_count[b] += bin_count[b - 1];
  std::vector<uint32_t> bin_nodes(bin_count.back());
  {
    std::vector<uint32_t> cursor(bin_count.begin(), bin_count.end() - 1);
    for (uint32_t n = 0; n < count; ++n) {
      const ScreenExtent& e = ext[n];
      if (!e.visible()) continue;
      for (int by = e.y0 / bin; by <= e.y1 / bin; ++by)
        for (int bx = e.x0 / bin; bx <= e.x1 / bin; ++bx) bin_nodes[cursor[size_t(by) * bins_x + bx]++] = n;
    }
  }
  UnionFind merged(count);
  std::vector<std::pair<uint32_t, uint32_t>> edges;  // (before, after)
  for (int by = 0; by < bins_y; ++by) {
    for (int bx = 0; bx < bins_x; ++bx) {
      const size_t b = size_t(by) * bins_x + bx;
      for (uint32_t i = bin_count[b]; i < bin_count[b + 1]; ++i) {
        const uint32_t u = bin_nodes[i];
        const ScreenExtent& eu = ext[u];
        for (uint32_t j = i + 1; j < bin_count[b + 1]; ++j) {
          const uint32_t v = bin_nodes[j];
          const ScreenExtent& ev = ext[v];
          if (!rectsOverlap(eu, ev)) continue;
          if (std::max(eu.x0, ev.x0) / bin != bx || std::max(eu.y0, ev.y0) / bin != by) continue;
          ++*pairs_tested;
          const int rel = relation(u, v);
          if (rel == 1) edges.emplace_back(u, v);
          else if (rel == -1) edges.emplace_back(v, u);
          else if (rel == 2) {
            ++*merged_pairs;
            merged.unite(u, v);
          }
        }
      }
    }
  }

  // Nodes of the constraint graph: the merged sets of visible nodes.
  std::vector<uint32_t> node_of(count, UINT32_MAX), node_root;
  for (uint32_t g = 0; g < count; ++g) {
    if (!ext[g].visible()) continue;
    const uint32_t r = merged.find(g);
    if (node_of[r] == UINT32_MAX) {
      node_of[r] = uint32_t(node_root.size());
      node_root.push_back(r);
    }
    node_of[g] = node_of[r];
  }
  const uint32_t nodes = uint32_t(node_root.size());
  // Adjacency by a counting sort on the source (duplicates are harmless below).
  std::vector<uint32_t> out_first(nodes + 1, 0), out;
  for (auto [a, b] : edges)
    if (node_of[a] != node_of[b]) ++out_first[node_of[a] + 1];
  for (uint32_t n = 0; n < nodes; ++n) out_first[n + 1] += out_first[n];
  out.resize(out_first[nodes]);
  {
    std::vector<uint32_t> cursor(out_first.begin(), out_first.end() - 1);
    for (auto [a, b] : edges)
      if (node_of[a] != node_of[b]) out[cursor[node_of[a]]++] = node_of[b];
  }

  // Strongly connected components (iterative Tarjan).
  std::vector<uint32_t> comp(nodes, UINT32_MAX), index(nodes, UINT32_MAX), low(nodes, 0);
  std::vector<uint32_t> stack, call, edge_at(nodes, 0);
  std::vector<char> on_stack(nodes, 0);
  uint32_t next_index = 0, comps = 0;
  for (uint32_t root = 0; root < nodes; ++root) {
    if (index[root] != UINT32_MAX) continue;
    index[root] = low[root] = next_index++;
    edge_at[root] = out_first[root];
    stack.push_back(root);
    on_stack[root] = 1;
    call.push_back(root);
    while (!call.empty()) {
      const uint32_t n = call.back();
      if (edge_at[n] < out_first[n + 1]) {
        const uint32_t m = out[edge_at[n]++];
        if (index[m] == UINT32_MAX) {
          index[m] = low[m] = next_index++;
          edge_at[m] = out_first[m];
          stack.push_back(m);
          on_stack[m] = 1;
          call.push_back(m);
        } else if (on_stack[m]) {
          low[n] = std::min(low[n], index[m]);
        }
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

  // Kahn's algorithm on the condensed graph, nearest free component first.
  std::vector<float> comp_z(comps, 1e30f);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX)
      comp_z[comp[node_of[g]]] = std::min(comp_z[comp[node_of[g]]], ext[g].zmin);
  std::vector<uint32_t> indeg(comps, 0), cfirst(comps + 1, 0), cout;
  for (uint32_t n = 0; n < nodes; ++n)
    for (uint32_t k = out_first[n]; k < out_first[n + 1]; ++k)
      if (comp[n] != comp[out[k]]) {
        ++cfirst[comp[n] + 1];
        ++indeg[comp[out[k]]];
      }
  for (uint32_t c = 0; c < comps; ++c) cfirst[c + 1] += cfirst[c];
  cout.resize(cfirst[comps]);
  {
    std::vector<uint32_t> cursor(cfirst.begin(), cfirst.end() - 1);
    for (uint32_t n = 0; n < nodes; ++n)
      for (uint32_t k = out_first[n]; k < out_first[n + 1]; ++k)
        if (comp[n] != comp[out[k]]) cout[cursor[comp[n]]++] = comp[out[k]];
  }
  using Item = std::pair<float, uint32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> ready;
  for (uint32_t c = 0; c < comps; ++c)
    if (indeg[c] == 0) ready.emplace(comp_z[c], c);
  std::vector<uint32_t> rank(comps, 0);
  uint32_t next = 0;
  while (!ready.empty()) {
    const uint32_t c = ready.top().second;
    ready.pop();
    rank[c] = next++;
    for (uint32_t k = cfirst[c]; k < cfirst[c + 1]; ++k)
      if (--indeg[cout[k]] == 0) ready.emplace(comp_z[cout[k]], cout[k]);
  }
  if (std::getenv("STRATA_DEBUG_ORDER")) {
    uint32_t largest_comp = 0;
    std::vector<uint32_t> csize(comps, 0);
    for (uint32_t n = 0; n < nodes; ++n) largest_comp = std::max(largest_comp, ++csize[comp[n]]);
    std::fprintf(stderr, "order: %u nodes (%u after merges), %zu edges, %u components, largest %u nodes, pairs %llu merged %llu\n",
                 count, nodes, out.size(), comps, largest_comp, (unsigned long long)*pairs_tested,
                 (unsigned long long)*merged_pairs);
  }
  std::vector<std::vector<uint32_t>> groups(comps);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] != UINT32_MAX) groups[rank[comp[node_of[g]]]].push_back(g);
  for (uint32_t g = 0; g < count; ++g)
    if (node_of[g] == UINT32_MAX) groups.push_back({g});
  return groups;
}

CellOrder orderCells(const CellScene& s, const Camera& camera, int width, int height) {
  ViewGeometry vg;
  vg.view_proj = camera.projectionMatrix(float(width) / float(height)) * camera.viewMatrix();
  vg.eye = camera.eye;
  vg.forward = camera.forward();
  vg.perspective = camera.projection == Projection::Perspective;
  vg.near_distance = camera.near_distance;
  vg.width = width;
  vg.height = height;
  CellOrder order;
  order.group_first.push_back(0);

  // Level 1: instances (parts). Parts ordered by depth or by a plane between their boxes;
  // parts whose boxes overlap are ordered together, cell by cell, at level 2.
  const uint32_t parts = uint32_t(s.part_box.size());
  std::vector<ScreenExtent> part_ext(parts);
  for (uint32_t p = 0; p < parts; ++p) part_ext[p] = vg.extent(s.part_box[p]);
  const std::vector<std::vector<uint32_t>> part_groups = orderNodes(
      part_ext, width, height, 64,
      [&](uint32_t a, uint32_t b) {
        const int z = orderOf(part_ext[a], part_ext[b]);
        if (z != 2) return z;
        const int box = vg.boxOrder(s.part_box[a], s.part_box[b]);
        return box != 0 ? box : 2;
      },
      &order.pairs_tested, &order.merged_pairs);

  // Level 2: the cells of each group of parts.
  std::vector<std::vector<glm::vec2>> hulls(s.cellCount()), projected(s.cellCount());
  std::vector<char> hull_state(s.cellCount(), 0);  // 0 not made, 1 made, 2 unusable
  auto hullOf = [&](uint32_t c) -> const std::vector<glm::vec2>* {
    if (hull_state[c] == 0) {
      hull_state[c] = 1;
      std::vector<glm::vec2>& h = projected[c];
      for (uint32_t k = s.cell_vertex_first[c]; k < s.cell_vertex_first[c + 1]; ++k) {
        const glm::vec3& p = s.cell_vertices[k];
        if (glm::dot(vg.forward, p - vg.eye) < vg.near_distance) {
          hull_state[c] = 2;  // a corner near or behind the eye: no usable projection
          break;
        }
        const glm::vec4 q = vg.view_proj * glm::vec4(p, 1.0f);
        h.emplace_back((q.x / q.w * 0.5f + 0.5f) * float(width), (0.5f - q.y / q.w * 0.5f) * float(height));
      }
      if (hull_state[c] == 1) {
        hulls[c] = h;
        convexHull(hulls[c]);
      }
    }
    return hull_state[c] == 1 ? &hulls[c] : nullptr;
  };
  // Whether two cells' projected triangles overlap (interiors, beyond 1e-3 pixel): their hulls
  // first, then triangle by triangle when the cells are small (else the hulls decide, which
  // only errs towards overlap).
  std::vector<glm::vec2> ta(3), tb(3);
  auto cellsOverlap = [&](uint32_t a, uint32_t b) {
    const std::vector<glm::vec2>* ha = hullOf(a);
    const std::vector<glm::vec2>* hb = ha ? hullOf(b) : nullptr;
    if (!ha || !hb) return true;
    if (!hullsOverlap(*ha, *hb, 1e-3f)) return false;
    const uint32_t na = s.cell_first[a + 1] - s.cell_first[a], nb = s.cell_first[b + 1] - s.cell_first[b];
    if (size_t(na) * nb > 64) return true;
    auto triangle = [&](uint32_t c, uint32_t k, std::vector<glm::vec2>& t) {
      const uint16_t* idx = &s.cell_corners[size_t(s.cell_first[c] + k) * 3];
      for (int v = 0; v < 3; ++v) t[v] = projected[c][idx[v]];
      const float area = (t[1].x - t[0].x) * (t[2].y - t[0].y) - (t[2].x - t[0].x) * (t[1].y - t[0].y);
      if (area < 0.0f) std::swap(t[1], t[2]);
      return std::fabs(area) > 1e-6f;
    };
    for (uint32_t i = 0; i < na; ++i) {
      if (!triangle(a, i, ta)) continue;
      for (uint32_t j = 0; j < nb; ++j)
        if (triangle(b, j, tb) && hullsOverlap(ta, tb, 1e-3f)) return true;
    }
    return false;
  };
  std::vector<uint32_t> cells;
  std::vector<ScreenExtent> ext;
  for (const std::vector<uint32_t>& pg : part_groups) {
    cells.clear();
    for (uint32_t p : pg)
      for (uint32_t c = s.part_cell_first[p]; c < s.part_cell_first[p + 1]; ++c) cells.push_back(c);
    ext.resize(cells.size());
    for (size_t i = 0; i < cells.size(); ++i) ext[i] = vg.extent(s.cell_box[cells[i]]);
    auto relation = [&](uint32_t i, uint32_t j) -> int {
      const uint32_t a = cells[i], b = cells[j];
      const int z = orderOf(ext[i], ext[j]);
      if (z != 2) return z;
      // Only pairs that really overlap on screen constrain the order: neighbours on one sheet
      // of the surface merely touch, and constraints between them would form cycles.
      if (!cellsOverlap(a, b)) return 0;
      const int box = vg.boxOrder(s.cell_box[a], s.cell_box[b]);
      if (box != 0) return box;
      const auto first = s.neighbours.begin() + s.neighbour_first[a];
      const auto last = s.neighbours.begin() + s.neighbour_first[a + 1];
      const auto it = std::lower_bound(first, last, b, [](const CellNeighbour& x, uint32_t v) {
        return x.other < v;
      });
      if (it != last && it->other == b && it->separable) {
        const int side = vg.negativeFirst(it->plane);
        return side;
      }
      return 2;
    };
    const std::vector<std::vector<uint32_t>> groups =
        cells.size() == 1 ? std::vector<std::vector<uint32_t>>{{0}}
                          : orderNodes(ext, width, height, 8, relation, &order.pairs_tested,
                                       &order.merged_pairs);
    for (const std::vector<uint32_t>& g : groups) {
      for (uint32_t i : g) order.cells.push_back(cells[i]);
      order.largest_group = std::max(order.largest_group, uint32_t(g.size()));
      order.group_first.push_back(uint32_t(order.cells.size()));
    }
  }
  return order;
}

}  // namespace strata
