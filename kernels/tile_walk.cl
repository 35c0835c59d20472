/* tile_walk.cl: the tile walk the raster stages share. One work-group owns one ST_TILE_SIZE^2
 * tile and walks its bin list (or, in a kernel's serial form, one work-item alone:
 * st_tile_walk_alone); pixel centres are tested against integer edge functions (top-left rule
 * folded into the setup). */

/* How many bin entries ahead of the current one a walk prefetches: a work-group's item, whose
 * neighbours walk the entries in between, and a work-item alone on its tile (the serial kernels),
 * which can look further ahead. */
#define ST_WALK_AHEAD 4
#define ST_WALK_AHEAD_ALONE 12

/* Bin list range [begin, end) of tile `tile`. */
inline void st_tile_range_of(__global const uint* tile_offsets, uint tile, uint bin_capacity,
                             uint* begin, uint* end) {
  *begin = min(tile_offsets[tile], bin_capacity);
  *end = min(tile_offsets[tile + 1], bin_capacity);
}

/* Bin list range [begin, end) of the tile owned by this work-group. */
inline void st_tile_range(__global const uint* tile_offsets, uint tiles_x, uint bin_capacity,
                          uint* begin, uint* end) {
  st_tile_range_of(tile_offsets, get_group_id(1) * tiles_x + get_group_id(0), bin_capacity, begin,
                   end);
}

/* Where the serial binners (bin.cl, cells_bin.cl) keep the count and the cursor of tile `tile` for run c of a table of
 * tile_count tiles: each run's column is its own stretch of memory. Stored tile by tile, the
 * counters of one tile for every run shared a cache line, which the threads' runs, drawing
 * overlapping parts of the screen at once, took from each other at every record. */
inline uint st_run_slot(uint tile, uint c, uint tile_count) {
  return c * (tile_count + ST_BIN_RUN_PAD) + tile;
}

/* The coefficients of record r's three edges: edge 2's from the other two, the edges closing
 * the triangle (each is a difference of corners, so the sum is exact in 32 bits). */
#define ST_RECORD_EDGES(r, a0, b0, a1, b1, a2, b2)                                        \
  const int a0 = (r)->edge_a[0], a1 = (r)->edge_a[1], a2 = -(a0 + a1);                    \
  const int b0 = (r)->edge_b[0], b1 = (r)->edge_b[1], b2 = -(b0 + b1)

/* Edge e's coefficients (a, b) of record r (ST_RECORD_EDGES). */
inline int2 st_record_edge(__global const StTriSetup* r, int e) {
  ST_RECORD_EDGES(r, a0, b0, a1, b1, a2, b2);
  return e == 0 ? (int2)(a0, b0) : e == 1 ? (int2)(a1, b1) : (int2)(a2, b2);
}

/* Edge function e of record r, whose corner e is (cx, cy), at the centre of pixel (x, y), in
 * full 64-bit precision: a * (px - cx) + b * (py - cy), less one unless the edge is a top or
 * left one (the fill rule: setup's flags). */
inline long st_edge_at(__global const StTriSetup* r, int e, int cx, int cy, int x, int y) {
  const int2 ab = st_record_edge(r, e);
  return (long)ab.x * ((long)x * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2 - cx) +
         (long)ab.y * ((long)y * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2 - cy) -
         (long)(((r->flags / ST_TRI_TOP_LEFT_EDGE0) >> e & 1u) ^ 1u);
}

/* Corners 1 and 2 of record r (fixed point) from corner 0 and the edges: edge e runs from
 * corner e to corner e + 1 with a = -dy and b = dx (st_setup_projected). */
#define ST_RECORD_CORNERS(r, x0, y0, x1, y1, x2, y2)                                      \
  const int x0 = (r)->corner_x, y0 = (r)->corner_y;                                       \
  const int x1 = x0 + (r)->edge_b[0], y1 = y0 - (r)->edge_a[0];                           \
  const int x2 = x1 + (r)->edge_b[1], y2 = y1 - (r)->edge_a[1]

/* The pixels of record r's bounds inside the tile whose top-left pixel is (tx, ty): x0, y0,
 * x1, y1 (empty when x0 > x1 or y0 > y1). */
inline int4 st_record_tile_rect(__global const StTriSetup* r, int tx, int ty) {
  const int4 b = st_unpack_bounds((uint2)(r->bounds_min, r->bounds_max));
  return (int4)(max(b.x, tx), max(b.y, ty), min(b.z, tx + ST_TILE_SIZE - 1),
                min(b.w, ty + ST_TILE_SIZE - 1));
}

/* The pixels [x0, x1] x [y0, y1] of a tile (relative to the tile) as a mask, bit y * 8 + x (the
 * 8 x 8 tile of every 64-bit coverage mask). */
inline ulong st_tile_rect_mask(int x0, int y0, int x1, int y1) {
  const ulong columns = (ulong)(((2u << x1) - 1u) & ~((1u << x0) - 1u)) * 0x0101010101010101ul;
  return columns & (~0ul << (y0 * ST_TILE_SIZE)) &
         (~0ul >> ((ST_TILE_SIZE - 1 - y1) * ST_TILE_SIZE));
}

/* Corner 0 of record r in pixels, the origin of its depth planes (as setup computed it). */
inline float2 st_record_origin(__global const StTriSetup* r) {
  const float inv_one = 1.0f / (float)ST_SUBPIXEL_ONE;
  return (float2)(r->corner_x * inv_one, r->corner_y * inv_one);
}

/* View distance of record r, whose origin is `origin`, at the centre of pixel (x, y)
 * (perspective-correct: d/w over 1/w). */
inline float st_record_depth(__global const StTriSetup* r, float2 origin, int x, int y) {
  const float dx = ((float)x + 0.5f) - origin.x, dy = ((float)y + 0.5f) - origin.y;
  const float dw = r->dw0 + r->dw_dx * dx + r->dw_dy * dy;
  const float iw = r->iw0 + r->iw_dx * dx + r->iw_dy * dy;
  return dw / iw;
}

/* One edge over the rectangle: its extremes there and its 32-bit steps from the rectangle's
 * first pixel (all zero for an edge the whole rectangle is inside, lo >= 0). */
typedef struct {
  long lo, hi;
  uint start, step_x, step_y;
} StEdgeSpan;

inline StEdgeSpan st_edge_span(__global const StTriSetup* r, int e, int cx, int cy, int x0, int y0,
                               int x1, int y1) {
  StEdgeSpan s;
  const int2 ab = st_record_edge(r, e);
  const long a = (long)ab.x * ST_SUBPIXEL_ONE, b = (long)ab.y * ST_SUBPIXEL_ONE;
  const long c00 = st_edge_at(r, e, cx, cy, x0, y0);
  const long dx = a * (x1 - x0), dy = b * (y1 - y0);
  s.lo = c00 + min(dx, 0L) + min(dy, 0L);
  s.hi = c00 + max(dx, 0L) + max(dy, 0L);
  const bool inside = s.lo >= 0;
  s.start = inside ? 0u : (uint)c00;
  s.step_x = inside ? 0u : (uint)a;
  s.step_y = inside ? 0u : (uint)b;
  return s;
}

/* Whether an edge crossing the rectangle has values beyond 32 bits there (an edge inside it
 * everywhere is dropped, whatever its values). */
inline bool st_edge_span_wide(const StEdgeSpan s) {
  return (s.lo <= -(1L << 31)) | ((s.lo < 0) & (s.hi >= (1L << 31)));
}

/* Coverage of record r over pixels [x0, x1] x [y0, y1] (inside the tile whose top-left pixel is
 * (tx, ty) and inside r's pixel bounds) as a mask: bit (y - ty) * ST_TILE_SIZE + (x - tx). The
 * edge functions are affine, so over the rectangle each lies between its values at the
 * rectangle's corners: an edge that is non-negative at all four corners is dropped, one
 * negative at all four empties the mask, and an
 * edge whose corner values fit in 32 bits is stepped incrementally in 32-bit arithmetic (every
 * partial sum is the value at some pixel of the rectangle, so the sums are exact; unsigned, so a
 * step that wraps is defined). Only an edge of extent beyond about 2^23 subpixels that crosses
 * the rectangle needs the 64-bit test per pixel. With ST_ROW_LANES (PoCL) a row is stepped as
 * the eight lanes of a uint8: explicit vectors are what PoCL's compiler turns into SIMD, while
 * a loop over the row's pixels stays scalar. Bit-identical to st_edge_at at every pixel. */
#if defined(ST_ROW_LANES) && ST_TILE_SIZE != 8
#error "st_tile_coverage evaluates a tile row as the eight lanes of a uint8"
#endif

#ifdef ST_ROW_LANES
/* Bit k set where lane k of `outside` has its sign bit clear (the OR of a pixel's three edge
 * values: inside all three). On x86 (PoCL's CPU targets define __AVX__) one vmovmskps;
 * elsewhere a reduction of the lanes' weighted bits, which took half of a small triangle's row
 * loop. */
inline uint st_row_inside_bits(const uint8 outside) {
#ifdef __AVX__
  return (uint)__builtin_ia32_movmskps256(as_float8(~outside));
#else
  const uint8 weight = (uint8)(1u, 2u, 4u, 8u, 16u, 32u, 64u, 128u);
  const uint8 in = (~outside >> 31) * weight;
  const uint4 h4 = in.lo | in.hi;
  const uint2 h2 = h4.lo | h4.hi;
  return h2.x | h2.y;
#endif
}
#endif

/* A small triangle: every edge's coefficients below 2^ST_SMALL_EDGE_BITS subpixels, so the
 * triangle spans less than that on both axes (its edges join every pair of corners). A pixel
 * centre inside its pixel bounds lies inside its bounding box, within that span of every corner,
 * so each edge's value there, a * dx + b * dy less the fill rule's one, is at most
 * 2 * 2^28 + 1 < 2^31 in magnitude: exact in 32 bits. So the three edges are stepped from the
 * rectangle's first row in 32-bit arithmetic without the 64-bit extremes of st_edge_span (those
 * were most of the coverage's cost on meshes of small triangles: builtin:spheres:32's cells
 * composite 87 -> 78 ms). Unsigned, so a lane outside the rectangle (masked off) may wrap
 * harmlessly. Bit-identical to st_edge_at. */
#define ST_SMALL_EDGE_BITS 14
inline bool st_small_edges(int a0, int b0, int a1, int b1, int a2, int b2) {
  return ((abs(a0) | abs(b0) | abs(a1) | abs(b1) | abs(a2) | abs(b2)) >> ST_SMALL_EDGE_BITS) == 0;
}
inline __attribute__((always_inline)) ulong st_small_tile_coverage(
    uint flags, int a0, int b0, int a1, int b1, int a2, int b2, int ax, int ay, int bx, int by,
    int cx, int cy, int tx, int ty, int x0, int y0, int x1, int y1) {
  const uint fill0 = ((flags / ST_TRI_TOP_LEFT_EDGE0) & 1u) ^ 1u;
  const uint fill1 = ((flags / ST_TRI_TOP_LEFT_EDGE0) >> 1 & 1u) ^ 1u;
  const uint fill2 = ((flags / ST_TRI_TOP_LEFT_EDGE0) >> 2 & 1u) ^ 1u;
  const int py = y0 * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2;
  /* Each edge at column tx of row y0, and its steps. */
  const int px = tx * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2;
  const uint row0 = (uint)a0 * (uint)(px - ax) + (uint)b0 * (uint)(py - ay) - fill0;
  const uint row1 = (uint)a1 * (uint)(px - bx) + (uint)b1 * (uint)(py - by) - fill1;
  const uint row2 = (uint)a2 * (uint)(px - cx) + (uint)b2 * (uint)(py - cy) - fill2;
  const uint dx0 = (uint)a0 * ST_SUBPIXEL_ONE, dx1 = (uint)a1 * ST_SUBPIXEL_ONE,
             dx2 = (uint)a2 * ST_SUBPIXEL_ONE;
  const uint dy0 = (uint)b0 * ST_SUBPIXEL_ONE, dy1 = (uint)b1 * ST_SUBPIXEL_ONE,
             dy2 = (uint)b2 * ST_SUBPIXEL_ONE;
  ulong mask = 0;
#ifdef ST_ROW_LANES
  const uint columns = ((2u << (x1 - tx)) - 1u) & ~((1u << (x0 - tx)) - 1u);
  const uint8 lane = (uint8)(0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u);
  uint8 e0 = (uint8)row0 + (uint8)dx0 * lane;
  uint8 e1 = (uint8)row1 + (uint8)dx1 * lane;
  uint8 e2 = (uint8)row2 + (uint8)dx2 * lane;
  for (int y = y0; y <= y1; ++y) {
    mask |= (ulong)(st_row_inside_bits(e0 | e1 | e2) & columns) << ((y - ty) * ST_TILE_SIZE);
    e0 += dy0;
    e1 += dy1;
    e2 += dy2;
  }
#else
  uint r0 = row0 + dx0 * (uint)(x0 - tx), r1 = row1 + dx1 * (uint)(x0 - tx),
       r2 = row2 + dx2 * (uint)(x0 - tx);
  for (int y = y0; y <= y1; ++y) {
    uint e0 = r0, e1 = r1, e2 = r2, bits = 0;
    for (int i = 0; i <= x1 - x0; ++i) {
      bits |= ((~(e0 | e1 | e2)) >> 31) << i; /* all three sign bits clear: inside */
      e0 += dx0;
      e1 += dx1;
      e2 += dx2;
    }
    mask |= (ulong)bits << ((y - ty) * ST_TILE_SIZE + (x0 - tx));
    r0 += dy0;
    r1 += dy1;
    r2 += dy2;
  }
#endif
  return mask;
}
inline ulong st_tile_coverage(__global const StTriSetup* r, int tx, int ty, int x0, int y0, int x1,
                              int y1) {
  ST_RECORD_CORNERS(r, ax, ay, bx, by, cx, cy);
  ST_RECORD_EDGES(r, a0, b0, a1, b1, a2, b2);
  if (st_small_edges(a0, b0, a1, b1, a2, b2))
    return st_small_tile_coverage(r->flags, a0, b0, a1, b1, a2, b2, ax, ay, bx, by, cx, cy, tx,
                                  ty, x0, y0, x1, y1);
  /* The three edges one after another in straight-line code, returning as soon as one misses
   * the rectangle (a loop over the edges with that early exit kept them in memory on PoCL). */
  const StEdgeSpan s0 = st_edge_span(r, 0, ax, ay, x0, y0, x1, y1);
  if (s0.hi < 0) return 0; /* outside an edge everywhere */
  const StEdgeSpan s1 = st_edge_span(r, 1, bx, by, x0, y0, x1, y1);
  if (s1.hi < 0) return 0;
  const StEdgeSpan s2 = st_edge_span(r, 2, cx, cy, x0, y0, x1, y1);
  if (s2.hi < 0) return 0;
  const bool wide = st_edge_span_wide(s0) | st_edge_span_wide(s1) | st_edge_span_wide(s2);
  const uint start[3] = {s0.start, s1.start, s2.start};
  const uint step_x[3] = {s0.step_x, s1.step_x, s2.step_x};
  const uint step_y[3] = {s0.step_y, s1.step_y, s2.step_y};
  ulong mask = 0;
  if (wide) {
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        if (st_edge_at(r, 0, ax, ay, x, y) >= 0 && st_edge_at(r, 1, bx, by, x, y) >= 0 &&
            st_edge_at(r, 2, cx, cy, x, y) >= 0)
          mask |= 1ul << ((y - ty) * ST_TILE_SIZE + (x - tx));
    return mask;
  }
#ifdef ST_ROW_LANES
  /* Whole tile rows as eight lanes: lane k is column tx + k; lanes outside [x0, x1] wrap
   * harmlessly and are masked off, those inside hold the exact edge values. */
  const uint8 lane = as_uint8((int8)(0, 1, 2, 3, 4, 5, 6, 7) - (int8)(x0 - tx));
  uint8 e0 = (uint8)start[0] + (uint8)step_x[0] * lane;
  uint8 e1 = (uint8)start[1] + (uint8)step_x[1] * lane;
  uint8 e2 = (uint8)start[2] + (uint8)step_x[2] * lane;
  const uint columns = ((2u << (x1 - tx)) - 1u) & ~((1u << (x0 - tx)) - 1u);
  for (int y = y0; y <= y1; ++y) {
    mask |= (ulong)(st_row_inside_bits(e0 | e1 | e2) & columns) << ((y - ty) * ST_TILE_SIZE);
    e0 += step_y[0];
    e1 += step_y[1];
    e2 += step_y[2];
  }
#else
  uint row0 = start[0], row1 = start[1], row2 = start[2];
  for (int y = y0; y <= y1; ++y) {
    uint e0 = row0, e1 = row1, e2 = row2;
    uint bits = 0;
    for (int i = 0; i <= x1 - x0; ++i) {
      bits |= ((~(e0 | e1 | e2)) >> 31) << i; /* all three sign bits clear: inside */
      e0 += step_x[0];
      e1 += step_x[1];
      e2 += step_x[2];
    }
    mask |= (ulong)bits << ((y - ty) * ST_TILE_SIZE + (x0 - tx));
    row0 += step_y[0];
    row1 += step_y[1];
    row2 += step_y[2];
  }
#endif
  return mask;
}

/* st_tile_coverage with the small path inline and the rest out of line, for the cells plain
 * composite, whose walk does little else per bin entry (builtin:spheres:96 at 1024x1024: its
 * composite 203 -> 193 ms). The other walks keep the call: inlined there, the opaque raster and
 * the cells composite of the horse were 2-3% slower. */
inline __attribute__((always_inline)) ulong st_tile_coverage_inline(
    __global const StTriSetup* r, int tx, int ty, int x0, int y0, int x1, int y1) {
  ST_RECORD_EDGES(r, a0, b0, a1, b1, a2, b2);
  if (!st_small_edges(a0, b0, a1, b1, a2, b2)) return st_tile_coverage(r, tx, ty, x0, y0, x1, y1);
  ST_RECORD_CORNERS(r, ax, ay, bx, by, cx, cy);
  return st_small_tile_coverage(r->flags, a0, b0, a1, b1, a2, b2, ax, ay, bx, by, cx, cy, tx, ty,
                                x0, y0, x1, y1);
}

/* A work-item's walk over the fragments of its work-group's tile. The work-group walks the bin
 * list range, one triangle per work-item at a time (stride ST_TILE_PIXELS), so the cost is
 * proportional to fragments plus tile-triangle pairs rather than pairs times tile pixels (real
 * meshes at these sizes have triangles of a few pixels). Per triangle the work-item computes its
 * coverage of the tile as a 64-bit mask (st_tile_coverage: branch-free 32-bit steps), then takes
 * the covered pixels from the mask in raster order:
 *   StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
 *   while (st_tile_triangle_next(&f)) {
 *     ... per triangle: f.r, f.record ...
 *     while (st_tile_fragment_next(&f)) {
 *       ... per fragment: f.x, f.y, f.p, f.depth ...
 *     }
 *   }
 * Kernels follow the walk with barriers: never `return` from inside it.
 * The walk functions are always_inline: PoCL otherwise keeps one out of line with the walk
 * state in memory. */
typedef struct {
  /* The current fragment. */
  __global const StTriSetup* r; /* its triangle's setup record */
  uint record;                  /* that record's index (the bin entry) */
  int x, y;                     /* the pixel, in image coordinates */
  uint p;                       /* the pixel's index inside the tile */
  float depth;                  /* the view distance at the pixel centre */
  /* Walk state. */
  __global const StTriSetup* records;
  __global const uint* bin_entries;
  uint next, end;  /* bin entry of the next triangle; end of this work-item's run */
  uint group_end;  /* end of the work-group's range */
  uint ahead;      /* how many entries ahead to prefetch */
  int tx, ty;     /* the tile's top-left pixel */
  ulong covered;  /* the current triangle's pixels not yet visited (bit p) */
  float2 origin;  /* the current triangle's depth-plane origin (st_record_origin) */
} StTileWalk;

/* A walk over bin entries [begin, end) of the tile whose top-left pixel is (tx, ty). */
inline __attribute__((always_inline)) StTileWalk st_tile_walk(
    __global const StTriSetup* records, __global const uint* bin_entries, uint begin, uint end,
    int tx, int ty) {
  StTileWalk w;
  w.records = records;
  w.bin_entries = bin_entries;
  const uint chunk = (end - begin + ST_TILE_PIXELS - 1) / ST_TILE_PIXELS;
  w.next = min(begin + st_local_index() * chunk, end);
  w.end = min(w.next + chunk, end);
  w.group_end = end;
  w.ahead = ST_WALK_AHEAD;
  w.tx = tx;
  w.ty = ty;
  w.r = 0;
  w.record = 0;
  w.x = w.y = 0;
  w.p = 0;
  w.depth = 0.0f;
  w.covered = 0;
  w.origin = (float2)(0.0f);
  return w;
}

/* The walk of a work-item alone on its tile (a serial kernel: no work-group, no barriers): every
 * bin entry of [begin, end), in drawing order. */
inline __attribute__((always_inline)) StTileWalk st_tile_walk_alone(
    __global const StTriSetup* records, __global const uint* bin_entries, uint begin, uint end,
    int tx, int ty) {
  StTileWalk w = st_tile_walk(records, bin_entries, begin, begin, tx, ty);
  w.next = begin;
  w.end = w.group_end = end;
  w.ahead = ST_WALK_AHEAD_ALONE;
  return w;
}

/* Moves to this work-item's next triangle (w->r, w->record; no pixel yet); false when none is
 * left. */
inline __attribute__((always_inline)) bool st_tile_triangle_next(StTileWalk* w) {
  if (w->next >= w->end) return false;
  w->record = w->bin_entries[w->next];
  ++w->next;
  if (w->next + w->ahead <= w->group_end) {
    /* A record is one cache line (buffers are aligned far beyond). */
    ST_PREFETCH(&w->records[w->bin_entries[w->next + w->ahead - 1]]);
  }
  __global const StTriSetup* r = &w->records[w->record];
  w->r = r;
  const int4 b = st_record_tile_rect(r, w->tx, w->ty);
  w->covered = b.x > b.z || b.y > b.w ? 0 : st_tile_coverage(r, w->tx, w->ty, b.x, b.y, b.z, b.w);
  w->origin = st_record_origin(r);
  return true;
}

/* Moves to the current triangle's next covered pixel (w->x, w->y, w->p, w->depth); false when
 * its pixels are done. */
inline __attribute__((always_inline)) bool st_tile_fragment_next(StTileWalk* w) {
  const ulong m = w->covered;
  if (m == 0) return false;
  const uint p = (uint)popcount((m & (0ul - m)) - 1ul); /* lowest set bit */
  w->covered = m & (m - 1ul);
  w->p = p;
  w->x = w->tx + (int)(p & (ST_TILE_SIZE - 1));
  w->y = w->ty + (int)(p >> ST_TILE_LOG2);
  w->depth = st_record_depth(w->r, w->origin, w->x, w->y);
  return true;
}

/* ---- One body for a tile kernel's two forms. ----
 * A per-tile kernel runs as a work-group of ST_TILE_PIXELS work-items, one per pixel (the form for
 * GPUs), or as one work-item alone on its tile (the serial form for CPU devices, launched with
 * work-groups of one). Both forms call one always-inline body with `alone` a literal, so the
 * compiler specialises it: the body runs each per-pixel step over the pixels its work-item owns
 * (ST_FOR_OWNED_PIXELS: its own pixel, or all of them), keeps per-pixel tables in __local memory
 * (a work-group of one owns them alone), updates them with the st_owned_* operations (common.cl:
 * local atomics, or plain ones alone) and separates the steps with barriers, which a work-group
 * of one passes at once. */
#define ST_FOR_OWNED_PIXELS(p, alone)                                  \
  for (uint p = (alone) ? 0u : st_local_index(); p < ST_TILE_PIXELS; \
       p += (alone) ? 1u : (uint)ST_TILE_PIXELS)

/* The resolve of a tile (tx, ty) whose per-pixel results are ready: for each owned pixel inside
 * the image, RESOLVE(p, &transmittance) gives its colour, which goes with the background seen
 * through the transmittance into the image (st_put_resolved_pixel, with its fragment count
 * count[p]), then the tile's totals into the frame's counters. Uses the kernel's view, image,
 * depth_complexity, capture_depth_complexity and counters. */
#define ST_RESOLVE_OWNED_PIXELS(alone, tx, ty, count, scratch, RESOLVE)                          \
  do {                                                                                            \
    uint fragments_ = 0, deepest_ = 0;                                                            \
    ST_FOR_OWNED_PIXELS(p_, alone) {                                                              \
      const int x_ = (tx) + (int)(p_ & (ST_TILE_SIZE - 1)), y_ = (ty) + (int)(p_ >> ST_TILE_LOG2); \
      if (x_ >= view->width || y_ >= view->height) continue;                                      \
      float t_;                                                                                   \
      const float3 c_ = RESOLVE(p_, &t_);                                                         \
      st_put_resolved_pixel(view, image, depth_complexity, capture_depth_complexity, x_, y_, c_,  \
                            t_, (count)[p_], &fragments_, &deepest_);                             \
    }                                                                                             \
    st_report_owned_counts(alone, scratch, counters, fragments_, deepest_, 0u);                   \
  } while (0)

/* The colour (straight RGB, opacity) of record r's fragment at pixel (px, py), from the tile
 * kernel's usual arguments (st_fragment_colour). */
#define ST_RECORD_COLOUR(r, px, py) \
  st_fragment_colour(triangle_colors, tex_tris, atlas, view, (r)->source, px, py)

/* The arguments of a tile kernel that resolves the image from the binned records alone (wboit,
 * mboit), and their names. */
#define ST_TILE_RESOLVE_PARAMS                                                                  \
  __global const StTriSetup *records, __global const uint *bin_entries,                         \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,           \
      __global const float4 *triangle_colors, __global const StTexTriangle *tex_tris,           \
      __global const uint *atlas, __constant StViewConstants *view, __global uchar4 *image,     \
      __global ulong *counters, __global uint *depth_complexity,                                \
      const int capture_depth_complexity
#define ST_TILE_RESOLVE_ARGS                                                                    \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, triangle_colors, tex_tris, atlas,  \
      view, image, counters, depth_complexity, capture_depth_complexity

/* A step of ST_ORDERED_TILE's list: the tile walked in drawing order, FRAGMENT for each
 * fragment (ST_ORDERED_FRAGMENTS), then a barrier. */
#define ST_ORDERED_WALK_STEP(FRAGMENT)                                                     \
  ST_ORDERED_FRAGMENTS(alone_, records, bin_entries, begin_, end_, tx_, ty_, cover, entry, \
                       FRAGMENT);                                                          \
  barrier(CLK_LOCAL_MEM_FENCE);
/* The other kind of step: PIXEL(p) for each owned pixel, then a barrier. */
#define ST_ORDERED_PIXEL_STEP(PIXEL) \
  ST_FOR_OWNED_PIXELS(p_, alone_) {  \
    PIXEL(p_);                       \
  }                                  \
  barrier(CLK_LOCAL_MEM_FENCE);

/* The body of a tile kernel that walks its tile in drawing order (mlab, hybrid, adaptive,
 * stochastic, mboit): each owned pixel's tables set by CLEAR(p) and its count zeroed; then
 * STEPS(ST_ORDERED_WALK_STEP, ST_ORDERED_PIXEL_STEP), the method's list of walks and per-pixel
 * steps, each followed by a barrier; then the resolve (ST_RESOLVE_OWNED_PIXELS with RESOLVE).
 * Uses the kernel's arguments by their usual names and the tables of ST_ORDERED_TILE_TABLES. */
#define ST_ORDERED_TILE(alone, CLEAR, STEPS, RESOLVE)                                        \
  do {                                                                                         \
    const bool alone_ = (alone);                                                               \
    uint begin_, end_;                                                                         \
    st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin_, &end_);                        \
    ST_FOR_OWNED_PIXELS(p_, alone_) {                                                          \
      CLEAR(p_);                                                                               \
      count[p_] = 0;                                                                           \
    }                                                                                          \
    barrier(CLK_LOCAL_MEM_FENCE);                                                              \
    const int tx_ = (int)get_group_id(0) * ST_TILE_SIZE;                                       \
    const int ty_ = (int)get_group_id(1) * ST_TILE_SIZE;                                       \
    STEPS(ST_ORDERED_WALK_STEP, ST_ORDERED_PIXEL_STEP)                                         \
    ST_RESOLVE_OWNED_PIXELS(alone_, tx_, ty_, count, scratch, RESOLVE);                        \
  } while (0)

/* The __local tables of a tile kernel that walks its tile in drawing order: each pixel's
 * fragment count, the report's scratch and the ordered walk's round (ST_ORDERED_FRAGMENTS). */
#define ST_ORDERED_TILE_TABLES                                                        \
  __local uint count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS], entry[ST_TILE_PIXELS]; \
  __local ulong cover[ST_TILE_PIXELS];

/* A per-tile kernel's two forms from its one body: NAME, a work-group of ST_TILE_SIZE^2 items per
 * tile, and NAME_serial, one work-item alone per tile (launched with work-groups of one). BODY is
 * a macro: BODY(alone) declares the kernel's __local tables and calls the always-inline body with
 * `alone` a literal. */
#define ST_TILE_KERNELS(NAME, PARAMS, BODY)                                                     \
  __kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1))) void NAME(    \
      PARAMS) {                                                                                 \
    BODY(false)                                                                                 \
  }                                                                                             \
  __kernel __attribute__((reqd_work_group_size(1, 1, 1))) void NAME##_serial(PARAMS) {         \
    BODY(true)                                                                                  \
  }

/* The walk of the owner of tile (tx, ty): its share of a work-group's, or every entry alone. */
inline __attribute__((always_inline)) StTileWalk st_tile_walk_owned(
    bool alone, __global const StTriSetup* records, __global const uint* bin_entries, uint begin,
    uint end, int tx, int ty) {
  return alone ? st_tile_walk_alone(records, bin_entries, begin, end, tx, ty)
               : st_tile_walk(records, bin_entries, begin, end, tx, ty);
}

/* ---- A work-group's walk in drawing order, pixel by pixel. ----
 * For a method whose per-pixel update depends on the order of the pixel's fragments (on a GPU,
 * fragment-shader interlock or a spin lock per pixel): round by round, work-item i covers entry
 * base + i of the tile's list (its coverage in cover[i], its record in entry[i]; nothing past
 * `end`), and after a barrier each work-item takes the round's triangles in order for the pixel
 * it owns, so its pixel sees its fragments in the list's order, as a work-item alone on the tile
 * does with st_tile_walk_alone; that is the drawing order with the serial binner's lists (a
 * method asks for them with ClMethod::needsDrawingOrder). Returns how many triangles the round holds. Every work-item calls
 * it for every round, with a barrier after its reads of the round. */
inline __attribute__((always_inline)) uint st_ordered_round(__global const StTriSetup* records,
                                                            __global const uint* bin_entries,
                                                            uint base, uint end, int tx, int ty,
                                                            __local ulong* cover,
                                                            __local uint* entry) {
  const uint i = st_local_index();
  ulong mask = 0;
  uint record = 0;
  if (base + i < end) {
    record = bin_entries[base + i];
    __global const StTriSetup* r = &records[record];
    const int4 b = st_record_tile_rect(r, tx, ty);
    mask = b.x > b.z || b.y > b.w ? 0 : st_tile_coverage(r, tx, ty, b.x, b.y, b.z, b.w);
  }
  cover[i] = mask;
  entry[i] = record;
  barrier(CLK_LOCAL_MEM_FENCE);
  return min(end - base, (uint)ST_TILE_PIXELS);
}

/* Every fragment of the tile with each pixel's in the list's order, in either form of a tile
 * kernel: FRAGMENT(r, p, x, y, depth) for each (r its setup record, p its tile pixel). Alone, the
 * walk of st_tile_walk_alone; in a work-group, rounds of st_ordered_round in which each item
 * takes its own pixel's fragments. A statement with barriers in the work-group form: every
 * work-item reaches it. */
#define ST_ORDERED_FRAGMENTS(alone, records, bin_entries, begin, end, tx, ty, cover, entry,       \
                             FRAGMENT)                                                           \
  if (alone) {                                                                                    \
    StTileWalk f_ = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);                 \
    while (st_tile_triangle_next(&f_))                                                            \
      while (st_tile_fragment_next(&f_)) FRAGMENT(f_.r, f_.p, f_.x, f_.y, f_.depth);              \
  } else {                                                                                        \
    const uint p_ = st_local_index();                                                             \
    const int x_ = (tx) + (int)(p_ & (ST_TILE_SIZE - 1)), y_ = (ty) + (int)(p_ >> ST_TILE_LOG2);  \
    for (uint base_ = (begin); base_ < (end); base_ += ST_TILE_PIXELS) {                          \
      const uint n_ = st_ordered_round(records, bin_entries, base_, end, tx, ty, cover, entry);   \
      for (uint j_ = 0; j_ < n_; ++j_) {                                                          \
        if (!((cover[j_] >> p_) & 1ul)) continue;                                                 \
        __global const StTriSetup* r_ = &records[entry[j_]];                                      \
        FRAGMENT(r_, p_, x_, y_, st_record_depth(r_, st_record_origin(r_), x_, y_));              \
      }                                                                                           \
      barrier(CLK_LOCAL_MEM_FENCE); /* the round's tables are read before the next is written */ \
    }                                                                                             \
  }
