// Convex cells (the convex-polyhedra method, methods/convex-cells.md): a mesh's triangles grouped
// into cells that each lie on the boundary of one convex body, so from any viewpoint a cell has
// at most one front and one back fragment per pixel; the uniform grid that finds cells close
// enough to need a view-independent separating plane; and the versioned cache file of both.
// No OpenCL and no engine types here: this header is public.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/mesh_view.h"
#include "strata/strata.h"

namespace strata {

// DecomposeMode and parseDecomposeMode are public: include/strata/strata.h.
const char* decomposeModeName(DecomposeMode mode);

struct DecomposeOptions {
  DecomposeMode mode = DecomposeMode::Strict;
  // The strict test costs O(n^2) in a cell's size; larger convex patches are split (the
  // renderer merges the pieces back into one ordered group when no plane separates them). A
  // mesh that is convex as a whole (a sphere, a box) is one cell whatever its size.
  uint32_t max_cell_triangles = 1024;
};

// Cell c owns triangles triangle_order[cell_begin[c] .. cell_begin[c + 1]) (indices into the
// mesh's triangles); every triangle belongs to exactly one cell.
// Coincident triangles (the same three corners, in any order or winding; CAD exports and merged
// scans repeat faces), three or more of them, are cells of one triangle each: the lowest triangle of a class first, its
// copies in the cells right after it, in triangle order. cell_leader[c] is the first cell of c's
// class, c itself for every other cell; empty when the mesh repeats no triangle. The copies take
// no part in the pairs: they lie at their first cell's depth and are drawn right after it (equal
// depths in triangle order), so k copies cost k cells, not k^2 pairs.
struct CellDecomposition {
  DecomposeMode mode = DecomposeMode::Strict;
  std::vector<uint32_t> cell_begin;      // cellCount() + 1 offsets
  std::vector<uint32_t> triangle_order;  // a permutation of 0 .. triangle_count - 1
  std::vector<uint32_t> cell_leader;     // empty, or cellCount() entries

  uint32_t cellCount() const { return cell_begin.empty() ? 0 : uint32_t(cell_begin.size() - 1); }
  // Whether cell c is a copy drawn after its class's first cell.
  bool isCopy(uint32_t c) const { return !cell_leader.empty() && cell_leader[c] != c; }
};

// A plane: points x with dot(n, x) + d <= 0 are on its negative side.
struct CellPlane {
  glm::vec3 n{0.0f};
  float d = 0.0f;
};

// Two cells of one mesh whose (slightly inflated) bounding boxes overlap. If separable, every
// vertex of cell a is on or on the negative side of `plane` and every vertex of cell b on or on
// its positive side (within a tolerance of 1e-6 of the mesh's bounding-box diagonal), so from an
// eye on the positive side b is never behind a, and the reverse. Inseparable pairs (overlapping
// hulls, nesting, non-planar shared boundaries) must be drawn in one group.
struct CellPair {
  uint32_t a = 0, b = 0;  // a < b
  bool separable = false;
  CellPlane plane;
};

// The uniform grid over the mesh's bounding box, sized so a grid cell holds few cells.
struct CellGrid {
  glm::ivec3 dims{0};
  glm::vec3 origin{0.0f}, cell_size{0.0f};
};

struct CellPreprocess {
  CellDecomposition cells;
  CellGrid grid;
  // More pairs than the bound (cellPairBound): none are kept, and the renderer draws the mesh's
  // cells as one merged group (exact, a sorted list per pixel) instead of ordering them.
  bool unpaired = false;
  // Every pair of cells whose boxes overlap, sorted by (a, b), copies left out (a copy's pairs
  // are its first cell's).
  std::vector<CellPair> pairs;
  double decompose_seconds = 0.0, pairs_seconds = 0.0;
};

// Seed growing (preprocess/convex_cells.cpp). Zero-area triangles become cells of their own.
CellDecomposition decomposeConvexCells(const MeshView& mesh, const DecomposeOptions& options);

// Whether the triangles of one cell satisfy the strict test (a check for tests and debugging):
// every vertex of the cell is within `tolerance` of or behind every face plane, faces oriented
// consistently, no two coplanar faces overlapping.
bool cellIsStrictlyConvex(const MeshView& mesh, const uint32_t* triangles, size_t count,
                          float tolerance);

// The uniform grid and the separation of every pair of cells with overlapping boxes
// (preprocess/cell_pairs.cpp). Returns false, with no pairs, when there would be more than
// max_pairs (by default cellPairBound of the cells): a mesh of many overlapping cells (thousands
// of large triangles crossing one another) would otherwise cost time and memory quadratic in its
// size.
bool findCellPairs(const MeshView& mesh, const CellDecomposition& cells, CellGrid* grid,
                   std::vector<CellPair>* pairs, uint64_t max_pairs = 0);
// 64 pairs per cell and 2^20 besides: about 30 times what scans and CAD parts need (horse 4.9
// per cell, the builtin hairball 29), and so a cache file of at most about 1.8 KB per cell.
uint64_t cellPairBound(uint32_t cells);

// Decomposition + pairs, read from the cache file of this mesh and options when a valid one
// exists, else built and written there (preprocess/cell_cache.cpp). cache_dir empty: the user's
// cache ($XDG_CACHE_HOME/strata/cells, else ~/.cache/strata/cells). A cache file carries a
// magic, a format version, the key of the mesh content and options, and a checksum; a stale,
// truncated or corrupt file is rebuilt and replaced (written to a temporary name, then renamed),
// never trusted. *from_cache tells which happened.
CellPreprocess loadOrBuildCells(const MeshView& mesh, const DecomposeOptions& options,
                                const std::string& cache_dir, bool* from_cache);
std::string defaultCellCacheDir();
// A cache file's bytes for `result` of this mesh and options, and the parse of such bytes: false
// when they are not a valid, consistent cache of exactly this mesh and these options.
std::vector<char> serializeCellCache(const CellPreprocess& result, const MeshView& mesh,
                                     const DecomposeOptions& options);
bool parseCellCache(std::string_view bytes, const MeshView& mesh, const DecomposeOptions& options,
                    CellPreprocess* out);
// The file loadOrBuildCells uses for this mesh and options.
std::string cellCachePath(const MeshView& mesh, const DecomposeOptions& options,
                          const std::string& cache_dir);

}  // namespace strata
