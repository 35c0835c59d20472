/* raster.cl: tile-owned rasterization. One work-group owns one ST_TILE_SIZE^2 tile and walks its
 * bin list; pixel centres are tested against integer edge functions (top-left rule folded into
 * the setup). A tile's per-pixel state stays in local memory, so the opaque method needs no
 * per-fragment global atomics (DESIGN.md: tile ownership). */

/* Bin list range [begin, end) of the tile owned by this work-group. */
inline void st_tile_range(__global const uint* tile_offsets, uint tiles_x, uint bin_capacity,
                          uint* begin, uint* end) {
  const uint tile = get_group_id(1) * tiles_x + get_group_id(0);
  *begin = min(tile_offsets[tile], bin_capacity);
  *end = min(tile_offsets[tile + 1], bin_capacity);
}

/* Whether setup record r covers the centre of pixel (x, y); if so, its view distance. */
inline bool st_covers(__global const StTriSetup* r, int x, int y, float* depth) {
  if (x < r->min_x || x > r->max_x || y < r->min_y || y > r->max_y) return false;
  const long px = (long)x * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2;
  const long py = (long)y * ST_SUBPIXEL_ONE + ST_SUBPIXEL_ONE / 2;
  for (int e = 0; e < 3; ++e)
    if ((long)r->edge_a[e] * px + (long)r->edge_b[e] * py + r->edge_c[e] < 0) return false;
  const float dx = ((float)x + 0.5f) - r->origin_x, dy = ((float)y + 0.5f) - r->origin_y;
  const float dw = r->dw0 + r->dw_dx * dx + r->dw_dy * dy;
  const float iw = r->iw0 + r->iw_dx * dx + r->iw_dy * dy;
  *depth = dw / iw;
  return true;
}

/* Visibility word: view distance (a positive float, so its bits order like the value) above the
 * source triangle id; the smallest word is the nearest fragment, ties broken by the lower id. */
inline ulong st_visibility_word(float depth, uint source) {
  return ((ulong)as_uint(fmax(depth, 0.0f)) << 32) | (ulong)source;
}

/* The tile walk shared by every raster kernel: the work-group walks its tile's bin list
 * [begin, end), one triangle per work-item at a time (stride ST_TILE_PIXELS), so the cost is
 * proportional to fragments plus tile-triangle pairs rather than pairs times tile pixels (real
 * meshes at these sizes have triangles of a few pixels). Each work-item loops over its triangle's
 * pixels clipped to the tile (top-left pixel (tx, ty)) and runs the statement that follows the
 * macro once per covered pixel, with these names declared (the caller chooses them):
 *   r      __global const StTriSetup*  the triangle's setup record
 *   x, y   int                         the pixel, in image coordinates
 *   p      uint                        the pixel's index inside the tile
 *   depth  float                       the view distance at the pixel centre (st_covers)
 * Usage: ST_FOR_EACH_TILE_FRAGMENT(records, bin_entries, begin, end, tx, ty, r, x, y, p, depth) {
 *          ...
 *        }
 * It expands to nested for statements (single-pass ones declare r, depth and p), so no lambda is
 * needed. `continue` in the body ends this fragment and goes on to the next one. Do not use
 * `break` in the body: it would only leave an inner helper loop (acting like `continue`), not
 * the walk. Do not `return` from the body either: the walk is followed by barriers. */
#define ST_FOR_EACH_TILE_FRAGMENT(records, bin_entries, begin, end, tx, ty, r, x, y, p, depth)  \
  for (uint st_walk_k_ = (begin) + st_local_index(); st_walk_k_ < (end);                      \
       st_walk_k_ += ST_TILE_PIXELS)                                                          \
    for (__global const StTriSetup* r = &(records)[(bin_entries)[st_walk_k_]]; r; r = 0)      \
      for (int st_walk_x0_ = max(r->min_x, (tx)), y = max(r->min_y, (ty)),                    \
               st_walk_x1_ = min(r->max_x, (tx) + ST_TILE_SIZE - 1),                          \
               st_walk_y1_ = min(r->max_y, (ty) + ST_TILE_SIZE - 1);                          \
           y <= st_walk_y1_; ++y)                                                             \
        for (int x = st_walk_x0_; x <= st_walk_x1_; ++x)                                      \
          for (float depth, st_walk_hit_ = st_covers(r, x, y, &depth) ? 1.0f : 0.0f;         \
               st_walk_hit_ != 0.0f; st_walk_hit_ = 0.0f)                                     \
            for (uint p = (uint)((y - (ty)) * ST_TILE_SIZE + (x - (tx))), st_walk_once_ = 1u; \
                 st_walk_once_; st_walk_once_ = 0u)

/* Opaque method: nearest fragment per pixel. The tile's words live in local memory (64-bit
 * atom_min: depth above triangle id), then go to the global visibility buffer with one atom_min
 * per pixel, so several raster launches over one buffer combine correctly. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void raster_visibility(__global const StTriSetup* records, __global const uint* bin_entries,
                       __global const uint* tile_offsets, const uint tiles_x,
                       const uint bin_capacity, const int width, const int height,
                       __global ulong* visibility, __global ulong* counters,
                       __global uint* depth_complexity, const int capture_depth_complexity) {
  __local ulong best[ST_TILE_PIXELS];
  __local uint depth_count[ST_TILE_PIXELS];
  __local uint scratch[ST_TILE_PIXELS];
  const uint lid = st_local_index();
  best[lid] = ST_VISIBILITY_EMPTY;
  depth_count[lid] = 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  uint fragments = 0;
  ST_FOR_EACH_TILE_FRAGMENT(records, bin_entries, begin, end, tx, ty, r, x, y, p, depth) {
    const ulong word = st_visibility_word(depth, r->source);
    if (word < best[p]) atom_min(&best[p], word); /* most fragments lose: test first */
    atomic_inc(&depth_count[p]);
    ++fragments;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int x = get_global_id(0), y = get_global_id(1);
  if (x < width && y < height) {
    if (best[lid] != ST_VISIBILITY_EMPTY) atom_min(&visibility[y * width + x], best[lid]);
    if (capture_depth_complexity) depth_complexity[y * width + x] = depth_count[lid];
  }
  st_report_tile_counts(scratch, counters, fragments, depth_count[lid]);
}
