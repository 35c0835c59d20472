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

/* Loads this work-item's pixel range (and for bdp2 its occupancy words and their prefix counts)
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
 * Tile totals (fragments, deepest pixel, buckets kept) are gathered with local atomics. */

/* ---- Pass 1: depth bounds. ---- */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_bounds(__global const StTriSetup* records, __global const uint* bin_entries,
                   __global const uint* tile_offsets, const uint tiles_x, const uint bin_capacity,
                   const int width, const int height, __global float2* bounds,
                   __global ulong* counters, __global uint* depth_complexity,
                   const int capture_depth_complexity) {
  __local uint lo[ST_TILE_PIXELS], hi[ST_TILE_PIXELS], count[ST_TILE_PIXELS];
  __local uint tile_fragments, tile_deepest;
  const int x = get_global_id(0), y = get_global_id(1);
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  const bool busy = begin != end; /* the same for the whole work-group */
  const uint lid = st_local_index();
  lo[lid] = 0xFFFFFFFFu;
  hi[lid] = 0u;
  count[lid] = 0u;
  if (lid == 0) tile_fragments = tile_deepest = 0u;
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  uint fragments = 0;
  StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint p = f.p;
      /* Non-negative floats order like their bit patterns. */
      const uint bits = as_uint(fmax(f.depth, 0.0f));
      atomic_min(&lo[p], bits);
      atomic_max(&hi[p], bits);
      atomic_inc(&count[p]);
      ++fragments;
    }
  }
  if (fragments) atomic_add(&tile_fragments, fragments);
  barrier(CLK_LOCAL_MEM_FENCE);
  const uint n = count[lid];
  /* Tiles without triangles are skipped by the later passes: nothing to store. */
  if (busy)
    bounds[bucket_tile_index(tiles_x) * ST_TILE_PIXELS + lid] =
        n ? (float2)(as_float(lo[lid]), as_float(hi[lid])) : (float2)(0.0f, 0.0f);
  if (capture_depth_complexity && x < width && y < height) depth_complexity[y * width + x] = n;
  if (n) atomic_max(&tile_deepest, n);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid == 0) {
    if (tile_fragments) atom_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)tile_fragments);
    if (tile_deepest) atom_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)tile_deepest);
  }
}

/* ---- Pass 2 (bdp2): fine-bin occupancy. ---- */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_histogram(__global const StTriSetup* records, __global const uint* bin_entries,
                      __global const uint* tile_offsets, const uint tiles_x,
                      const uint bin_capacity, __global const float2* bounds,
                      __global uint* bitmaps) {
  __local float lo[ST_TILE_PIXELS], scale[ST_TILE_PIXELS];
  __local uint bits[ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS];
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  const bool busy = begin != end; /* the same for the whole work-group; empty tiles are skipped */
  const uint lid = st_local_index();
  const uint tile = bucket_tile_index(tiles_x);
  if (busy) {
    const float2 range = bounds[tile * ST_TILE_PIXELS + lid];
    lo[lid] = range.x;
    scale[lid] = bucket_scale(range, ST_BUCKET_FINE_BINS);
    for (uint w = 0; w < ST_BUCKET_FINE_WORDS; ++w) bits[w * ST_TILE_PIXELS + lid] = 0u;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint bin = (uint)bucket_uniform_bin(f.depth, lo[f.p], scale[f.p], ST_BUCKET_FINE_BINS);
      const uint i = (bin >> 5) * ST_TILE_PIXELS + f.p, mask = 1u << (bin & 31u);
      atomic_or(&bits[i], mask);
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  if (busy)
    for (uint w = 0; w < ST_BUCKET_FINE_WORDS; ++w)
      bitmaps[(tile * ST_BUCKET_FINE_WORDS + w) * ST_TILE_PIXELS + lid] = bits[w * ST_TILE_PIXELS + lid];
}

/* ---- Pass 3: bucket sort and front-to-back composite. ----
 * Both variants take the per-pixel tables as __local arguments sized by the host: lo and scale
 * (ST_TILE_PIXELS floats each), and for bdp2 bitmap (ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS uints)
 * and prefix (as many uchars); bdp passes them with one element.
 * One body for the tile's buckets in either address space (OpenCL C 1.2 has no generic address
 * space): `buckets` is the tile's ST_BDP_BUCKETS * ST_TILE_PIXELS words, FENCE the fence of the
 * barriers that order them. `used` (ST_TILE_PIXELS) and `totals` (fragments, kept) are the
 * kernel's __local scratch. */
#define BUCKET_DEFINE_SORT(NAME, SPACE, FENCE)                                                    \
inline void NAME(__global const StTriSetup* records, __global const uint* bin_entries,            \
                 uint begin, uint end, uint tile, __global const float2* bounds,                  \
                 __global const uint* bitmaps, int adaptive,                                      \
                 __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,  \
                 __global const uint* atlas, __constant StViewConstants* view,                    \
                 __global uchar4* image, __global ulong* counters, SPACE ulong* buckets,          \
                 __local float* lo, __local float* scale, __local uint* bitmap,                   \
                 __local uchar* prefix, __local uint* used, __local uint* totals) {               \
  const bool busy = begin != end; /* the same for the whole work-group */                         \
  const uint lid = st_local_index();                                                              \
  if (busy) { /* tiles without triangles only write the background */                             \
    for (uint b = 0; b < ST_BDP_BUCKETS; ++b)                                                     \
      buckets[b * ST_TILE_PIXELS + lid] = ST_VISIBILITY_EMPTY;                                    \
    bucket_load_pixel(bounds, bitmaps, adaptive, tile, lid, lo, scale, bitmap, prefix);           \
  }                                                                                               \
  used[lid] = 0u;                                                                                 \
  if (lid == 0) totals[0] = totals[1] = 0u;                                                       \
  barrier(FENCE);                                                                                 \
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;   \
  uint fragments = 0;                                                                             \
  StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);                          \
  while (st_tile_triangle_next(&f)) {                                                             \
    while (st_tile_fragment_next(&f)) {                                                           \
      ++fragments;                                                                                \
      const uint p = f.p;                                                                         \
      const int slot = bucket_slot(lo, scale, bitmap, prefix, adaptive, p, f.depth);              \
      if (slot == ST_BUCKET_NO_SLOT) continue;                                                    \
      const ulong word = st_visibility_word(f.depth, f.r->source);                                \
      SPACE ulong* bucket = &buckets[(uint)slot * ST_TILE_PIXELS + p];                            \
      atom_min(bucket, word);                                                                     \
      atomic_or(&used[p], 1u << (uint)slot);                                                      \
    }                                                                                             \
  }                                                                                               \
  if (fragments) atomic_add(&totals[0], fragments);                                               \
  barrier(FENCE);                                                                                 \
  float3 color = (float3)(0.0f);                                                                  \
  float transmittance = 1.0f;                                                                     \
  uint mask = used[lid];                                                                          \
  const uint kept = popcount(mask);                                                               \
  const int x = get_global_id(0), y = get_global_id(1);                                           \
  for (; mask; mask &= mask - 1u) {                                                               \
    const ulong word = buckets[bucket_lowest_bit(mask) * ST_TILE_PIXELS + lid];                   \
    const float4 c =                                                                              \
        st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)word, x, y);             \
    st_composite_under(&color, &transmittance, c);                                                \
  }                                                                                               \
  if (x < view->width && y < view->height) {                                                      \
    color += transmittance * st_background(view, x, y);                                           \
    image[y * view->width + x] = st_pack_rgba8(color);                                            \
  }                                                                                               \
  if (kept) atomic_add(&totals[1], kept);                                                         \
  barrier(CLK_LOCAL_MEM_FENCE);                                                                   \
  /* Fragments scattered minus buckets occupied: the ones that collided or found no bucket. */    \
  if (lid == 0 && totals[0] > totals[1])                                                          \
    atom_add(&counters[ST_COUNTER_FRAGMENTS_LOST], (ulong)(totals[0] - totals[1]));               \
}

BUCKET_DEFINE_SORT(bucket_sort_tile_local, __local, CLK_LOCAL_MEM_FENCE)
BUCKET_DEFINE_SORT(bucket_sort_tile_global, __global, CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE)

/* Buckets in local memory: `buckets` holds the tile's. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_sort_local(__global const StTriSetup* records, __global const uint* bin_entries,
                       __global const uint* tile_offsets, const uint tiles_x,
                       const uint bin_capacity, __global const float2* bounds,
                       __global const uint* bitmaps, const int adaptive,
                       __global const float4* triangle_colors,
                       __global const StTexTriangle* tex_tris, __global const uint* atlas,
                       __constant StViewConstants* view, __global uchar4* image,
                       __global ulong* counters,
                       __local ulong* buckets, __local float* lo, __local float* scale,
                       __local uint* bitmap, __local uchar* prefix) {
  __local uint used[ST_TILE_PIXELS];
  __local uint totals[2];
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  bucket_sort_tile_local(records, bin_entries, begin, end, bucket_tile_index(tiles_x), bounds,
                         bitmaps, adaptive, triangle_colors, tex_tris, atlas, view, image,
                         counters, buckets, lo, scale, bitmap, prefix, used, totals);
}

/* Buckets in global memory: `all_buckets` holds every tile's, tile-major. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void bucket_sort_global(__global const StTriSetup* records, __global const uint* bin_entries,
                        __global const uint* tile_offsets, const uint tiles_x,
                        const uint bin_capacity, __global const float2* bounds,
                        __global const uint* bitmaps, const int adaptive,
                        __global const float4* triangle_colors,
                        __global const StTexTriangle* tex_tris, __global const uint* atlas,
                        __constant StViewConstants* view, __global uchar4* image,
                        __global ulong* counters,
                        __global ulong* all_buckets, __local float* lo, __local float* scale,
                        __local uint* bitmap, __local uchar* prefix) {
  __local uint used[ST_TILE_PIXELS];
  __local uint totals[2];
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  const uint tile = bucket_tile_index(tiles_x);
  bucket_sort_tile_global(records, bin_entries, begin, end, tile, bounds, bitmaps, adaptive,
                          triangle_colors, tex_tris, atlas, view, image, counters,
                          all_buckets + (size_t)tile * (ST_BDP_BUCKETS * ST_TILE_PIXELS), lo,
                          scale, bitmap, prefix, used, totals);
}

/* ---- The serial forms, for a CPU device: one work-item owns the tile, a work-group of its own
 * (bucket_tile_index is then its tile, and the tile's __local tables are its alone), walking the
 * tile's triangles in drawing order without barriers or local atomics. A bucket keeps the
 * minimum word whatever the order of arrival, so the bounds, histograms, buckets and losses are
 * those of the work-group forms. ---- */

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_bounds_serial(__global const StTriSetup* records, __global const uint* bin_entries,
                          __global const uint* tile_offsets, const uint tiles_x,
                          const uint bin_capacity, const int width, const int height,
                          __global float2* bounds, __global ulong* counters,
                          __global uint* depth_complexity, const int capture_depth_complexity) {
  uint lo[ST_TILE_PIXELS], hi[ST_TILE_PIXELS], count[ST_TILE_PIXELS];
  const uint tile = bucket_tile_index(tiles_x);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    lo[p] = 0xFFFFFFFFu;
    hi[p] = 0u;
    count[p] = 0u;
  }
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  uint fragments = 0;
  StTileWalk f = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint bits = as_uint(fmax(f.depth, 0.0f)); /* orders like the non-negative float */
      lo[f.p] = min(lo[f.p], bits);
      hi[f.p] = max(hi[f.p], bits);
      ++count[f.p];
      ++fragments;
    }
  }
  uint deepest = 0;
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    const uint n = count[p];
    /* Tiles without triangles are skipped by the later passes: nothing to store. */
    if (begin != end)
      bounds[tile * ST_TILE_PIXELS + p] =
          n ? (float2)(as_float(lo[p]), as_float(hi[p])) : (float2)(0.0f, 0.0f);
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (capture_depth_complexity && x < width && y < height) depth_complexity[y * width + x] = n;
    deepest = max(deepest, n);
  }
  st_report_counts_alone(counters, fragments, deepest);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_histogram_serial(__global const StTriSetup* records, __global const uint* bin_entries,
                             __global const uint* tile_offsets, const uint tiles_x,
                             const uint bin_capacity, __global const float2* bounds,
                             __global uint* bitmaps) {
  __local uint bits[ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS];
  float lo[ST_TILE_PIXELS], scale[ST_TILE_PIXELS];
  const uint tile = bucket_tile_index(tiles_x);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  if (begin == end) return; /* empty tiles are skipped */
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    const float2 range = bounds[tile * ST_TILE_PIXELS + p];
    lo[p] = range.x;
    scale[p] = bucket_scale(range, ST_BUCKET_FINE_BINS);
  }
  for (uint i = 0; i < ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS; ++i) bits[i] = 0u;
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  StTileWalk f = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint bin = (uint)bucket_uniform_bin(f.depth, lo[f.p], scale[f.p], ST_BUCKET_FINE_BINS);
      bits[(bin >> 5) * ST_TILE_PIXELS + f.p] |= 1u << (bin & 31u);
    }
  }
  for (uint i = 0; i < ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS; ++i)
    bitmaps[tile * ST_BUCKET_FINE_WORDS * ST_TILE_PIXELS + i] = bits[i];
}

/* Pass 3, serial: one body for the tile's buckets in either address space, as above. */
#define BUCKET_DEFINE_SORT_SERIAL(NAME, SPACE)                                                    \
inline void NAME(__global const StTriSetup* records, __global const uint* bin_entries,            \
                 uint begin, uint end, uint tile, __global const float2* bounds,                  \
                 __global const uint* bitmaps, int adaptive,                                      \
                 __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,  \
                 __global const uint* atlas, __constant StViewConstants* view,                    \
                 __global uchar4* image, __global ulong* counters, SPACE ulong* buckets,          \
                 __local float* lo, __local float* scale, __local uint* bitmap,                   \
                 __local uchar* prefix) {                                                         \
  uint used[ST_TILE_PIXELS];                                                                      \
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {                                                     \
    used[p] = 0u;                                                                                 \
    if (begin == end) continue; /* tiles without triangles only write the background */          \
    for (uint b = 0; b < ST_BDP_BUCKETS; ++b) buckets[b * ST_TILE_PIXELS + p] = ST_VISIBILITY_EMPTY; \
    bucket_load_pixel(bounds, bitmaps, adaptive, tile, p, lo, scale, bitmap, prefix);             \
  }                                                                                               \
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;   \
  uint fragments = 0;                                                                             \
  StTileWalk f = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);                    \
  while (st_tile_triangle_next(&f)) {                                                             \
    while (st_tile_fragment_next(&f)) {                                                           \
      ++fragments;                                                                                \
      const uint p = f.p;                                                                         \
      const int slot = bucket_slot(lo, scale, bitmap, prefix, adaptive, p, f.depth);              \
      if (slot == ST_BUCKET_NO_SLOT) continue;                                                    \
      const ulong word = st_visibility_word(f.depth, f.r->source);                                \
      SPACE ulong* bucket = &buckets[(uint)slot * ST_TILE_PIXELS + p];                            \
      *bucket = min(*bucket, word);                                                               \
      used[p] |= 1u << (uint)slot;                                                                \
    }                                                                                             \
  }                                                                                               \
  uint kept = 0;                                                                                  \
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {                                                     \
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);          \
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
    color += transmittance * st_background(view, x, y);                                           \
    image[y * view->width + x] = st_pack_rgba8(color);                                            \
  }                                                                                               \
  /* Fragments scattered minus buckets occupied: the ones that collided or found no bucket. */    \
  if (fragments > kept) atom_add(&counters[ST_COUNTER_FRAGMENTS_LOST], (ulong)(fragments - kept)); \
}

BUCKET_DEFINE_SORT_SERIAL(bucket_sort_tile_local_serial, __local)
BUCKET_DEFINE_SORT_SERIAL(bucket_sort_tile_global_serial, __global)

/* bucket_sort_local, serial form (same arguments). */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_sort_local_serial(__global const StTriSetup* records, __global const uint* bin_entries,
                              __global const uint* tile_offsets, const uint tiles_x,
                              const uint bin_capacity, __global const float2* bounds,
                              __global const uint* bitmaps, const int adaptive,
                              __global const float4* triangle_colors,
                              __global const StTexTriangle* tex_tris, __global const uint* atlas,
                              __constant StViewConstants* view, __global uchar4* image,
                              __global ulong* counters, __local ulong* buckets,
                              __local float* lo, __local float* scale, __local uint* bitmap,
                              __local uchar* prefix) {
  uint begin, end;
  const uint tile = bucket_tile_index(tiles_x);
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  bucket_sort_tile_local_serial(records, bin_entries, begin, end, tile, bounds, bitmaps, adaptive,
                                triangle_colors, tex_tris, atlas, view, image, counters, buckets,
                                lo, scale, bitmap, prefix);
}

/* bucket_sort_global, serial form (same arguments). */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bucket_sort_global_serial(__global const StTriSetup* records,
                               __global const uint* bin_entries,
                               __global const uint* tile_offsets, const uint tiles_x,
                               const uint bin_capacity, __global const float2* bounds,
                               __global const uint* bitmaps, const int adaptive,
                               __global const float4* triangle_colors,
                               __global const StTexTriangle* tex_tris, __global const uint* atlas,
                               __constant StViewConstants* view, __global uchar4* image,
                               __global ulong* counters, __global ulong* all_buckets,
                               __local float* lo, __local float* scale, __local uint* bitmap,
                               __local uchar* prefix) {
  uint begin, end;
  const uint tile = bucket_tile_index(tiles_x);
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  bucket_sort_tile_global_serial(records, bin_entries, begin, end, tile, bounds, bitmaps,
                                 adaptive, triangle_colors, tex_tris, atlas, view, image,
                                 counters,
                                 all_buckets + (size_t)tile * (ST_BDP_BUCKETS * ST_TILE_PIXELS),
                                 lo, scale, bitmap, prefix);
}
