/* strata_shared.h: constants, record layouts and shading rules shared by the host (C++) and the
 * OpenCL kernels. Every tunable is defined here once; the host prepends this file to every
 * kernel program, so nothing is written twice.
 *
 * Only plain 32-bit scalar members appear in shared structs so that C++ and OpenCL C agree on
 * their layout without packing pragmas. */
#ifndef STRATA_SHARED_H
#define STRATA_SHARED_H

#ifdef __OPENCL_VERSION__
typedef uint st_u32;
typedef int st_i32;
typedef ulong st_u64;
typedef long st_i64;
#define ST_FN inline
/* In a function body: no fused multiply-add, so the kernels round as the host does (built with
 * -ffp-contract=off) and shared rules give the same bits on both sides. */
#define ST_NO_CONTRACT _Pragma("OPENCL FP_CONTRACT OFF")
#else
#define ST_NO_CONTRACT
#include <cmath>
#include <cstdint>
typedef uint32_t st_u32;
typedef int32_t st_i32;
typedef uint64_t st_u64;
typedef int64_t st_i64;
#define ST_FN inline
#endif

/* ---- Screen tiles: one work-group owns one tile (tile ownership, DESIGN.md). ---- */
#define ST_TILE_LOG2 3
#define ST_TILE_SIZE (1 << ST_TILE_LOG2)           /* pixels per tile side */
#define ST_TILE_PIXELS (ST_TILE_SIZE * ST_TILE_SIZE) /* work-items per raster work-group */

/* ---- Fixed-point screen coordinates. ---- */
#define ST_SUBPIXEL_BITS 8
#define ST_SUBPIXEL_ONE (1 << ST_SUBPIXEL_BITS)
/* Largest image side: keeps snapped coordinates and 64-bit edge functions far from overflow. */
#define ST_MAX_IMAGE_SIDE 16384
/* Guard band in pixels around the viewport; vertices beyond it are clipped away in homogeneous
 * space so snapped coordinates stay below 2^30 and edge products below 2^62. */
#define ST_GUARD_BAND_PIXELS 2097152.0f

/* ---- Work-group sizes (fixed, so PoCL compiles each kernel once). ---- */
#define ST_LINEAR_WG 64  /* per-vertex / per-triangle kernels */
#define ST_SCAN_WG 256   /* single work-group exclusive scan over tiles */
/* The serial binners' tile x run tables are stored run by run, each run's column this many
 * words longer than the tiles: columns a multiple of 4 KiB apart fell in one L1 set, and the
 * scan, which reads every run of a tile in turn, missed on every read. */
#define ST_BIN_RUN_PAD 16
#define ST_BIN_SORT_WG 256     /* ordered binning's per-tile sort (cells_bin.cl) */
#define ST_BIN_SORT_KEYS 2048  /* keys it sorts in local memory at once (16 KB) */

/* ---- Per-pixel sort in the linked-list resolve. ---- */
/* Fragments of one pixel are sorted in a private array of this size; deeper pixels fall back to
 * an exact selection walk (O(n^2)) so no depth is ever truncated. */
#define ST_PPLL_SORT_CAPACITY 128
#define ST_PPLL_END 0xFFFFFFFFu
/* A pixel letting less light through than this takes no more fragments where a method stops
 * early (deep ppll pixels, the octree early out): what lies behind changes each 8-bit channel by
 * less than half a step. */
#define ST_OPAQUE_TRANSMITTANCE (0.5f / 255.0f)
/* first_batch of the cells and octree composites: FRESH starts every pixel fresh; SEEDED also
 * takes translucency's inside count and last depth from accum_extra (a distributed share). */
#define ST_FIRST_BATCH_FRESH 1
#define ST_FIRST_BATCH_SEEDED 2

/* ---- Fixed-budget and bucket methods. ---- */
#define ST_MAX_K 256     /* largest per-pixel budget K of abuffer / mdts */
#define ST_BDP_BUCKETS 32 /* depth buckets per pixel of bucket depth peeling */
#define ST_BUCKET_FINE_BINS 1024                        /* bdp2 histogram bins per pixel */
#define ST_BUCKET_FINE_WORDS (ST_BUCKET_FINE_BINS / 32) /* 32-bit occupancy words per pixel */
#define ST_STOCHASTIC_MAX_SAMPLES 64 /* stochastic transparency's samples per pixel, at most */
#define ST_STOCHASTIC_MASK_ROWS 64    /* random sample orders its coverage masks are drawn from */

/* ---- Convex cells. ---- */
#define ST_CELLS_MAX_CLIP_PIECES 7 /* a triangle clipped by 5 planes: a 9-gon, 7 triangles */
/* A composite work-group owns a block of ST_CELLS_BLOCK_TILES^2 tiles, one after the other. */
#define ST_CELLS_BLOCK_TILES 2
/* Per record: its pass in the draw order (for the serial composite its group's rank), and
 * whether its group is a single convex cell (two layers) rather than merged cells (a sorted
 * k-buffer). */
#define ST_CELLS_PASS_MASK 0x7FFFFFFFu
#define ST_CELLS_SINGLE_CELL 0x80000000u
/* Layer writes of single cells: a strict cell has at most one fragment per layer and pixel, so
 * its owner stores it; a cell of the paper's local test may have more, so the paper's atomic max
 * keeps one deterministically. */
#define ST_CELLS_LAYER_STORE 0
#define ST_CELLS_LAYER_ATOMIC_MAX 1
/* How the composite kernels treat the order they are given. An order made for an earlier view
 * (a moving camera) may put two groups that now overlap in one pass, or their fragments out of
 * depth order at a pixel: with ST_CELLS_ORDER_CHECK every pixel's composited fragments are
 * checked to ascend in depth with none overwritten, and the pixels that fail are flagged (a
 * 64-bit mask per tile); the repair launch then composites only the flagged pixels, every
 * fragment of a pixel sorted as one group, exact whatever the order. */
#define ST_CELLS_ORDER_TRUSTED 0
#define ST_CELLS_ORDER_CHECK 1
#define ST_CELLS_ORDER_REPAIR 2
/* Counters of one batch (a separate ulong[ST_COUNTER_COUNT] buffer, cleared per batch). */
#define ST_CELLS_BATCH_EXTRA 0   /* extra records of clipped triangles in this batch */
#define ST_CELLS_BATCH_ENTRIES 3 /* bin entries of this batch (written by bin_scan) */
#define ST_CELLS_BATCH_NEXT_BLOCK 15 /* the serial composite's next block to draw */
/* Frame counters of the cells method. */
#define ST_COUNTER_CELLS_GROUP_DEPTH ST_COUNTER_METHOD_0 /* most fragments of a group at a pixel */
#define ST_COUNTER_CELLS_ENTRIES ST_COUNTER_METHOD_1     /* most bin entries of a batch */
#define ST_COUNTER_CELLS_REPAIR_TILES ST_COUNTER_METHOD_2  /* tiles an order check flagged */
#define ST_COUNTER_CELLS_REPAIR_PIXELS ST_COUNTER_METHOD_3 /* and their pixels it flagged */
#define ST_COUNTER_CELLS_REPAIR_DEPTH ST_COUNTER_METHOD_4  /* most fragments a repair sorted */

/* ---- Octree method (engine/methods/octree.cpp, kernels/octree_resolve.cl). ---- */
#define ST_OCTREE_MAX_K 64 /* largest per-pixel k-buffer of a leaf resolve */
/* How a leaf resolve knows how many layers a pixel has (the variants of the method). */
#define ST_OCTREE_COUNT_NONE 0     /* walk until a walk finds nothing (occlusion-query style) */
#define ST_OCTREE_COUNT_COVERAGE 1 /* a coverage-only walk first: the leaf's depth histogram */
#define ST_OCTREE_COUNT_FIRST 2    /* counted by the first walk, which appends (k-buffer) */
/* Frame counters of the octree method. */
#define ST_COUNTER_OCTREE_WALKS ST_COUNTER_METHOD_0   /* (tile, leaf) walks over bin lists */
#define ST_COUNTER_OCTREE_ENTRIES ST_COUNTER_METHOD_1 /* most bin entries of a batch */
#define ST_COUNTER_OCTREE_ENTRY_READS ST_COUNTER_METHOD_2 /* bin entries read by all walks */

/* A leaf's cube as its resolve sees it: the planes x = lo[0], ..., z = hi[2]. A face on the
 * root's boundary is at -/+INFINITY, so a fragment just outside the root still has a leaf. Two
 * leaves sharing a face hold the same float for it (the host rounds one exact value). */
typedef struct {
  float lo[3];
  float hi[3];
  st_u32 pad[2];
} StOctreeLeaf;

/* The claim rule: the fragment of a leaf's triangle at view distance d on the ray of a pixel
 * (origin o, direction dir with dot(dir, forward) = 1, so the ray parameter is the view
 * distance; inv[a] = 1 / dir[a], computed once per pixel) counts in that leaf only when
 * t_in <= d < t_out for the leaf's interval below. Per axis the planes' ray parameters
 * (c - o) * inv are monotone in c (a correctly rounded subtraction and product), so for one
 * pixel the half-open intervals of consecutive slabs tile the whole line exactly, and so do
 * the leaves' intervals: every d lies in exactly one leaf, and no fragment is counted twice. An
 * axis the ray runs parallel to selects the slab holding o (half-open too). */
ST_FN void st_octree_axis_interval(float lo, float hi, float o, float dir, float inv,
                                   float* enter, float* exit) {
  ST_NO_CONTRACT
  if (dir > 0.0f) {
    *enter = (lo - o) * inv;
    *exit = (hi - o) * inv;
  } else if (dir < 0.0f) {
    *enter = (hi - o) * inv;
    *exit = (lo - o) * inv;
  } else {
    const int in = o >= lo && o < hi;
    *enter = in ? -INFINITY : INFINITY;
    *exit = in ? INFINITY : -INFINITY;
  }
}

ST_FN void st_octree_leaf_interval(const float* lo, const float* hi, const float* o,
                                   const float* dir, const float* inv, float* t_in,
                                   float* t_out) {
  float a_in, a_out;
  st_octree_axis_interval(lo[0], hi[0], o[0], dir[0], inv[0], &a_in, &a_out);
  float lo_t = a_in, hi_t = a_out;
  st_octree_axis_interval(lo[1], hi[1], o[1], dir[1], inv[1], &a_in, &a_out);
  lo_t = a_in > lo_t ? a_in : lo_t;
  hi_t = a_out < hi_t ? a_out : hi_t;
  st_octree_axis_interval(lo[2], hi[2], o[2], dir[2], inv[2], &a_in, &a_out);
  *t_in = a_in > lo_t ? a_in : lo_t;
  *t_out = a_out < hi_t ? a_out : hi_t;
}

ST_FN int st_octree_claims(float t_in, float t_out, float d) { return t_in <= d && d < t_out; }

/* ---- The cells order's pixel masks (engine/cells/cell_order.cpp, kernels/cells_order_masks.cl). ----
 * Two cells need an order only if some pixel centre receives a fragment from both. The order
 * marks, per cell, every centre within ST_COVER_SLACK pixel of one of its projected triangles: a
 * superset of what the rasterizer covers, whose snapping moves corners by at most 1/512 pixel.
 * The slack is kept small: cells that merely touch along an edge (which the fill rule never lets
 * share a centre) are taken to share the centres within it. A triangle whose bounds span at
 * most ST_COVER_FLOAT_SPAN pixels and start within ST_COVER_FLOAT_REACH of the image origin is
 * set up in float, relative to its first centre (corners exact to 2^-19 pixel there, products
 * below 2^12, so the rounding stays some 100 times under the slack); the host sets up the others
 * in double. The host and the device run the float setup below with the same operations in the
 * same order (no contraction), so both mark the same centres. */
#define ST_COVER_SLACK (1.0f / 256.0f)
#define ST_COVER_FLOAT_SPAN 32.0f
#define ST_COVER_FLOAT_REACH 16384.0f

/* A projected triangle set up for the centre test: the centres it may cover (x0..x1, y0..y1,
 * clipped to the image) and its edge functions, relative to the first: edge i is inside where
 * ex * (x - x0) + (ey * (y - y0) + ec) >= 0, widened by the slack times its L1 length (at least
 * the Euclidean one), so no square root is taken; a triangle with no area covers the centres
 * next to its segment (within its bounds). */
typedef struct {
  st_i32 x0, x1, y0, y1;
  float ex[3], ey[3], ec[3];
} StCoverEdges;

/* floor and ceil of a pixel coordinate, saturated (NaN too) well outside any image so the
 * conversion to int is defined; min and max as std::min and std::max (which the host's SSE
 * setup matches lane for lane). */
ST_FN float st_cover_saturate(float v) {
  if (!(v > -1.0e7f)) return -1.0e7f;
  return v < 1.0e7f ? v : 1.0e7f;
}
ST_FN st_i32 st_cover_floor(float v) {
  v = st_cover_saturate(v);
  const st_i32 i = (st_i32)v;
  return i - ((float)i > v ? 1 : 0);
}
ST_FN st_i32 st_cover_ceil(float v) {
  v = st_cover_saturate(v);
  const st_i32 i = (st_i32)v;
  return i + ((float)i < v ? 1 : 0);
}
ST_FN float st_cover_min(float a, float b) { return b < a ? b : a; }
ST_FN float st_cover_max(float a, float b) { return a < b ? b : a; }
ST_FN float st_cover_abs(float v) { return fabs(v); }

#define ST_COVER_EMPTY 0  /* near no pixel centre of the image */
#define ST_COVER_SET_UP 1 /* set up in float */
#define ST_COVER_WIDE 2   /* too large or too far off for float: the host's double setup */

/* Sets up triangle (a, b, d) in pixels for the centre test (x0..x1, y0..y1 are always set). */
ST_FN int st_cover_setup(float ax, float ay, float bx, float by, float dx, float dy,
                         st_i32 width, st_i32 height, StCoverEdges* t) {
  ST_NO_CONTRACT
  const float fx0 = st_cover_min(ax, st_cover_min(bx, dx));
  const float fx1 = st_cover_max(ax, st_cover_max(bx, dx));
  const float fy0 = st_cover_min(ay, st_cover_min(by, dy));
  const float fy1 = st_cover_max(ay, st_cover_max(by, dy));
  const st_i32 x0 = st_cover_ceil(fx0 - 0.5f - ST_COVER_SLACK);
  const st_i32 x1 = st_cover_floor(fx1 - 0.5f + ST_COVER_SLACK);
  const st_i32 y0 = st_cover_ceil(fy0 - 0.5f - ST_COVER_SLACK);
  const st_i32 y1 = st_cover_floor(fy1 - 0.5f + ST_COVER_SLACK);
  t->x0 = x0 > 0 ? x0 : 0;
  t->x1 = x1 < width - 1 ? x1 : width - 1;
  t->y0 = y0 > 0 ? y0 : 0;
  t->y1 = y1 < height - 1 ? y1 : height - 1;
  if (t->x0 > t->x1 || t->y0 > t->y1) return ST_COVER_EMPTY;
  if (!(fx1 - fx0 <= ST_COVER_FLOAT_SPAN && fy1 - fy0 <= ST_COVER_FLOAT_SPAN &&
        st_cover_abs(fx0) < ST_COVER_FLOAT_REACH && st_cover_abs(fy0) < ST_COVER_FLOAT_REACH))
    return ST_COVER_WIDE;
  const float ox = (float)t->x0 + 0.5f, oy = (float)t->y0 + 0.5f;
  const float rax = ax - ox, ray = ay - oy, rbx = bx - ox, rby = by - oy;
  const float rdx = dx - ox, rdy = dy - oy;
  const float area = (rbx - rax) * (rdy - ray) - (rdx - rax) * (rby - ray);
  /* Counter-clockwise in pixels (y down), so inside is the non-negative side of every edge. */
  const float px[3] = {rax, area < 0.0f ? rdx : rbx, area < 0.0f ? rbx : rdx};
  const float py[3] = {ray, area < 0.0f ? rdy : rby, area < 0.0f ? rby : rdy};
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const float ux = px[j] - px[i], uy = py[j] - py[i];
    t->ex[i] = -uy;
    t->ey[i] = ux;
    t->ec[i] = uy * px[i] - ux * py[i] + ST_COVER_SLACK * (st_cover_abs(ux) + st_cover_abs(uy));
  }
  return ST_COVER_SET_UP;
}

/* Whether the centre (x0 + xf, y0 + yf) is inside every edge of t, each edge value rounded as
 * ex * xf + (ey * yf + ec) reads: every coverage test rounds it so, whatever lanes it
 * evaluates, and so all give the same bits. */
ST_FN int st_cover_inside(const StCoverEdges* t, float xf, float yf) {
  ST_NO_CONTRACT
  return t->ex[0] * xf + (t->ey[0] * yf + t->ec[0]) >= 0.0f &&
         t->ex[1] * xf + (t->ey[1] * yf + t->ec[1]) >= 0.0f &&
         t->ex[2] * xf + (t->ey[2] * yf + t->ec[2]) >= 0.0f;
}

/* ---- The cells order's relation of two cells (engine/cells/cell_order.cpp, cells_order_pairs.cl). ---- */
/* Which of two cells on either side of plane n . x + d = 0 can be in front: +1 the one on the
 * negative side (draw it first), -1 the one on the positive side, 0 the eye is on the plane
 * (their projections cannot overlap). eye and forward: 3 floats each. */
ST_FN int st_order_negative_first(float nx, float ny, float nz, float d, const float* eye,
                                  const float* forward, int perspective) {
  ST_NO_CONTRACT
  if (!perspective) {
    const float s = nx * forward[0] + ny * forward[1] + nz * forward[2];
    return s > 0.0f ? 1 : (s < 0.0f ? -1 : 0);
  }
  const float s = nx * eye[0] + ny * eye[1] + nz * eye[2] + d;
  return s < 0.0f ? 1 : (s > 0.0f ? -1 : 0);
}

/* Order of two disjoint boxes (lo, hi: 3 floats each): +1 a first, -1 b first, 0 none found
 * (the boxes overlap on every axis); the plane halfway between them on the first axis that
 * separates them. */
ST_FN int st_order_boxes(const float* alo, const float* ahi, const float* blo, const float* bhi,
                         const float* eye, const float* forward, int perspective) {
  ST_NO_CONTRACT
  for (int k = 0; k < 3; ++k) {
    const float nx = k == 0 ? 1.0f : 0.0f, ny = k == 1 ? 1.0f : 0.0f, nz = k == 2 ? 1.0f : 0.0f;
    if (ahi[k] < blo[k])
      return st_order_negative_first(nx, ny, nz, -0.5f * (ahi[k] + blo[k]), eye, forward,
                                     perspective);
    if (bhi[k] < alo[k])
      return -st_order_negative_first(nx, ny, nz, -0.5f * (bhi[k] + alo[k]), eye, forward,
                                      perspective);
  }
  return 0;
}

/* ---- Frame counters written by kernels (one st_u64 each, read back once per frame). ---- */
#define ST_COUNTER_SETUP_OVERFLOW 0   /* extra records of clipped triangles (may exceed capacity) */
#define ST_COUNTER_CULLED_DEGENERATE 1 /* zero area after snapping */
#define ST_COUNTER_CULLED_NONFINITE 2
#define ST_COUNTER_BIN_ENTRIES 3       /* tile-triangle pairs needed */
#define ST_COUNTER_NODES 4             /* linked-list nodes needed (= fragments for ppll) */
#define ST_COUNTER_FRAGMENTS 5         /* fragments rasterized */
#define ST_COUNTER_MAX_DEPTH 6         /* max fragments at one pixel */
#define ST_COUNTER_CLIPPED 7           /* triangles cut by near-plane / guard-band clipping */
#define ST_COUNTER_FRAGMENTS_LOST 8    /* fragments a fixed-budget method could not keep */
#define ST_COUNTER_PASS_FRAGMENTS 9    /* fragments a peeling pass added (reset per pass) */
#define ST_COUNTER_METHOD_0 10         /* free for one method's own use */
#define ST_COUNTER_METHOD_1 11
#define ST_COUNTER_METHOD_2 12
#define ST_COUNTER_METHOD_3 13
#define ST_COUNTER_METHOD_4 14
#define ST_COUNTER_COUNT 16

/* ---- Projection kinds. ---- */
#define ST_PROJ_PERSPECTIVE 0
#define ST_PROJ_ORTHOGRAPHIC 1

/* ---- Background kinds. ---- */
#define ST_BACKGROUND_SOLID 0
#define ST_BACKGROUND_CHECKER 1
#define ST_CHECKER_SQUARE 16 /* pixels per checker square */

/* A triangle after setup, as the raster stage reads it (64 bytes: one cache line). Edge e runs
 * from corner e to corner e + 1 and is inside when a * (px - cx) + b * (py - cy) >= 0, less one
 * unless it is a top or left edge (the fill rule), with px, py the fixed-point pixel centre and
 * (cx, cy) corner e (st_edge_at). Corner 0 is stored and corners 1 and 2 follow from the edges
 * (corner 1 = corner 0 + (b0, -a0)), so the edges need no 64-bit constants. The three edges
 * close the triangle, so their coefficients sum to zero: edge 2's are not stored
 * (st_record_edges). Depth is the view distance d = (d/w) / (1/w), both planes affine in screen
 * space and evaluated relative to corner 0. */
typedef struct {
  st_i32 corner_x, corner_y; /* corner 0, snapped, in fixed-point pixels */
  st_i32 edge_a[2];          /* edges 0 and 1; edge 2's are -(a0 + a1), -(b0 + b1) */
  st_i32 edge_b[2];
  float dw0, dw_dx, dw_dy;       /* d/w plane */
  float iw0, iw_dx, iw_dy;       /* 1/w plane */
  st_u32 source;                 /* source triangle id (tie-breaks, shading) */
  st_u32 flags;                  /* ST_TRI_FRONT_FACING, ST_TRI_TOP_LEFT_EDGE0 << e, ... */
  st_u32 bounds_min, bounds_max; /* inclusive pixel bounds, clamped to the viewport, packed
                                    as the binners read them (ST_BOUNDS_EMPTY_*) */
} StTriSetup;

/* A vertex after projection and snapping, written once per vertex by the transform stage so
 * that setup does not project every triangle corner again: x, y in fixed-point pixels (y down),
 * d/w and 1/w. A vertex behind the near plane, outside the guard band or not finite has
 * x = ST_SCREEN_CLIPPED, and its triangles take setup's clipping path from clip space. */
typedef struct {
  st_i32 x, y;
  float dw, iw;
} StScreenVertex;
#define ST_SCREEN_CLIPPED (-2147483647 - 1)

/* A setup record's inclusive pixel bounds packed for binning (setup writes them next to the
 * record, so the binner reads 8 bytes per triangle, not the record): x | y << 16 of the
 * top-left pixel, then of the bottom-right one; an empty record has min x > max x. */
#define ST_BOUNDS_EMPTY_MIN 1u
#define ST_BOUNDS_EMPTY_MAX 0u

#define ST_TRI_FRONT_FACING 1u /* counter-clockwise on screen (the winding's facing) */
#define ST_TRI_CELL_FRONT 2u   /* cells: on its convex cell's front layer from this view */
/* Edge e of the record is a top or left edge (the fill rule: its centres belong to it): bit
 * ST_TRI_TOP_LEFT_EDGE0 << e, set by setup so a walk need not classify the edges again. */
#define ST_TRI_TOP_LEFT_EDGE0 4u

/* A node of a per-pixel linked list (ppll). */
typedef struct {
  float depth;
  st_u32 source;
  st_u32 next; /* ST_PPLL_END terminates */
} StPpllNode;

/* The empty visibility-buffer word: every packed (depth, id) compares below it. */
#define ST_VISIBILITY_EMPTY 0xFFFFFFFFFFFFFFFFul

/* Per-frame constants of a view. */
typedef struct {
  float view_proj[16]; /* column-major, world -> clip (x, y, -, w) */
  float view_row[4];   /* world -> view-space distance d = dot(view_row.xyz, p) + view_row.w */
  float light_dir[4];  /* world-space unit vector towards the light */
  float background[4]; /* RGBA, linear 0..1 */
  float background2[4];
  /* Pixel rays (Camera::pixelRay, st_pixel_ray): perspective: origin = eye, direction =
   * forward + right * (ndc_x * ray_tan[0]) + up * (ndc_y * ray_tan[1]) (normalised);
   * orthographic: origin = eye + right * (ndc_x * ray_tan[2]) + up * (ndc_y * ray_tan[3]),
   * direction = forward. */
  float eye[4];
  float forward[4];
  float right[4];
  float up[4];
  float ray_tan[4];
  st_i32 width, height;
  float near_distance; /* near plane: d >= near_distance */
  st_i32 projection;
  st_i32 background_kind;
  st_i32 effect;       /* ST_EFFECT_* */
  float sigma;         /* translucency: absorption per world unit */
  st_i32 textured;     /* 1: the scene has textured materials (StTexTriangle per triangle) */
  /* background and background2 as 8-bit RGBA (st_to_unorm8, alpha 255), red in the lowest
   * byte: what a pixel with no fragment shows, without converting it per pixel. */
  st_u32 background_rgba8[2];
} StViewConstants;

/* ---- Draw units (engine batching, engine/features/batching.h). ----
 * The front end draws runs of draw units; a run is one transform and one setup launch over a
 * table of StDraw (one per unit), each n instances of a source range (n = 1 except instanced
 * units). Source vertices are object space (transformed by the instance) or world space;
 * source indices are local to the range. Device vertices of instance i start at
 * dst_first_vertex + i * vertex_count; every record is written at its world triangle id. */
typedef struct {
  st_u32 vertex_prefix;      /* vertices of the run before this draw */
  st_u32 triangle_prefix;    /* triangles of the run before this draw */
  st_u32 src_first_vertex;   /* in the source positions */
  st_u32 src_first_triangle; /* in the source indices (and the static id map) */
  st_u32 dst_first_vertex;   /* clip / world vertex of instance 0's first vertex */
  st_u32 dst_first_triangle; /* device triangle of instance 0's first (records go to world ids) */
  st_u32 vertex_count;       /* per instance */
  st_u32 triangle_count;     /* per instance */
  st_u32 first_instance;     /* into the instance buffer */
  st_u32 instance_count;
  st_u32 pad[2];
} StDraw;

/* One instance: object -> world affine transform (column c, row r at m[3 * c + r]; the product
 * is evaluated as glm's mat4 * vec4 does, so world positions match the host's bit for bit),
 * flat colour (RGB + opacity), object id and the world id of its first triangle. */
typedef struct {
  float m[12];
  float color[4];
  st_u32 object_id;
  st_u32 world_first_triangle;
  st_u32 pad[2];
} StInstance;

/* How setup finds a record's source (world) triangle id and colour. */
#define ST_SOURCE_IDENTITY 0  /* source = source triangle; colour from triangle_material */
#define ST_SOURCE_ID_MAP 1    /* source = triangle_ids[source triangle]; colour as above */
#define ST_SOURCE_INSTANCE 2  /* source = instance's world_first_triangle + k; its colour */

/* ---- Effects (cells and the Embree reference). ---- */
#define ST_EFFECT_TRANSPARENCY 0
#define ST_EFFECT_TRANSLUCENCY 1
/* Translucency, evaluated front to back over the depth-sorted fragments of a pixel ray, with
 * colour C = 0, throughput T = 1 and an inside count of 0 at the eye:
 *  - between consecutive fragments at view distances d0 < d1, while the inside count is > 0,
 *    T *= exp(-sigma * (d1 - d0) * ray_length_per_distance) (Beer-Lambert; the path length is the
 *    view-distance difference scaled by |ray direction| / (ray direction . forward));
 *  - at each fragment with flat-shaded colour s and cosine c = |n . ray direction|:
 *    R = Schlick reflectance, C += T * R * s, T *= 1 - R; a front-facing fragment (the facing
 *    the rasterizer uses) then increments the inside count, a back-facing one decrements it
 *    (not below 0);
 *  - pixel = C + T * background. */
#define ST_FRESNEL_F0 0.04f

ST_FN float st_schlick_reflectance(float cos_nv) {
  float m = 1.0f - fabs(cos_nv);
  m = m < 0.0f ? 0.0f : (m > 1.0f ? 1.0f : m);
  const float m2 = m * m;
  return ST_FRESNEL_F0 + (1.0f - ST_FRESNEL_F0) * m2 * m2 * m;
}

/* ---- Shading rules, identical in the kernels and the Embree reference. ---- */
#define ST_AMBIENT 0.3f
#define ST_DIFFUSE 0.7f

/* Two-sided diffuse factor for a unit normal n and unit light direction l. */
ST_FN float st_diffuse_factor(float ndotl) { return ST_AMBIENT + ST_DIFFUSE * fabs(ndotl); }

/* Which background colour pixel (x, y) shows: 0 (background) or 1 (background2). */
ST_FN int st_background_index(st_i32 kind, int x, int y) {
  return kind == ST_BACKGROUND_CHECKER && (((x / ST_CHECKER_SQUARE) + (y / ST_CHECKER_SQUARE)) & 1);
}

/* Background colour channel c (0..2) at pixel (x, y). */
ST_FN float st_background_channel(const StViewConstants* v, int x, int y, int c) {
  return st_background_index(v->background_kind, x, y) ? v->background2[c] : v->background[c];
}

/* Float 0..1 to an 8-bit channel, rounding to nearest. */
ST_FN st_u32 st_to_unorm8(float c) {
  float x = c < 0.0f ? 0.0f : (c > 1.0f ? 1.0f : c);
  return (st_u32)(x * 255.0f + 0.5f);
}

/* ---- Texturing (engine/features/texture_atlas.h, kernels/texture.cl). ----
 * A textured fragment's colour is its flat-shaded colour times the base-colour texel (RGBA).
 * Texture coordinates at pixel (x, y) are those of the point where the ray through the pixel's
 * centre meets the plane of the triangle (barycentric interpolation, extended past its edges);
 * their screen derivatives are the differences to the same for pixels (x + 1, y) and
 * (x, y + 1), so the mip level does not depend on which renderer found the fragment.
 * For one view that point's coordinates are a ratio of affine functions of the pixel centre
 * (px, py): u = U(px, py) / W(px, py), v = V / W (perspective-correct interpolation; W = 1 for
 * orthographic views). The host computes the three planes per triangle and view in double
 * precision (makeTexTriangle); kernels and the Embree reference evaluate them with the same
 * code below, so both get the same bits. */
#define ST_NO_TEXTURE 0xFFFFFFFFu
#define ST_ATLAS_MAX_LEVELS 15 /* mip levels of a page: 16384 >> 14 = 1 */
#define ST_WRAP_REPEAT 0
#define ST_WRAP_MIRRORED_REPEAT 1
#define ST_WRAP_CLAMP 2
#define ST_FILTER_NEAREST 0
#define ST_FILTER_BILINEAR 1
#define ST_FILTER_TRILINEAR 2

/* wboit's weight functions (WboitWeight, McGuire and Bavoil 2013's equations 7 to 10). */
#define ST_WBOIT_EQ7 0
#define ST_WBOIT_EQ8 1
#define ST_WBOIT_EQ9 2
#define ST_WBOIT_EQ10 3

/* Per world triangle and view (written by the host once per render call, read when a fragment
 * is shaded): the planes U, V, W as (coefficient of px, of py, constant), and the atlas entry. */
typedef struct {
  float u_plane[3], v_plane[3], w_plane[3];
  st_u32 texture; /* atlas entry, or ST_NO_TEXTURE */
} StTexTriangle;

/* One atlas entry: a texture placed with one sampler (a texture sampled with two wrap modes is
 * placed twice, each with its own gutter). Level l starts at (ceil(cell_x / 2^l) + 1,
 * ceil(cell_y / 2^l) + 1) of its page and is max(1, width >> l) x max(1, height >> l). */
typedef struct {
  st_i32 page, cell_x, cell_y, width, height, levels;
  st_i32 wrap_s, wrap_t, filter;
  st_i32 pad[3];
} StAtlasTexture;

/* One atlas page: level l is max(1, width >> l) x max(1, height >> l) RGBA8 texels (one word
 * each, R in the low byte) at word `offset[l]` of the texel array. */
typedef struct {
  st_i32 width, height;
  st_u32 offset[ST_ATLAS_MAX_LEVELS];
} StAtlasPage;

/* The atlas buffer, in 32-bit words: this header, texture_count StAtlasTexture, page_count
 * StAtlasPage, then the texels. */
typedef struct {
  st_u32 texture_count, page_count, texel_word_offset, pad;
} StAtlasHeader;

#ifdef __OPENCL_VERSION__
#define ST_TEX_TRIANGLE __global const StTexTriangle
#else
#define ST_TEX_TRIANGLE const StTexTriangle
#endif

/* Texture coordinates of triangle t at pixel (x, y) and their derivatives per pixel
 * (duv[0..1] along x, duv[2..3] along y). A pixel whose neighbour's ray misses the plane's front
 * (the horizon) gets infinite derivatives there: the coarsest level. */
ST_FN void st_texcoords_at_pixel(ST_TEX_TRIANGLE* t, int x, int y, float* uv, float* duv) {
  ST_NO_CONTRACT
  const float px = (float)x + 0.5f, py = (float)y + 0.5f;
  const float u = t->u_plane[0] * px + t->u_plane[1] * py + t->u_plane[2];
  const float v = t->v_plane[0] * px + t->v_plane[1] * py + t->v_plane[2];
  const float w = t->w_plane[0] * px + t->w_plane[1] * py + t->w_plane[2];
  const float iw = 1.0f / w;
  uv[0] = u * iw;
  uv[1] = v * iw;
  const float wx = w + t->w_plane[0], wy = w + t->w_plane[1];
  if (wx > 0.0f) {
    const float ix = 1.0f / wx;
    duv[0] = (u + t->u_plane[0]) * ix - uv[0];
    duv[1] = (v + t->v_plane[0]) * ix - uv[1];
  } else {
    duv[0] = duv[1] = INFINITY;
  }
  if (wy > 0.0f) {
    const float iy = 1.0f / wy;
    duv[2] = (u + t->u_plane[1]) * iy - uv[0];
    duv[3] = (v + t->v_plane[1]) * iy - uv[1];
  } else {
    duv[2] = duv[3] = INFINITY;
  }
}

#endif /* STRATA_SHARED_H */
