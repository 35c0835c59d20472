/* bucket.cl: bucket depth peeling (Liu, Huang, Liu & Wu, "Efficient depth peeling via bucket
 * sort", HPG 2009): `bdp` and its adaptive two-pass variant `bdp2`.
 *
 * Geometry passes, each one launch over all screen tiles (tile ownership, DESIGN.md):
 *   1. bucket_bounds     nearest and farthest fragment depth per pixel (min/max), fragment counts;
 *   2. bucket_histogram  (bdp2 only) occupancy of ST_BUCKET_FINE_BINS uniform depth bins between
 *                        the pixel's min and max, one bit per bin (set with atomic OR);
 *   3. bucket_sort_*     every fragment goes to one of ST_BDP_BUCKETS buckets; then the buckets are
 *                        composited front to back in the same launch.
 * Bucket of a fragment at depth d, pixel range [lo, hi]:
 *   bdp:  floor((d - lo) / (hi - lo) * ST_BDP_BUCKETS), clamped to the last bucket;
 *   bdp2: the rank of its fine bin among the pixel's occupied fine bins (number of occupied bins
 *         nearer than it), so the buckets are re-divided to where the fragments are (the paper's
 *         aim: one fragment per subinterval): two fragments collide only when they share a fine
 *         bin. Ranks >= ST_BDP_BUCKETS (a pixel with more
 *         occupied bins than buckets) are dropped: the farthest fragments, the least visible ones.
 * A bucket keeps ONE fragment: the 64-bit atomic MIN of the (depth bits, triangle id) word, i.e.
 * the nearest fragment that landed in it, ties by the lower triangle id (the papers' MIN blending;
 * deterministic whatever the arrival order). Every other fragment landing in an occupied bucket is
 * lost: lost = fragments - occupied buckets, added to ST_COUNTER_FRAGMENTS_LOST once per tile.
 * With max == min (all of a pixel's fragments at one depth) the scale is 0, so they all land in
 * bucket 0: one is kept, the others are lost; no division by zero.
 *
 * Per-pixel data between passes is stored tile-major (tile * ST_TILE_PIXELS + pixel in tile), so a
 * work-group reads and writes one contiguous block. The buckets of pass 3 live in local memory
 * (ST_BDP_BUCKETS x ST_TILE_PIXELS x 8 bytes = 16 KB per tile) where the device has room
 * (bucket_sort_local), else in a global buffer of ST_BDP_BUCKETS words per pixel, the published
 * method's footprint (bucket_sort_global). */

#define ST_BUCKET_NO_SLOT (-1)

inline uint bucket_tile_index(uint tiles_x) { return get_group_id(1) * tiles_x + get_group_id(0); }

/* Position of a fragment at `depth` in [0, bins): uniform subdivision of the pixel's range by
 * `scale` = bins / (hi - lo) (0 when hi == lo). Out-of-range values (rounding) clamp to the ends;
 * a NaN product (0 * inf for an underflowing range) goes to bin 0. */
inline int bucket_uniform_bin(float depth, float lo, float scale, int bins) {
  const float t = (fmax(depth, 0.0f) - lo) * scale;
  return t > 0.0f ? (t < (float)bins ? (int)t : bins - 1) : 0;
}

/* The `scale` of bucket_uniform_bin for a pixel's depth range (lo, hi) cut into `bins`. */
inline float bucket_scale(float2 range, int bins) {
  const float s = range.y > range.x ? (float)bins / (range.y - range.x) : 0.0f;
  return isfinite(s) ? s : 0.0f;
}

/* Bucket of a fragment of tile pixel p, or ST_BUCKET_NO_SLOT when bdp2 has no bucket left for it.
 * bitmap / prefix are the pixel's fine-bin occupancy words and, per word, the number of occupied
 * bins before it (saturated at 255), both word-major: [word * ST_TILE_PIXELS + p]. */
inline int bucket_slot(__local const float* lo, __local const float* scale,
                       __local const uint* bitmap, __local const uchar* prefix, int adaptive,
                       uint p, float depth) {
  if (!adaptive) return bucket_uniform_bin(depth, lo[p], scale[p], ST_BDP_BUCKETS);
  const int bin = bucket_uniform_bin(depth, lo[p], scale[p], ST_BUCKET_FINE_BINS);
  const uint w = (uint)bin >> 5;
  const uint below = bitmap[w * ST_TILE_PIXELS + p] & ((1u << ((uint)bin & 31u)) - 1u);
  const uint rank = (uint)prefix[w * ST_TILE_PIXELS + p] + popcount(below);
  return rank < ST_BDP_BUCKETS ? (int)rank : ST_BUCKET_NO_SLOT;
}

/* Loads tile pixel lid's range (and for bdp2 its occupancy words and their prefix counts)
 * into the tile's local arrays. Followed by a barrier in the caller. */
inline void bucket_load_pixel(__global const float2* bounds, __global const uint* bitmaps,
                              int adaptive, uint tile, uint lid, __local float* lo,
                              __local float* scale, __local uint* bitmap, __local uchar* prefix) {
  const float2 range = bounds[tile * ST_TILE_PIXELS + lid];
  lo[lid] = range.x;
  scale[lid] = bucket_scale(range, adaptive ? ST_BUCKET_FINE_BINS : ST_BDP_BUCKETS);
  if (adaptive) {
    uint occupied = 0;
    for (uint w = 0; w < ST_BUCKET_FINE_WORDS; ++w) {
      const uint bits = bitmaps[(tile * ST_BUCKET_FINE_WORDS + w) * ST_TILE_PIXELS + lid];
      bitmap[w * ST_TILE_PIXELS + lid] = bits;
      prefix[w * ST_TILE_PIXELS + lid] = (uchar)min(occupied, 255u);
      occupied += popcount(bits);
    }
  }
}

/* Lowest set bit of a non-zero mask (OpenCL C 1.2 has clz, not ctz). */
inline uint bucket_lowest_bit(uint mask) { return 31u - clz(mask & (0u - mask)); }

/* Tiles without triangles skip the per-pixel work but still reach every barrier: PoCL 3.1 lost
 * private values that lived across barriers after a (uniform) early return from such a kernel.
 * Tile totals (fragments, deepest pixel, buckets kept) are gathered with local atomics.
 *
 * Each pass is one always-inline body for the kernel's two forms (tile_walk.cl): a work-group
 * per tile, or one work-item alone on its tile (the _serial kernels, for CPU devices: a
 * work-group of its own, so bucket_tile_index is its tile and the __local tables are its alone).
 * A bucket keeps the minimum word whatever the order of arrival, so the bounds, histograms,
 * buckets and losses of both forms are the same. */

/* The pixel of tile pixel p, in image coordinates. */
#define BUCKET_PIXEL_XY(p, x, y)                                              \
  const int x = (int)get_group_id(0) * ST_TILE_SIZE + (int)((p) & (ST_TILE_SIZE - 1)); \
  const int y = (int)get_group_id(1) * ST_TILE_SIZE + (int)((p) >> ST_TILE_LOG2)

/* ---- Pass 1: depth bounds. ---- */
#define BUCKET_BOUNDS_PARAMS                                                                      \
  __global const StTriSetup *records, __global const uint *bin_entries,                            \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,              \
      const int width, const int height, __global float2 *bounds, __global ulong *counters,        \
      __global uint *depth_complexity, const int capture_depth_complexity
#define BUCKET_BOUNDS_ARGS                                                                        \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, width, height, bounds, counters,      \
      depth_complexity, capture_depth_complexity

inline __attribute__((always_inline)) void bucket_bounds_tile(bool alone, BUCKET_BOUNDS_PARAMS,
                                                              __local uint* lo, __local uint* hi,
                                                              __local uint* count,
                                                              __local uint* totals) {
  const uint tile = bucket_tile_index(tiles_x);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  const bool busy = begin != end; /* the same for the whole work-group */
  ST_FOR_OWNED_PIXELS(p, alone) {
    lo[p] = 0xFFFFFFFFu;
    hi[p] = 0u;
    count[p] = 0u;
  }
  if (st_local_index() == 0) totals[0] = totals[1] = 0u;
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  uint fragments = 0;
  StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint p = f.p;
      /* Non-negative floats order like their bit patterns. */
      const uint bits = as_uint(fmax(f.depth, 0.0f));
      st_owned_min_uint(alone, &lo[p], bits);
      st_owned_max_uint(alone, &hi[p], bits);
      st_owned_add_uint(alone, &count[p], 1u);
      ++fragments;
    }
  }
  if (fragments) st_owned_add_uint(alone, &totals[0], fragments);
  barrier(CLK_LOCAL_MEM_FENCE);
  uint deepest = 0;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const uint n = count[p];
    /* Tiles without triangles are skipped by the later passes: nothing to store. */
    if (busy)
      bounds[tile * ST_TILE_PIXELS + p] =
          n ? (float2)(as_float(lo[p]), as_float(hi[p])) : (float2)(0.0f, 0.0f);
    BUCKET_PIXEL_XY(p, x, y);
    if (capture_depth_complexity && x < width && y < height) depth_complexity[y * width + x] = n;
    deepest = max(deepest, n);
  }
  if (deepest) st_owned_max_uint(alone, &totals[1], deepest);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (st_local_index() == 0) {
    if (totals[0]) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)totals[0]);
    if (totals[1]) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)totals[1]);
  }
}

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_bounds(BUCKET_BOUNDS_PARAMS) {
  __local uint lo[ST_TILE_PIXELS], hi[ST_TILE_PIXELS], count[ST_TILE_PIXELS], totals[2];
  bucket_bounds_tile(false, BUCKET_BOUNDS_ARGS, lo, hi, count, totals);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_bounds_serial(BUCKET_BOUNDS_PARAMS) {
  __local uint lo[ST_TILE_PIXELS], hi[ST_TILE_PIXELS], count[ST_TILE_PIXELS], totals[2];
  bucket_bounds_tile(true, BUCKET_BOUNDS_ARGS, lo, hi, count, totals);
}

/* ---- Pass 2 (bdp2): fine-bin occupancy. ---- */
#define BUCKET_HISTOGRAM_PARAMS                                                                   \
  __global const StTriSetup *records, __global const uint *bin_entries,                            \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,              \
      __global const float2 *bounds, __global uint *bitmaps
#define BUCKET_HISTOGRAM_ARGS records, bin_entries, tile_offsets, tiles_x, bin_capacity, bounds, bitmaps

inline __attribute__((always_inline)) void bucket_histogram_tile(bool alone,
                                                                 BUCKET_HISTOGRAM_PARAMS,
                                                                 __local float* lo,
                                                                 __local float* scale,
                                                                 __local uint* bits) {
  const uint tile = bucket_tile_index(tiles_x);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  const bool busy = begin != end; /* the same for the whole work-group; empty tiles are skipped */
  if (busy) {
    ST_FOR_OWNED_PIXELS(p, alone) {
      const float2 range = bounds[tile * ST_TILE_PIXELS + p];
      lo[p] = range.x;
      scale[p] = bucket_scale(range, ST_BUCKET_FINE_BINS);
      for (uint w = 0; w < ST_BUCKET_FINE_WORDS; ++w) bits[w * ST_TILE_PIXELS + p] = 0u;
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint bin = (uint)bucket_uniform_bin(f.depth, lo[f.p], scale[f.p], ST_BUCKET_FINE_BINS);
      st_owned_or_uint(alone, &bits[(bin >> 5) * ST_TILE_PIXELS + f.p], 1u << (bin & 31u));
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  if (busy) {
    ST_FOR_OWNED_PIXELS(p, alone) {
      for (uint w = 0; w < ST_BUCKET_FINE_WORDS; ++w)
        bitmaps[(tile * ST_BUCKET_FINE_WORDS + w) * ST_TILE_PIXELS + p] = bits[w * ST_TILE_PIXELS + p];
    }
  }
}

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_histogram(BUCKET_HISTOGRAM_PARAMS) {
  __local float lo[ST_TILE_PIXELS], scale[ST_TILE_PIXELS];
  __local uint bits[ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS];
  bucket_histogram_tile(false, BUCKET_HISTOGRAM_ARGS, lo, scale, bits);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_histogram_serial(BUCKET_HISTOGRAM_PARAMS) {
  __local float lo[ST_TILE_PIXELS], scale[ST_TILE_PIXELS];
  __local uint bits[ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS];
  bucket_histogram_tile(true, BUCKET_HISTOGRAM_ARGS, lo, scale, bits);
}

#define BUCKET_SORT_PARAMS                                                                        \
  __global const StTriSetup *records, __global const uint *bin_entries,                            \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,              \
      __global const float2 *bounds, __global const uint *bitmaps, const int adaptive,             \
      __global const float4 *triangle_colors, __global const StTexTriangle *tex_tris,              \
      __global const uint *atlas, __constant StViewConstants *view, __global uchar4 *image,        \
      __global ulong *counters
#define BUCKET_TABLE_PARAMS \
  __local float *lo, __local float *scale, __local uint *bitmap, __local uchar *prefix

/* ---- Pass 3: bucket sort and front-to-back composite. ----
 * Both variants take the per-pixel tables as __local arguments sized by the host: lo and scale
 * (ST_TILE_PIXELS floats each), and for bdp2 bitmap (ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS uints)
 * and prefix (as many uchars); bdp passes them with one element.
 * One body for the tile's buckets in either address space (OpenCL C 1.2 has no generic address
 * space): the tile's ST_BDP_BUCKETS * ST_TILE_PIXELS words start TILE_STRIDE words per tile into
 * `all_buckets` (0 for a local table of the tile's own), FENCE is the fence of the barriers that
 * order them. `used` (ST_TILE_PIXELS) and `totals` (fragments, kept) are the
 * kernel's __local scratch. */
#define BUCKET_DEFINE_SORT(NAME, SPACE, TILE_STRIDE, FENCE)                                       \
inline __attribute__((always_inline)) void NAME(bool alone, BUCKET_SORT_PARAMS,                   \
                                                SPACE ulong* all_buckets, BUCKET_TABLE_PARAMS,    \
                                                __local uint* used, __local uint* totals) {       \
  const uint tile = bucket_tile_index(tiles_x);                                                   \
  uint begin, end;                                                                                \
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);                               \
  SPACE ulong* buckets = all_buckets + (size_t)tile * (TILE_STRIDE);                              \
  const bool busy = begin != end; /* the same for the whole work-group */                         \
  ST_FOR_OWNED_PIXELS(p, alone) {                                                                 \
    if (busy) { /* tiles without triangles only write the background */                           \
      for (uint b = 0; b < ST_BDP_BUCKETS; ++b)                                                   \
        buckets[b * ST_TILE_PIXELS + p] = ST_VISIBILITY_EMPTY;                                    \
      bucket_load_pixel(bounds, bitmaps, adaptive, tile, p, lo, scale, bitmap, prefix);           \
    }                                                                                             \
    used[p] = 0u;                                                                                 \
  }                                                                                               \
  if (st_local_index() == 0) totals[0] = totals[1] = 0u;                                          \
  barrier(FENCE);                                                                                 \
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;   \
  uint fragments = 0;                                                                             \
  StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);             \
  while (st_tile_triangle_next(&f)) {                                                             \
    while (st_tile_fragment_next(&f)) {                                                           \
      ++fragments;                                                                                \
      const uint p = f.p;                                                                         \
      const int slot = bucket_slot(lo, scale, bitmap, prefix, adaptive, p, f.depth);              \
      if (slot == ST_BUCKET_NO_SLOT) continue;                                                    \
      const ulong word = st_visibility_word(f.depth, f.r->source);                                \
      SPACE ulong* bucket = &buckets[(uint)slot * ST_TILE_PIXELS + p];                            \
      if (alone) *bucket = min(*bucket, word);                                                    \
      else ST_ATOM64_MIN(bucket, word);                                                                \
      st_owned_or_uint(alone, &used[p], 1u << (uint)slot);                                        \
    }                                                                                             \
  }                                                                                               \
  if (fragments) st_owned_add_uint(alone, &totals[0], fragments);                                 \
  barrier(FENCE);                                                                                 \
  uint kept = 0;                                                                                  \
  ST_FOR_OWNED_PIXELS(p, alone) {                                                                 \
    BUCKET_PIXEL_XY(p, x, y);                                                                     \
    uint mask = used[p];                                                                          \
    kept += popcount(mask);                                                                       \
    if (x >= view->width || y >= view->height) continue;                                          \
    float3 color = (float3)(0.0f);                                                                \
    float transmittance = 1.0f;                                                                   \
    for (; mask; mask &= mask - 1u) {                                                             \
      const ulong word = buckets[bucket_lowest_bit(mask) * ST_TILE_PIXELS + p];                   \
      st_composite_under(&color, &transmittance,                                                  \
                         st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)word,   \
                                            x, y));                                               \
    }                                                                                             \
    color += transmittance * st_background(view, x, y);                                          \
    image[y * view->width + x] = st_pack_rgba8(color);                                            \
  }                                                                                               \
  if (kept) st_owned_add_uint(alone, &totals[1], kept);                                           \
  barrier(CLK_LOCAL_MEM_FENCE);                                                                   \
  /* Fragments scattered minus buckets occupied: the ones that collided or found no bucket. */    \
  if (st_local_index() == 0 && totals[0] > totals[1])                                             \
    st_counter_add(&counters[ST_COUNTER_FRAGMENTS_LOST], (ulong)(totals[0] - totals[1]));               \
}

/* Buckets in local memory (`all_buckets` holds the tile's) or in global memory (every tile's,
 * tile-major), in either form. */
BUCKET_DEFINE_SORT(bucket_sort_local_tile, __local, 0, CLK_LOCAL_MEM_FENCE)
BUCKET_DEFINE_SORT(bucket_sort_global_tile, __global, ST_BDP_BUCKETS * ST_TILE_PIXELS,
                   CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE)

#define BUCKET_SORT_ARGS                                                                          \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, bounds, bitmaps, adaptive,            \
      triangle_colors, tex_tris, atlas, view, image, counters

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_sort_local(BUCKET_SORT_PARAMS, __local ulong* buckets, BUCKET_TABLE_PARAMS) {
  __local uint used[ST_TILE_PIXELS], totals[2];
  bucket_sort_local_tile(false, BUCKET_SORT_ARGS, buckets, lo, scale, bitmap, prefix, used,
                         totals);
}

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_sort_global(BUCKET_SORT_PARAMS, __global ulong* all_buckets, BUCKET_TABLE_PARAMS) {
  __local uint used[ST_TILE_PIXELS], totals[2];
  bucket_sort_global_tile(false, BUCKET_SORT_ARGS, all_buckets, lo, scale, bitmap, prefix, used,
                          totals);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_sort_local_serial(BUCKET_SORT_PARAMS, __local ulong* buckets, BUCKET_TABLE_PARAMS) {
  __local uint used[ST_TILE_PIXELS], totals[2];
  bucket_sort_local_tile(true, BUCKET_SORT_ARGS, buckets, lo, scale, bitmap, prefix, used,
                         totals);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_sort_global_serial(BUCKET_SORT_PARAMS, __global ulong* all_buckets,
                               BUCKET_TABLE_PARAMS) {
  __local uint used[ST_TILE_PIXELS], totals[2];
  bucket_sort_global_tile(true, BUCKET_SORT_ARGS, all_buckets, lo, scale, bitmap, prefix, used,
                          totals);
}
