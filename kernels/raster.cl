/* raster.cl: tile-owned rasterization. One work-group owns one ST_TILE_SIZE^2 tile, one
 * work-item one pixel; each walks its tile's bin list and tests its pixel centre against the
 * integer edge functions (top-left rule folded into the setup). No pixel is shared between
 * work-items, so fragments are resolved without per-fragment global atomics (DESIGN.md). */

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

/* Opaque method: nearest fragment per pixel into a 64-bit visibility buffer (atom_min, so
 * several raster launches over the same buffer combine correctly). */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void raster_visibility(__global const StTriSetup* records, __global const uint* bin_entries,
                       __global const uint* tile_offsets, const uint tiles_x,
                       const uint bin_capacity, const int width, const int height,
                       __global ulong* visibility, __global ulong* counters) {
  __local uint scratch[ST_TILE_PIXELS];
  const int x = get_global_id(0), y = get_global_id(1);
  const bool inside = x < width && y < height;
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  ulong best = ST_VISIBILITY_EMPTY;
  uint fragments = 0;
  if (inside) {
    for (uint k = begin; k < end; ++k) {
      __global const StTriSetup* r = &records[bin_entries[k]];
      float depth;
      if (st_covers(r, x, y, &depth)) {
        best = min(best, st_visibility_word(depth, r->source));
        ++fragments;
      }
    }
    if (best != ST_VISIBILITY_EMPTY) atom_min(&visibility[y * width + x], best);
  }
  st_report_tile_counts(scratch, counters, fragments, fragments);
}
