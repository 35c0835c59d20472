// The cells of a scene (CellScene::build): one decomposition per mesh, cached, placed per
// instance in world space.
#include "engine/cells/cell_order.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>

#include "preprocess/core/threads.h"

namespace strata {

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

namespace {

// One decomposition per mesh, in the mesh's own space when the geometry has it (so moving an
// instance neither re-decomposes it nor writes a new cache file), else on its first instance.
// Convexity and plane sides are invariant under the affine maps between them.
struct MeshCells {
  CellPreprocess prep;
  glm::mat4 inverse_first{1.0f};     // world space of first_part -> the decomposed space
  uint32_t first_part = UINT32_MAX;  // the part decomposed in its own world space, if any
};

// Every mesh's cells, decomposed or read from the cache; s learns whether all came from it and
// the grid of the largest part.
std::map<uint32_t, MeshCells> decomposeMeshes(const WorldGeometry& geo,
                                              const std::vector<GeometryPart>& parts,
                                              const DecomposeOptions& options,
                                              const std::string& cache_dir, CellScene& s) {
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
  return meshes;
}

// Appends cell c of part pi to s: its triangles, their corners as indices into the cell's
// distinct vertices, the triangles' facing and the cell's box (returned); widens the part's
// vertex range [vertex_begin, vertex_end).
Bounds addCell(const WorldGeometry& geo, const GeometryPart& part, uint32_t pi,
               const CellDecomposition& cells, uint32_t c, CellScene& s, uint32_t& vertex_begin,
               uint32_t& vertex_end) {
  Bounds box;
  std::vector<uint32_t> corners;
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
        glm::dot(n, centre - p0) > 1e-9 * glm::length(n) * glm::length(glm::dvec3(box.max - box.min))
            ? 1
            : 0;
  }
  s.cell_first.push_back(uint32_t(s.cell_triangles.size()));
  s.cell_part.push_back(pi);
  s.cell_box.push_back(box);
  return box;
}

// Part pi's cell pairs as neighbours of its cells (its first cell is `base`), the separating
// planes mapped from the decomposed space into the part's world space.
void addPartPairs(const MeshCells& mc, const GeometryPart& part, uint32_t pi, uint32_t base,
                  CellScene& s, std::vector<std::vector<CellNeighbour>>& neighbours) {
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

}  // namespace

CellScene CellScene::build(const WorldGeometry& geo, const DecomposeOptions& options,
                           const std::string& cache_dir) {
  const auto t0 = std::chrono::steady_clock::now();
  CellScene s;
  s.mode = options.mode;
  std::vector<GeometryPart> parts = geo.parts;
  if (parts.empty())
    parts.push_back(
        {0, 0, geo.triangleCount(), 0, uint32_t(geo.positions.size()), glm::mat4(1.0f)});
  const std::map<uint32_t, MeshCells> meshes =
      decomposeMeshes(geo, parts, options, cache_dir, s);

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
    for (uint32_t c = 0; c < cells.cellCount(); ++c) {
      const Bounds box = addCell(geo, part, pi, cells, c, s, vertex_begin, vertex_end);
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
    addPartPairs(mc, part, pi, base, s, neighbours);
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

}  // namespace strata
