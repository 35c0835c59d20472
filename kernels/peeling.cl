/* peeling.cl: depth peeling (Everitt 2001) and dual depth peeling (Bavoil & Myers 2008).
 *
 * Both are exact: a fragment is the 64-bit visibility word (depth bits above triangle id,
 * st_visibility_word), so equal depths peel in triangle-id order, and every pass peels the
 * nearest (dp) or the nearest and farthest (ddp) word strictly inside what earlier passes left.
 *
 * Per-pixel state between passes is a range of words still to peel, kept as INCLUSIVE bounds:
 * after peeling word w from the front the lower bound becomes w + 1 (strictly greater than w),
 * after peeling w from the back the upper bound becomes w - 1. A finished pixel stores the empty
 * range (lower = ST_VISIBILITY_EMPTY, no word reaches it), so later passes test it like any other.
 * The first pass starts from the full range without reading state (no clear needed).
 *
 * One pass is one tile-owned raster launch (the pattern of raster_visibility): a work-group owns
 * an ST_TILE_SIZE^2 tile, keeps its pixels' bounds and the pass's candidates in local memory
 * (local 64-bit atom_min / atom_max), then each work-item composites its pixel's peeled layer(s)
 * into the accumulators and stores the new bounds. The peel and the blend of a layer are fused:
 * the work-group already owns the pixels, so no per-layer image is written and read back.
 * Each pass adds the fragments it peeled to ST_COUNTER_PASS_FRAGMENTS (one atomic per group);
 * the host reads the counter after every pass and stops after a pass that peeled nothing.
 * The first pass also counts fragments and depth complexity (ST_COUNTER_FRAGMENTS, _MAX_DEPTH,
 * the optional depth-complexity map) and lists the tiles that have triangles (ST_COUNTER_METHOD_0
 * counts them); later passes run on those tiles only. */

#define PEELING_RANGE_DONE_LO ST_VISIBILITY_EMPTY
#define PEELING_RANGE_DONE_HI 0ul

/* Back layer composited "over" a back accumulator (colour premultiplied, transmittance). */
inline void peeling_composite_over(float3* color, float* transmittance, float4 c) {
  *color = c.w * c.xyz + (1.0f - c.w) * *color;
  *transmittance *= 1.0f - c.w;
}

/* A tile's counts for one pass, gathered with local atomics (one barrier, where group
 * reductions would cost a barrier per level) and added to the frame counters by one work-item:
 * [0] fragments peeled (ST_COUNTER_PASS_FRAGMENTS), [1] fragments rasterized and [2] the deepest
 * pixel (first pass only: ST_COUNTER_FRAGMENTS, ST_COUNTER_MAX_DEPTH). */
#define PEELING_TILE_PEELED 0
#define PEELING_TILE_FRAGMENTS 1
#define PEELING_TILE_DEEPEST 2

/* Call with every work-item, after its pixels are done; ends with the tile's report. The first
 * pass also lists the tile if it has triangles (ST_COUNTER_METHOD_0 counts the list). */
inline __attribute__((always_inline)) void peeling_tile_counts_report(
    bool alone, __local uint* tile_counts, __global ulong* counters, uint peeled, uint fragments,
    uint depth, uint tile, bool list_tile, __global uint* tile_list) {
  if (peeled) st_owned_add_uint(alone, &tile_counts[PEELING_TILE_PEELED], peeled);
  if (fragments) st_owned_add_uint(alone, &tile_counts[PEELING_TILE_FRAGMENTS], fragments);
  if (depth) st_owned_max_uint(alone, &tile_counts[PEELING_TILE_DEEPEST], depth);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (st_local_index() == 0) {
    const uint n = tile_counts[PEELING_TILE_PEELED];
    const uint f = tile_counts[PEELING_TILE_FRAGMENTS];
    const uint d = tile_counts[PEELING_TILE_DEEPEST];
    if (n) st_counter_add(&counters[ST_COUNTER_PASS_FRAGMENTS], (ulong)n);
    if (f) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)f);
    if (d) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)d);
    if (list_tile) tile_list[st_counter_claim(&counters[ST_COUNTER_METHOD_0], 1)] = tile;
  }
}

/* The screen tile this work-group owns. The first pass runs one work-group per screen tile (it
 * initializes every pixel) and lists the tiles whose bins hold triangles; later passes run one
 * work-group per listed tile: a tile no triangle touches has nothing to peel, and on a CPU the
 * fixed cost of a work-group is a large part of a pass. Every triangle is still rasterized in
 * every pass. */
inline uint peeling_tile(__global const uint* tile_list, uint tiles_x, int first_pass) {
  return first_pass ? (uint)get_group_id(1) * tiles_x + (uint)get_group_id(0)
                    : tile_list[get_group_id(0)];
}

/* Call with every work-item once the tile's per-pixel tables are set: clears the tile's counts
 * and begins the walk of its bin list; returns whether the list holds any entry. */
inline __attribute__((always_inline)) bool peeling_tile_walk_begin(
    bool alone, StTileWalk* f, __local uint* tile_counts, __global const StTriSetup* records,
    __global const uint* bin_entries, __global const uint* tile_offsets, uint bin_capacity,
    uint tile, int tx, int ty) {
  if (st_local_index() == 0) {
    tile_counts[PEELING_TILE_PEELED] = 0;
    tile_counts[PEELING_TILE_FRAGMENTS] = 0;
    tile_counts[PEELING_TILE_DEEPEST] = 0;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  *f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);
  return begin < end;
}

/* A pass's kernel arguments, shared by both methods' kernels and both forms. */
#define PEELING_PASS_PARAMS                                                                       \
  __global const StTriSetup *records, __global const uint *bin_entries,                            \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,              \
      const int width, const int height
#define PEELING_PASS_ARGS records, bin_entries, tile_offsets, tiles_x, bin_capacity, width, height
#define PEELING_FRAME_PARAMS                                                                      \
  __global const float4 *triangle_colors, __global const StTexTriangle *tex_tris,                 \
      __global const uint *atlas, __constant StViewConstants *view, __global ulong *counters,      \
      __global uint *tile_list, __global uint *depth_complexity,                                   \
      const int capture_depth_complexity, const int first_pass
#define PEELING_FRAME_ARGS                                                                        \
  triangle_colors, tex_tris, atlas, view, counters, tile_list, depth_complexity,                   \
      capture_depth_complexity, first_pass

/* ---- dp: one layer per pass. ----
 * lower[p]: inclusive lower bound of the words still to peel (last peeled word + 1).
 * accum[p]: front-to-back accumulator, xyz = colour, w = transmittance. */

/* The end of a dp pass at pixel (x, y) inside the image, whose range started at my_lo and whose
 * nearest word inside it is `word` (EMPTY: none): blends that layer and stores the new bound.
 * Returns the layers peeled (0 or 1). */
inline uint peeling_dp_pixel_done(int x, int y, size_t pixel, ulong my_lo, ulong word,
                                  uint depth_count, __global ulong* lower, __global float4* accum,
                                  __global const float4* triangle_colors,
                                  __global const StTexTriangle* tex_tris,
                                  __global const uint* atlas, __constant StViewConstants* view,
                                  __global uint* depth_complexity, int capture_depth_complexity,
                                  int first_pass) {
  uint peeled = 0;
  if (word != ST_VISIBILITY_EMPTY) {
    float4 a = first_pass ? (float4)(0.0f, 0.0f, 0.0f, 1.0f) : accum[pixel];
    float3 color = a.xyz;
    float transmittance = a.w;
    st_composite_under(&color, &transmittance,
                       st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)word, x,
                                          y));
    accum[pixel] = (float4)(color, transmittance);
    lower[pixel] = word + 1ul;
    peeled = 1;
  } else {
    if (first_pass) accum[pixel] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
    if (my_lo != PEELING_RANGE_DONE_LO) lower[pixel] = PEELING_RANGE_DONE_LO;
  }
  if (first_pass && capture_depth_complexity) depth_complexity[pixel] = depth_count;
  return peeled;
}
/* A dp pass over the tile, in either form (tile_walk.cl: one body for a tile kernel's two forms);
 * the tables are the kernel's __local ones, ST_TILE_PIXELS each. */
inline __attribute__((always_inline)) void peeling_dp_tile(
    bool alone, PEELING_PASS_PARAMS, __global ulong* lower, __global float4* accum,
    PEELING_FRAME_PARAMS, __local ulong* lo, __local ulong* best, __local uint* depth_count,
    __local uint* tile_counts) {
  const uint tile = peeling_tile(tile_list, tiles_x, first_pass);
  const int tx = (int)(tile % tiles_x) * ST_TILE_SIZE, ty = (int)(tile / tiles_x) * ST_TILE_SIZE;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    const bool inside = x < width && y < height;
    lo[p] = !inside ? PEELING_RANGE_DONE_LO
                    : (first_pass ? 0ul : lower[(size_t)y * (size_t)width + (size_t)x]);
    best[p] = ST_VISIBILITY_EMPTY;
    depth_count[p] = 0;
  }
  StTileWalk f;
  const bool listed = peeling_tile_walk_begin(alone, &f, tile_counts, records, bin_entries,
                                              tile_offsets, bin_capacity, tile, tx, ty);
  uint fragments = 0;
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint p = f.p;
      const ulong word = st_visibility_word(f.depth, f.r->source);
      /* strictly behind the last peeled word, nearest such (atomics only in a work-group: a
       * plain read of best[] beside other work-items' atom_min would be a data race) */
      if (word >= lo[p]) st_owned_min_ulong(alone, &best[p], word);
      if (first_pass) {
        st_owned_add_uint(alone, &depth_count[p], 1u);
        ++fragments;
      }
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);

  uint peeled = 0, deepest = 0;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (x >= width || y >= height) continue;
    peeled += peeling_dp_pixel_done(x, y, (size_t)y * (size_t)width + (size_t)x, lo[p], best[p],
                                    depth_count[p], lower, accum, triangle_colors, tex_tris,
                                    atlas, view, depth_complexity, capture_depth_complexity,
                                    first_pass);
    deepest = max(deepest, depth_count[p]);
  }
  /* Unconditional (later passes report zeros): a barrier under a branch on a kernel argument
   * (if (first_pass) ...) lost the report on PoCL 3.1 although every work-item takes it. */
  peeling_tile_counts_report(alone, tile_counts, counters, peeled, fragments, deepest, tile,
                             first_pass && listed, tile_list);
}

/* The two forms of a dp pass, one body: peeling_dp_peel, a work-group per tile, and
 * peeling_dp_peel_serial for a CPU device, one work-item alone per tile (launched with
 * work-groups of one, so peeling_tile's group id is the tile's). */
#define PEELING_DP_KERNEL(NAME, GROUP_SIDE, ALONE)                                                \
  __kernel __attribute__((reqd_work_group_size(GROUP_SIDE, GROUP_SIDE, 1))) void NAME(            \
      PEELING_PASS_PARAMS, __global ulong* lower, __global float4* accum, PEELING_FRAME_PARAMS) { \
    __local ulong lo[ST_TILE_PIXELS], best[ST_TILE_PIXELS];                                       \
    __local uint depth_count[ST_TILE_PIXELS], tile_counts[3];                                     \
    peeling_dp_tile(ALONE, PEELING_PASS_ARGS, lower, accum, PEELING_FRAME_ARGS, lo, best,         \
                    depth_count, tile_counts);                                                    \
  }
PEELING_DP_KERNEL(peeling_dp_peel, ST_TILE_SIZE, false)
PEELING_DP_KERNEL(peeling_dp_peel_serial, 1, true)

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void peeling_dp_resolve(__global const float4* accum, __constant StViewConstants* view,
                        __global uchar4* image) {
  const int x = get_global_id(0), y = get_global_id(1);
  const int width = view->width;
  if (x >= width || y >= view->height) return;
  const size_t pixel = (size_t)y * (size_t)width + (size_t)x;
  const float4 a = accum[pixel];
  image[pixel] = st_pack_rgba8(st_over(a, st_background(view, x, y)));
}

/* ---- ddp: the nearest and the farthest remaining layer per pass. ----
 * range[p] = (lo, hi): inclusive bounds of the words still to peel.
 * front[p]: front layers composited "under" (xyz colour, w transmittance), nearest first.
 * back[p]: back layers composited "over", farthest first (xyz premultiplied colour of the
 *          layers behind, w their transmittance).
 * When the nearest and farthest remaining word are the same fragment (an odd count), it is
 * composited once, into the front accumulator, and the pixel is finished. */

/* The end of a ddp pass at pixel (x, y) inside the image, whose range started as my_range and
 * whose nearest and farthest words inside it are `nearest` (EMPTY: none) and `farthest`: blends
 * those layers and stores the new range. Returns the layers peeled (0, 1 or 2). */
inline uint peeling_ddp_pixel_done(int x, int y, size_t pixel, ulong2 my_range, ulong nearest,
                                   ulong farthest, uint depth_count, __global ulong2* range,
                                   __global float4* front_accum, __global float4* back_accum,
                                   __global const float4* triangle_colors,
                                   __global const StTexTriangle* tex_tris,
                                   __global const uint* atlas, __constant StViewConstants* view,
                                   __global uint* depth_complexity, int capture_depth_complexity,
                                   int first_pass) {
  uint peeled = 0;
  const ulong f = nearest;
  if (f != ST_VISIBILITY_EMPTY) {
    /* A candidate exists, so farthest >= nearest (a lone word 0 leaves farthest at 0 == f). */
    const ulong b = max(farthest, f);
    float4 fa = first_pass ? (float4)(0.0f, 0.0f, 0.0f, 1.0f) : front_accum[pixel];
    float3 color = fa.xyz;
    float transmittance = fa.w;
    st_composite_under(&color, &transmittance, st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)f, x, y));
    front_accum[pixel] = (float4)(color, transmittance);
    peeled = 1;
    if (b != f) {
      float4 ba = first_pass ? (float4)(0.0f, 0.0f, 0.0f, 1.0f) : back_accum[pixel];
      float3 bcolor = ba.xyz;
      float btrans = ba.w;
      peeling_composite_over(&bcolor, &btrans, st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)b, x, y));
      back_accum[pixel] = (float4)(bcolor, btrans);
      range[pixel] = (ulong2)(f + 1ul, b - 1ul); /* empty when f + 1 == b: next pass finds none */
      peeled = 2;
    } else {
      if (first_pass) back_accum[pixel] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
      range[pixel] = (ulong2)(PEELING_RANGE_DONE_LO, PEELING_RANGE_DONE_HI);
    }
  } else {
    if (first_pass) {
      front_accum[pixel] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
      back_accum[pixel] = (float4)(0.0f, 0.0f, 0.0f, 1.0f);
    }
    if (my_range.x != PEELING_RANGE_DONE_LO)
      range[pixel] = (ulong2)(PEELING_RANGE_DONE_LO, PEELING_RANGE_DONE_HI);
  }
  if (first_pass && capture_depth_complexity) depth_complexity[pixel] = depth_count;
  return peeled;
}

/* A ddp pass over the tile, in either form (as peeling_dp_tile). */
inline __attribute__((always_inline)) void peeling_ddp_tile(
    bool alone, PEELING_PASS_PARAMS, __global ulong2* range, __global float4* front_accum,
    __global float4* back_accum, PEELING_FRAME_PARAMS, __local ulong* lo, __local ulong* hi,
    __local ulong* nearest, __local ulong* farthest, __local uint* depth_count,
    __local uint* tile_counts) {
  const uint tile = peeling_tile(tile_list, tiles_x, first_pass);
  const int tx = (int)(tile % tiles_x) * ST_TILE_SIZE, ty = (int)(tile / tiles_x) * ST_TILE_SIZE;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    ulong2 bounds = (ulong2)(PEELING_RANGE_DONE_LO, PEELING_RANGE_DONE_HI);
    if (x < width && y < height)
      bounds = first_pass ? (ulong2)(0ul, ST_VISIBILITY_EMPTY)
                          : range[(size_t)y * (size_t)width + (size_t)x];
    lo[p] = bounds.x;
    hi[p] = bounds.y;
    nearest[p] = ST_VISIBILITY_EMPTY;
    farthest[p] = 0ul;
    depth_count[p] = 0;
  }
  StTileWalk f;
  const bool listed = peeling_tile_walk_begin(alone, &f, tile_counts, records, bin_entries,
                                              tile_offsets, bin_capacity, tile, tx, ty);
  uint fragments = 0;
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint p = f.p;
      const ulong word = st_visibility_word(f.depth, f.r->source);
      if (word >= lo[p] && word <= hi[p]) {
        st_owned_min_ulong(alone, &nearest[p], word);
        st_owned_max_ulong(alone, &farthest[p], word);
      }
      if (first_pass) {
        st_owned_add_uint(alone, &depth_count[p], 1u);
        ++fragments;
      }
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);

  uint peeled = 0, deepest = 0;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (x >= width || y >= height) continue;
    peeled += peeling_ddp_pixel_done(x, y, (size_t)y * (size_t)width + (size_t)x,
                                     (ulong2)(lo[p], hi[p]), nearest[p], farthest[p],
                                     depth_count[p], range, front_accum, back_accum,
                                     triangle_colors, tex_tris, atlas, view, depth_complexity,
                                     capture_depth_complexity, first_pass);
    deepest = max(deepest, depth_count[p]);
  }
  peeling_tile_counts_report(alone, tile_counts, counters, peeled, fragments, deepest, tile,
                             first_pass && listed, tile_list);
}

/* The two forms of a ddp pass, one body (as dp's): peeling_ddp_peel and peeling_ddp_peel_serial. */
#define PEELING_DDP_KERNEL(NAME, GROUP_SIDE, ALONE)                                               \
  __kernel __attribute__((reqd_work_group_size(GROUP_SIDE, GROUP_SIDE, 1))) void NAME(            \
      PEELING_PASS_PARAMS, __global ulong2* range, __global float4* front_accum,                  \
      __global float4* back_accum, PEELING_FRAME_PARAMS) {                                        \
    __local ulong lo[ST_TILE_PIXELS], hi[ST_TILE_PIXELS];                                         \
    __local ulong nearest[ST_TILE_PIXELS], farthest[ST_TILE_PIXELS];                              \
    __local uint depth_count[ST_TILE_PIXELS], tile_counts[3];                                     \
    peeling_ddp_tile(ALONE, PEELING_PASS_ARGS, range, front_accum, back_accum,                    \
                     PEELING_FRAME_ARGS, lo, hi, nearest, farthest, depth_count, tile_counts);    \
  }
PEELING_DDP_KERNEL(peeling_ddp_peel, ST_TILE_SIZE, false)
PEELING_DDP_KERNEL(peeling_ddp_peel_serial, 1, true)

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void peeling_ddp_resolve(__global const float4* front_accum, __global const float4* back_accum,
                         __constant StViewConstants* view, __global uchar4* image) {
  const int x = get_global_id(0), y = get_global_id(1);
  const int width = view->width;
  if (x >= width || y >= view->height) return;
  const size_t pixel = (size_t)y * (size_t)width + (size_t)x;
  const float4 f = front_accum[pixel];
  const float4 b = back_accum[pixel];
  image[pixel] = st_pack_rgba8(st_over(f, st_over(b, st_background(view, x, y))));
}
