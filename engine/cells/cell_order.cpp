// Per-view ordering of convex cells, in two levels: instances (parts) first, then the cells of
// each group of instances whose boxes overlap. Cells of one mesh come from the preprocessing
// (decomposition and the view-independent separating planes of every pair of cells with
// overlapping boxes). For a view, the cells are rasterized into per-tile pixel masks, and every
// two cells that may share a pixel centre get an order from, in turn: disjoint view-depth
// intervals; disjoint boxes (an axis plane); their separating plane (the side the eye is on).
// Pairs with no such relation are merged into one group, and so are cycles (strongly connected
// components); the groups come out in topological order, nearest first.
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
#include <queue>
#include <thread>

#include <glm/gtc/matrix_inverse.hpp>

#include "kernels/strata_shared.h"
#include "preprocess/core/threads.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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

  s.vertices = geo.positions;
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
    uint32_t vertex_begin = UINT32_MAX, vertex_end = 0;
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
        s.cell_vertex_index.push_back(v);
        centre += glm::dvec3(geo.positions[v]);
        vertex_begin = std::min(vertex_begin, v);
        vertex_end = std::max(vertex_end, v + 1);
      }
      centre /= double(std::max<size_t>(1, distinct.size()));
      s.cell_vertex_first.push_back(uint32_t(s.cell_vertex_index.size()));
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
    if (!cells.cell_leader.empty()) {
      for (uint32_t c = uint32_t(s.cell_leader.size()); c < base; ++c) s.cell_leader.push_back(c);
      for (uint32_t c = 0; c < cells.cellCount(); ++c) {
        s.cell_leader.push_back(base + cells.cell_leader[c]);
        s.copy_cells += cells.isCopy(c) ? 1 : 0;
      }
    }
    s.part_cell_first.push_back(s.cellCount());
    s.part_box.push_back(part_box);
    s.part_unpaired.push_back(mc.prep.unpaired ? 1 : 0);
    s.unpaired_parts += mc.prep.unpaired ? 1 : 0;
    s.part_vertex_begin.push_back(std::min(vertex_begin, vertex_end));
    s.part_vertex_end.push_back(vertex_end);
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
  if (!s.cell_leader.empty())
    for (uint32_t c = uint32_t(s.cell_leader.size()); c < s.cellCount(); ++c)
      s.cell_leader.push_back(c);
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
    return st_order_negative_first(p.n.x, p.n.y, p.n.z, p.d, &eye.x, &forward.x,
                                   perspective ? 1 : 0);
  }

  // Order from disjoint boxes: +1 a first, -1 b first, 0 none found (boxes overlap).
  int boxOrder(const Bounds& a, const Bounds& b) const {
    return st_order_boxes(&a.min.x, &a.max.x, &b.min.x, &b.max.x, &eye.x, &forward.x,
                          perspective ? 1 : 0);
  }
};

// floor and ceil of a pixel coordinate, saturated (strata_shared.h).
inline int floorPixel(float v) { return st_cover_floor(v); }
inline int ceilPixel(float v) { return st_cover_ceil(v); }

struct CoverageSink {
  int tx0, ty0, tiles_w;           // the cell's tile rectangle (origin and width)
  uint64_t* masks;                 // per tile of that rectangle, zero before the cell
  std::vector<uint32_t>* touched;  // the tiles of the rectangle made non-zero, in order

  void orTile(int tx, int ty, uint64_t m) {
    const uint32_t i = uint32_t(ty - ty0) * uint32_t(tiles_w) + uint32_t(tx - tx0);
    if (m && !masks[i]) touched->push_back(i);
    masks[i] |= m;
  }
  // Pixels x0..x1, y0..y1 of one tile.
  void setRect(int x0, int y0, int x1, int y1) {
    const uint64_t row = ((uint64_t(2) << (x1 & 7)) - 1) & ~((uint64_t(1) << (x0 & 7)) - 1);
    uint64_t m = 0;
    for (int y = y0 & 7; y <= (y1 & 7); ++y) m |= row << (y * 8);
    orTile(x0 >> 3, y0 >> 3, m);
  }
};

// A projected triangle set up for coverTriangle and coverTriangleRows (StCoverEdges).
using CoverEdges = StCoverEdges;

// Whether the centre (x0 + xf, y0 + yf) is inside every edge of t (st_cover_inside).
inline bool centreInside(const CoverEdges& t, float xf, float yf) {
  return st_cover_inside(&t, xf, yf) != 0;
}

#if defined(__SSE2__)
// centreInside for four centres of a row: ex * xf of columns x .. x + 3 (fourColumns), as bits.
struct FourColumns {
  __m128 ax[3];
  FourColumns(const CoverEdges& t, int x) {
    const __m128 xf = _mm_add_ps(_mm_set1_ps(float(x - t.x0)), _mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f));
    for (int i = 0; i < 3; ++i) ax[i] = _mm_mul_ps(_mm_set1_ps(t.ex[i]), xf);
  }
  uint32_t inside(const CoverEdges& t, float yf) const {
    const __m128 zero = _mm_setzero_ps();
    __m128 in = _mm_cmpge_ps(_mm_add_ps(ax[0], _mm_set1_ps(t.ey[0] * yf + t.ec[0])), zero);
    in = _mm_and_ps(in, _mm_cmpge_ps(_mm_add_ps(ax[1], _mm_set1_ps(t.ey[1] * yf + t.ec[1])), zero));
    in = _mm_and_ps(in, _mm_cmpge_ps(_mm_add_ps(ax[2], _mm_set1_ps(t.ey[2] * yf + t.ec[2])), zero));
    return uint32_t(_mm_movemask_ps(in));
  }
};
#endif

// The centres x = xa..xb, y = ya..yb of one tile (at most 8 x 8) inside every edge of t, as
// bits (y & 7) * 8 + (x & 7).
inline uint64_t tileCoverage(const CoverEdges& t, int xa, int xb, int ya, int yb) {
  uint64_t mask = 0;
#if defined(__SSE2__)
  const int first = xa & ~7;  // the tile's eight columns, in two rows of four lanes
  const FourColumns lo(t, first), hi(t, first + 4);
  const uint32_t columns = ((2u << (xb - first)) - 1u) & ~((1u << (xa - first)) - 1u);
  for (int y = ya; y <= yb; ++y) {
    const float yf = float(y - t.y0);
    const uint32_t bits = lo.inside(t, yf) | (hi.inside(t, yf) << 4);
    mask |= uint64_t(bits & columns) << ((y & 7) * 8);
  }
#else
  for (int y = ya; y <= yb; ++y)
    for (int x = xa; x <= xb; ++x)
      if (centreInside(t, float(x - t.x0), float(y - t.y0)))
        mask |= uint64_t(1) << ((y & 7) * 8 + (x & 7));
#endif
  return mask;
}

// Sets up triangle (a, b, d) so that its edge functions mark the centres (x + 0.5, y + 0.5) of
// the clipped pixel rectangle that lie within ST_COVER_SLACK of it. The edge functions are left
// unnormalised, each widened by the slack times its L1 length (at least the Euclidean one), so
// no square root is taken; a triangle with no area covers the centres next to its segment
// (within its bounds). false: the triangle is within the slack of no centre of the image.
bool setupCover(glm::vec2 a, glm::vec2 b, glm::vec2 d, int width, int height, CoverEdges& t) {
  // A small triangle near the image (most of them) in float, as the device sets it up too.
  const int kind = st_cover_setup(a.x, a.y, b.x, b.y, d.x, d.y, width, height, &t);
  if (kind != ST_COVER_WIDE) return kind == ST_COVER_SET_UP;
  // Large or far off: set up in double precision (corners far off the image would lose the
  // slack to rounding).
  const glm::dvec2 da(a), db(b), dd(d);
  const double area = (db.x - da.x) * (dd.y - da.y) - (dd.x - da.x) * (db.y - da.y);
  const glm::dvec2 p[3] = {da, area < 0.0 ? dd : db, area < 0.0 ? db : dd};
  const glm::dvec2 origin(double(t.x0) + 0.5, double(t.y0) + 0.5);
  for (int i = 0; i < 3; ++i) {
    const glm::dvec2 e = p[(i + 1) % 3] - p[i];
    t.ex[i] = float(-e.y);
    t.ey[i] = float(e.x);
    t.ec[i] = float(-e.y * (origin.x - p[i].x) + e.x * (origin.y - p[i].y) +
                    ST_COVER_SLACK * (std::fabs(e.x) + std::fabs(e.y)));
  }
  return true;
}

#if defined(__SSE2__)
// setupCover for four triangles at once (corners a, b, d of lane i in a*[i], b*[i], d*[i]):
// lane i of the result is set up in t[i] when bit i of the returned `done` is set; bit i of
// `empty` says the lane covers no centre; a lane in neither (a large triangle, or one far off
// the image) is left to setupCover. Every value is rounded as setupCover's float path rounds
// it (the same operations in the same order; std::min(a, b) is _mm_min_ps(b, a)), so the
// coverage is bit for bit the same.
struct CoverSetup4 {
  uint32_t done = 0, empty = 0;
};
inline __m128i maxZero(__m128i v) {
  return _mm_and_si128(v, _mm_cmpgt_epi32(v, _mm_setzero_si128()));
}
inline __m128i minInt(__m128i v, __m128i limit) {
  const __m128i over = _mm_cmpgt_epi32(v, limit);
  return _mm_or_si128(_mm_and_si128(over, limit), _mm_andnot_si128(over, v));
}
// saturatePixel, ceilPixel and floorPixel in four lanes (NaN saturates low, as there).
inline __m128 saturatePixel4(__m128 v) {
  return _mm_min_ps(_mm_max_ps(v, _mm_set1_ps(-1.0e7f)), _mm_set1_ps(1.0e7f));
}
inline __m128i ceilPixel4(__m128 v) {
  v = saturatePixel4(v);
  const __m128i i = _mm_cvttps_epi32(v);
  return _mm_sub_epi32(i, _mm_castps_si128(_mm_cmplt_ps(_mm_cvtepi32_ps(i), v)));
}
inline __m128i floorPixel4(__m128 v) {
  v = saturatePixel4(v);
  const __m128i i = _mm_cvttps_epi32(v);
  return _mm_add_epi32(i, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(i), v)));
}
inline __m128 absPs(__m128 v) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), v); }
inline __m128 selectPs(__m128 mask, __m128 a, __m128 b) {  // mask ? a : b
  return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b));
}

CoverSetup4 setupCover4(const float* ax, const float* ay, const float* bx, const float* by,
                        const float* dx, const float* dy, int width, int height, CoverEdges* t) {
  const __m128 Ax = _mm_loadu_ps(ax), Ay = _mm_loadu_ps(ay), Bx = _mm_loadu_ps(bx),
               By = _mm_loadu_ps(by), Dx = _mm_loadu_ps(dx), Dy = _mm_loadu_ps(dy);
  const __m128 fx0 = _mm_min_ps(_mm_min_ps(Dx, Bx), Ax), fx1 = _mm_max_ps(_mm_max_ps(Dx, Bx), Ax);
  const __m128 fy0 = _mm_min_ps(_mm_min_ps(Dy, By), Ay), fy1 = _mm_max_ps(_mm_max_ps(Dy, By), Ay);
  const __m128 half = _mm_set1_ps(0.5f), slack = _mm_set1_ps(ST_COVER_SLACK);
  const __m128i x0 = maxZero(ceilPixel4(_mm_sub_ps(_mm_sub_ps(fx0, half), slack)));
  const __m128i x1 =
      minInt(floorPixel4(_mm_add_ps(_mm_sub_ps(fx1, half), slack)), _mm_set1_epi32(width - 1));
  const __m128i y0 = maxZero(ceilPixel4(_mm_sub_ps(_mm_sub_ps(fy0, half), slack)));
  const __m128i y1 =
      minInt(floorPixel4(_mm_add_ps(_mm_sub_ps(fy1, half), slack)), _mm_set1_epi32(height - 1));
  CoverSetup4 r;
  r.empty = uint32_t(_mm_movemask_ps(
      _mm_castsi128_ps(_mm_or_si128(_mm_cmpgt_epi32(x0, x1), _mm_cmpgt_epi32(y0, y1)))));
  const __m128 span = _mm_set1_ps(ST_COVER_FLOAT_SPAN), reach = _mm_set1_ps(ST_COVER_FLOAT_REACH);
  const __m128 small =
      _mm_and_ps(_mm_and_ps(_mm_cmple_ps(_mm_sub_ps(fx1, fx0), span),
                            _mm_cmple_ps(_mm_sub_ps(fy1, fy0), span)),
                 _mm_and_ps(_mm_cmplt_ps(absPs(fx0), reach), _mm_cmplt_ps(absPs(fy0), reach)));
  r.done = uint32_t(_mm_movemask_ps(small)) & ~r.empty;
  if (!r.done) return r;
  const __m128 ox = _mm_add_ps(_mm_cvtepi32_ps(x0), half),
               oy = _mm_add_ps(_mm_cvtepi32_ps(y0), half);
  const __m128 rax = _mm_sub_ps(Ax, ox), ray = _mm_sub_ps(Ay, oy);
  const __m128 rbx = _mm_sub_ps(Bx, ox), rby = _mm_sub_ps(By, oy);
  const __m128 rdx = _mm_sub_ps(Dx, ox), rdy = _mm_sub_ps(Dy, oy);
  const __m128 area = _mm_sub_ps(_mm_mul_ps(_mm_sub_ps(rbx, rax), _mm_sub_ps(rdy, ray)),
                                 _mm_mul_ps(_mm_sub_ps(rdx, rax), _mm_sub_ps(rby, ray)));
  const __m128 flip = _mm_cmplt_ps(area, _mm_setzero_ps());
  const __m128 px[3] = {rax, selectPs(flip, rdx, rbx), selectPs(flip, rbx, rdx)};
  const __m128 py[3] = {ray, selectPs(flip, rdy, rby), selectPs(flip, rby, rdy)};
  alignas(16) float ex[3][4], ey[3][4], ec[3][4];
  alignas(16) int32_t bounds[4][4];
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const __m128 exv = _mm_sub_ps(px[j], px[i]), eyv = _mm_sub_ps(py[j], py[i]);
    _mm_store_ps(ex[i], _mm_xor_ps(eyv, _mm_set1_ps(-0.0f)));
    _mm_store_ps(ey[i], exv);
    _mm_store_ps(ec[i], _mm_add_ps(_mm_sub_ps(_mm_mul_ps(eyv, px[i]), _mm_mul_ps(exv, py[i])),
                                   _mm_mul_ps(slack, _mm_add_ps(absPs(exv), absPs(eyv)))));
  }
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[0]), x0);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[1]), x1);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[2]), y0);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[3]), y1);
  for (int l = 0; l < 4; ++l) {
    if (!(r.done >> l & 1u)) continue;
    CoverEdges& e = t[l];
    e.x0 = bounds[0][l];
    e.x1 = bounds[1][l];
    e.y0 = bounds[2][l];
    e.y1 = bounds[3][l];
    for (int i = 0; i < 3; ++i) {
      e.ex[i] = ex[i][l];
      e.ey[i] = ey[i][l];
      e.ec[i] = ec[i][l];
    }
  }
  return r;
}
#endif

// Adds the centres of a set-up triangle to the tiles of `sink`.
void coverTriangle(const CoverEdges& t, CoverageSink& sink) {
  const int x0 = t.x0, x1 = t.x1, y0 = t.y0, y1 = t.y1;
  const float *ex = t.ex, *ey = t.ey, *ec = t.ec;
  const bool large = (x1 - x0 + 1) * (y1 - y0 + 1) > 128;
  for (int ty = y0 >> 3; ty <= y1 >> 3; ++ty) {
    const int ya = std::max(y0, ty * 8), yb = std::min(y1, ty * 8 + 7);
    // The columns these rows can cover: an edge not close to horizontal is negative left (or
    // right) of where its largest value over the rows crosses zero. A pixel of margin keeps the
    // range a superset of the centres the tests below pass (their float rounding is orders of
    // magnitude smaller there), so the skipped tiles would have come out empty.
    int first = x0, last = x1;
    if (large) {
      for (int i = 0; i < 3; ++i) {
        const double a = ex[i], b = ey[i];
        if (!(std::fabs(a) >= 1e-3 * (std::fabs(a) + std::fabs(b)))) continue;
        const double top = std::max(b * double(ya - y0), b * double(yb - y0)) + double(ec[i]);
        const double cross = double(x0) - top / a;
        if (a > 0.0) {
          if (cross - 1.0 > double(first))
            first = cross - 1.0 > double(x1) ? x1 + 1 : int(cross - 1.0);
        } else if (cross + 1.0 < double(last)) {
          last = cross + 1.0 < double(x0) ? x0 - 1 : int(std::ceil(cross + 1.0));
        }
      }
      if (first > last) continue;
    }
    for (int tx = first >> 3; tx <= last >> 3; ++tx) {
      const int xa = std::max(x0, tx * 8), xb = std::min(x1, tx * 8 + 7);
      if (large) {
        // Linear edge functions: a part of the tile whose four corner centres are inside every
        // edge is covered whole; one whose corners are all outside one edge is missed whole.
        bool all_in = true, missed = false;
        for (int i = 0; i < 3 && !missed; ++i) {
          const float ax = ex[i] * float(xa - x0), bx = ex[i] * float(xb - x0);
          const float ay = ey[i] * float(ya - y0) + ec[i], by = ey[i] * float(yb - y0) + ec[i];
          const float lo = std::min(std::min(ax + ay, bx + ay), std::min(ax + by, bx + by));
          const float hi = std::max(std::max(ax + ay, bx + ay), std::max(ax + by, bx + by));
          missed = hi < 0.0f;
          all_in = all_in && lo >= 0.0f;
        }
        if (missed) continue;
        if (all_in) {
          sink.setRect(xa, ya, xb, yb);
          continue;
        }
      }
      // Centre by centre, a row of the tile at a time.
      sink.orTile(tx, ty, tileCoverage(t, xa, xb, ya, yb));
    }
  }
}

// A small cell's centres as one 64-bit row per pixel row: bit x - bx of rows[y - by]. Adds a
// set-up triangle's centres (all within 64 columns from bx and 64 rows from by), four columns
// at a time from the triangle's first.
void coverTriangleRows(const CoverEdges& t, int bx, int by, uint64_t* rows) {
#if defined(__SSE2__)
  for (int cx = t.x0; cx <= t.x1; cx += 4) {
    const FourColumns four(t, cx);
    const uint32_t valid = t.x1 - cx >= 3 ? 15u : (2u << (t.x1 - cx)) - 1u;
    for (int y = t.y0; y <= t.y1; ++y)
      rows[y - by] |= uint64_t(four.inside(t, float(y - t.y0)) & valid) << (cx - bx);
  }
#else
  for (int y = t.y0; y <= t.y1; ++y)
    for (int x = t.x0; x <= t.x1; ++x)
      if (centreInside(t, float(x - t.x0), float(y - t.y0)))
        rows[y - by] |= uint64_t(1) << (x - bx);
#endif
}

// out[j] byte k = in[k] byte j: eight 64-bit pixel rows (bit x of row k) as the masks of the
// eight 8x8 tiles they cross (bit k * 8 + (x & 7) of tile x / 8).
inline void transposeBytes8x8(const uint64_t* in, uint64_t* out) {
#if defined(__SSE2__)
  auto row = [&](int k) { return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(in + k)); };
  const __m128i a0 = _mm_unpacklo_epi8(row(0), row(1)), a1 = _mm_unpacklo_epi8(row(2), row(3));
  const __m128i a2 = _mm_unpacklo_epi8(row(4), row(5)), a3 = _mm_unpacklo_epi8(row(6), row(7));
  const __m128i b0 = _mm_unpacklo_epi16(a0, a1), b1 = _mm_unpackhi_epi16(a0, a1);
  const __m128i b2 = _mm_unpacklo_epi16(a2, a3), b3 = _mm_unpackhi_epi16(a2, a3);
  __m128i* o = reinterpret_cast<__m128i*>(out);
  _mm_storeu_si128(o + 0, _mm_unpacklo_epi32(b0, b2));
  _mm_storeu_si128(o + 1, _mm_unpackhi_epi32(b0, b2));
  _mm_storeu_si128(o + 2, _mm_unpacklo_epi32(b1, b3));
  _mm_storeu_si128(o + 3, _mm_unpackhi_epi32(b1, b3));
#else
  for (int j = 0; j < 8; ++j) {
    uint64_t m = 0;
    for (int k = 0; k < 8; ++k) m |= ((in[k] >> (8 * j)) & 0xFFu) << (8 * k);
    out[j] = m;
  }
#endif
}

// +1 a before b, -1 b before a, 0 any order, 2 unknown.
int orderOf(const ScreenExtent& ea, const ScreenExtent& eb) {
  if (ea.zmax <= eb.zmin) return 1;
  if (eb.zmax <= ea.zmin) return -1;
  return 2;
}

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
bool forEachOverlapInBin(const std::vector<ScreenExtent>& ext, const ScreenBins& bins, int bx,
                         int by, std::vector<uint32_t>& list, Visit&& visit) {
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
std::vector<Constraints> findConstraints(const std::vector<ScreenExtent>& ext,
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
bool rectOverlapsPast(const std::vector<ScreenExtent>& ext, const ScreenBins& bins,
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

// Orders nodes from the constraints found between them (by one or more threads, in any order:
// the result depends on the set of constraints only).
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
  if (ranked < nodes) {
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
    groups = ranked + comps;
  }
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

// Passes of groups in drawing order: a group's pass is one more than that of every earlier
// group it overlaps (at least `base`). Returns the last pass used (base - 1 if none).
int64_t assignPasses(const NodeOrder& order, int64_t base, std::vector<int64_t>& pass) {
  pass.resize(order.groupCount());
  int64_t last = base - 1;
  for (uint32_t g = 0; g < order.groupCount(); ++g) {
    pass[g] = base + int64_t(order.level[g]);
    last = std::max(last, pass[g]);
  }
  return last;
}

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
double lapMs(std::chrono::steady_clock::time_point& t0) {
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
    if (e.zmax < vg_.near_distance) return;  // wholly behind the near plane: empty
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
      return;
    }
    // The pixels whose centres the corners' span can reach, widened by the coverage slack.
    e.x0 = std::max(0, ceilPixel(px0 - 0.5f - ST_COVER_SLACK));
    e.y0 = std::max(0, ceilPixel(py0 - 0.5f - ST_COVER_SLACK));
    e.x1 = std::min(vg_.width - 1, floorPixel(px1 - 0.5f + ST_COVER_SLACK));
    e.y1 = std::min(vg_.height - 1, floorPixel(py1 - 0.5f + ST_COVER_SLACK));
    if (e.x0 > e.x1 || e.y0 > e.y1) return;  // covers no pixel centre
    // Every triangle of a cell this small and near takes the float setup: the device can mark
    // its centres with the host's bits.
    if (use_device_ && px1 - px0 <= ST_COVER_FLOAT_SPAN && py1 - py0 <= ST_COVER_FLOAT_SPAN &&
        px0 > -ST_COVER_FLOAT_REACH && py0 > -ST_COVER_FLOAT_REACH && px1 < ST_COVER_FLOAT_REACH &&
        py1 < ST_COVER_FLOAT_REACH) {
      on_device_[node] = 1;
      return;
    }
    const uint32_t n = s_.cell_first[c + 1] - s_.cell_first[c];
    const uint16_t* corners = &s_.cell_corners[size_t(s_.cell_first[c]) * 3];
    CoverEdges t;
    // Triangle k of the cell set up in t (false: it is near no pixel centre of the image).
    auto setUp = [&](uint32_t k) {
      return setupCover(h[corners[3 * k]], h[corners[3 * k + 1]], h[corners[3 * k + 2]], vg_.width,
                        vg_.height, t);
    };
    const int bx = e.x0 & ~7, by = e.y0 & ~7;
    if (e.x1 - bx < 64 && e.y1 - by < 64) {
      // A small cell (most of a fine mesh's): its centres as rows of bits, then cut into tiles
      // in tile order.
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
          } else if (!(r.empty >> l & 1u) && setUp(k + l)) {
            coverTriangleRows(t, bx, by, rows);
          }
        }
      }
#else
      for (uint32_t k = 0; k < n; ++k)
        if (setUp(k)) coverTriangleRows(t, bx, by, rows);
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
      return;
    }
    // The masks stay zero between cells: only the tiles a cell touched are read and cleared.
    CoverageSink sink{e.x0 >> 3, e.y0 >> 3, (e.x1 >> 3) - (e.x0 >> 3) + 1, nullptr, &touched};
    const int tiles_h = (e.y1 >> 3) - (e.y0 >> 3) + 1;
    if (masks.size() < size_t(sink.tiles_w) * tiles_h) masks.resize(size_t(sink.tiles_w) * tiles_h);
    sink.masks = masks.data();
    touched.clear();
    for (uint32_t k = 0; k < n; ++k)
      if (setUp(k)) coverTriangle(t, sink);
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
    if (copies > 0 && d.count > 1)
      std::sort(drawn.cells.begin() + d.first, drawn.cells.end());
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
