// Per-view ordering of convex cells (engine side of the convex-cells method): the cells of every
// instance, grouped where no order exists, sorted so that no group is drawn before a group that
// can be in front of it at some pixel. No OpenCL here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "preprocess/convex_cells.h"
#include "preprocess/scene/camera.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

// A neighbour of a cell (their boxes overlap): the other cell and, if separable, a world-space
// plane with this cell on the negative side and the other on the positive side.
struct CellNeighbour {
  uint32_t other = 0;
  bool separable = false;
  CellPlane plane;
};

// The mesh a part's cells are decomposed on: the part's mesh in its own (object) space when the
// geometry carries the meshes, else the part's world-space triangles (local_indices holds the
// re-based indices then). Cache files are keyed on this view.
MeshView cellMeshView(const WorldGeometry& geometry, const GeometryPart& part,
                      std::vector<uint32_t>& local_indices, bool* object_space);

// The cells of a whole world geometry (every instance of every mesh), built once per geometry.
struct CellScene {
  std::vector<uint32_t> cell_first;      // cellCount() + 1 offsets into cell_triangles
  std::vector<uint32_t> cell_triangles;  // world triangle ids, grouped by cell
  std::vector<uint32_t> cell_part;
  std::vector<uint8_t> triangle_flip;  // per world triangle: wound inwards in its cell
  std::vector<Bounds> cell_box;        // world-space bounds
  // The world-space vertices of the scene, each projected once per view however many cells
  // share it.
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> cell_vertex_first;  // cellCount() + 1 offsets into cell_vertex_index
  std::vector<uint32_t> cell_vertex_index;  // each cell's distinct corners, indices into vertices
  std::vector<uint16_t> cell_corners;       // per cell triangle: 3 indices into its corners
  std::vector<uint32_t> part_cell_first;    // parts + 1 offsets: a part's cells are contiguous
  std::vector<uint32_t> part_vertex_begin, part_vertex_end;  // per part: the vertices its cells use
  std::vector<Bounds> part_box;
  std::vector<uint32_t> neighbour_first;  // cellCount() + 1 offsets into neighbours
  std::vector<CellNeighbour> neighbours;  // pairs with overlapping boxes, listed from both cells
  // Coincident triangles (CellDecomposition::cell_leader): per cell, the first cell of its class
  // (itself but for copies, which have no neighbours and are drawn right after it); empty when
  // no mesh repeats a triangle.
  std::vector<uint32_t> cell_leader;
  uint64_t copy_cells = 0;
  // Per part: its mesh had more pairs than the bound (CellPreprocess::unpaired), so its cells,
  // and those of every part overlapping it, are drawn as one merged group without pairs.
  std::vector<uint8_t> part_unpaired;
  uint32_t unpaired_parts = 0;
  uint64_t separable_pairs = 0, inseparable_pairs = 0;
  CellGrid grid;  // the uniform grid of the largest mesh
  double preprocess_ms = 0.0;
  bool from_cache = true;
  DecomposeMode mode = DecomposeMode::Strict;

  uint32_t cellCount() const { return uint32_t(cell_part.size()); }
  bool isCopy(uint32_t c) const { return !cell_leader.empty() && cell_leader[c] != c; }
  // Decomposes every mesh once (through the cache) and maps the cells onto every instance.
  static CellScene build(const WorldGeometry& geometry, const DecomposeOptions& options,
                         const std::string& cache_dir);
};

// The draw order for one view: groups in visibility order, each a list of cells, and passes:
// runs of consecutive groups no two of which overlap on screen, so a pixel sees at most one
// group per pass (the paper's parts merged per viewpoint). Groups are listed pass by pass.
struct CellOrder {
  std::vector<uint32_t> cells;        // cell ids in drawing order
  std::vector<uint32_t> group_first;  // groupCount() + 1 offsets into cells
  std::vector<uint32_t> group_pass;   // per group, non-decreasing
  std::vector<glm::ivec4>
      group_rect;  // per group: pixels x0, y0, x1, y1 it may cover (x0 > x1: none)
  uint32_t passes = 0;
  uint32_t largest_group = 0;  // cells
  // The exact fall-back: groups of more than one cell (composited with a sorted per-pixel
  // budget instead of two layers) and the cells in them.
  uint32_t merged_groups = 0, merged_cells = 0;
  uint64_t pairs_tested = 0;  // pairs examined: cells sharing a pixel centre, parts whose
                              // screen rectangles overlap
  uint64_t merged_pairs = 0;  // overlapping pairs with no order: drawn as one group
  // Instances so many and so small on screen that their rectangles overlap dozens of others
  // each: every instance was ordered cell by cell, as one group of parts (level 2 only).
  bool crowded = false;
  // Per 8x8 screen tile (row by row, (width + 7) / 8 a row): the passes, ascending, at which
  // the composite starts a new segment of the tile's list. Consecutive passes that share no
  // pixel centre inside a tile are composited there in one segment (one raster and one
  // composite step instead of one per pass). Both empty: every pass is a segment of its own.
  std::vector<uint32_t> tile_break_first;  // tiles + 1 offsets into tile_breaks
  std::vector<uint32_t> tile_breaks;
  uint64_t tile_passes = 0;  // (tile, pass) pairs that may cover a pixel centre; the segments
                             // are tile_breaks.size()
  // Host time of the order's steps, ms: projecting the cells and rasterizing their pixel masks,
  // finding the pairs that share a pixel centre with their relations, the graph and the passes
  // (instances included), and the tile segments.
  double project_ms = 0.0, pairs_ms = 0.0, graph_ms = 0.0, segments_ms = 0.0;
  // Of project_ms and pairs_ms: the time in the device's calls (uploads, kernels, downloads).
  double device_ms = 0.0;
  uint32_t device_mask_cells = 0;  // cells whose pixel masks the device computed
  uint64_t device_pairs = 0;       // pairs of cells the device found and related

  uint32_t groupCount() const { return group_first.empty() ? 0 : uint32_t(group_first.size() - 1); }
};

// The pixel masks of the order computed off the host: engine/cells/cell_masks_device.h does it on the
// OpenCL device, for the cells whose triangles all take the float setup of strata_shared.h
// (st_cover_setup), with the host's bits. Called from the thread that orders, one call per
// group of parts; the scene is the one being ordered.
class CellMaskDevice {
 public:
  virtual ~CellMaskDevice() = default;
  struct Request {
    const glm::vec2* screen = nullptr;  // pixel positions of the scene's vertices first_vertex ..
    uint32_t first_vertex = 0, vertex_count = 0;
    int width = 0, height = 0;                       // the image
    const std::vector<uint32_t>* cells = nullptr;    // per node: the cell
    const std::vector<glm::ivec4>* rects = nullptr;  // per node: its pixels x0, y0, x1, y1
    // nodes + 1 offsets into the masks: a node's entries are the 8x8 tiles its rectangle
    // touches, row by row.
    const std::vector<uint32_t>* entry_first = nullptr;
  };
  // Writes every entry's mask: bit (y % 8) * 8 + x % 8 for each centre (x, y) of the tile that
  // a triangle of the node's cell may cover. Throws Error on a device fault.
  virtual void cover(const Request& request, std::vector<uint64_t>& masks) = 0;

  // The pairs of nodes whose masks share a centre, with their relation (the order's rules).
  struct PairRequest {
    // Every node's masks as entries of four words (tile, node, mask low, mask high), node by
    // node (node_first: nodes + 1 offsets) and each node's in tile order; the same entries
    // grouped by tile, each tile's in node order (tile_position: each entry's place there;
    // tile_end: per screen tile, one past its last entry, read for the tiles listed only).
    const uint32_t* by_node = nullptr;
    const uint32_t* by_tile = nullptr;
    const uint32_t* tile_position = nullptr;
    const uint32_t* tile_end = nullptr;
    const uint32_t* node_first = nullptr;
    uint32_t entries = 0, tiles = 0, nodes = 0;
    const uint32_t* node_cell = nullptr;    // per node: its cell
    const glm::vec2* node_depth = nullptr;  // per node: its view depth range (min, max)
    glm::vec3 eye{0.0f}, forward{0.0f};
    bool perspective = true;
  };
  // Each pair (w, v), w < v, once: out gets w and v | code << 30 (code 1: w first, 2: v first,
  // 3: no order known, 0: no order needed). Throws Error on a device fault.
  virtual void pairs(const PairRequest& request, std::vector<uint32_t>& out) = 0;
  // Groups of parts with fewer cells than this are left to the host (a call has a fixed cost).
  virtual uint32_t minCells() const { return 256; }
};

// The threads the order's parallel steps use at most: setCellOrderThreads(n) sets it for every
// later order (0: the default, the machine's cores up to eight).
void setCellOrderThreads(unsigned threads);
unsigned cellOrderThreads();

// tile_segments false: leave the tile segments empty (a composite that does not use them, the
// serial one, is to draw the order), which also saves gathering the passes' tile masks.
// device_masks: where the pixel masks of most cells are computed (null: all on the host); the
// order is the same either way.
CellOrder orderCells(const CellScene& scene, const Camera& camera, int width, int height,
                     bool tile_segments = true, CellMaskDevice* device_masks = nullptr);

}  // namespace strata
