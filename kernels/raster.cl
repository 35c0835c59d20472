/* raster.cl: tile-owned rasterization of the opaque method (the walk: tile_walk.cl). A tile's
 * per-pixel state stays in local memory, so the opaque method needs no per-fragment global
 * atomics (DESIGN.md: tile ownership). */

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
  StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const ulong word = st_visibility_word(f.depth, f.r->source);
      ST_ATOM64_MIN(&best[f.p], word);
      atomic_inc(&depth_count[f.p]);
      ++fragments;
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int x = get_global_id(0), y = get_global_id(1);
  if (x < width && y < height) {
    if (best[lid] != ST_VISIBILITY_EMPTY) ST_ATOM64_MIN(&visibility[y * width + x], best[lid]);
    if (capture_depth_complexity) depth_complexity[y * width + x] = depth_count[lid];
  }
  st_report_tile_counts(scratch, counters, fragments, depth_count[lid]);
}

/* raster_visibility for a CPU device: one work-item owns a whole tile, alone (no work-group, no
 * barriers, no local atomics; PoCL runs a group's items one after another, every barrier region
 * as a loop over them). Fragments meet the tile's pixels in drawing order; the nearest word is
 * the same in any order, so the visibility buffer is the same as raster_visibility's. No other
 * work-item of the launch writes the tile's pixels, and the launches over one buffer run one
 * after another on the queue, so each pixel's word is combined with a plain load and store (a
 * locked compare-exchange per pixel was a seventh of this kernel's time on the horse). */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void raster_visibility_serial(__global const StTriSetup* records, __global const uint* bin_entries,
                              __global const uint* tile_offsets, const uint tiles_x,
                              const uint bin_capacity, const int width, const int height,
                              __global ulong* visibility, __global ulong* counters,
                              __global uint* depth_complexity, const int capture_depth_complexity) {
  ulong best[ST_TILE_PIXELS];
  uint depth_count[ST_TILE_PIXELS];
  const uint tile_x = get_global_id(0), tile_y = get_global_id(1);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile_y * tiles_x + tile_x, bin_capacity, &begin, &end);
  if (begin == end && !capture_depth_complexity) return;
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    best[p] = ST_VISIBILITY_EMPTY;
    depth_count[p] = 0;
  }
  const int tx = (int)tile_x * ST_TILE_SIZE, ty = (int)tile_y * ST_TILE_SIZE;
  uint fragments = 0;
  ulong reached = 0; /* pixels with a fragment */
  StTileWalk f = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    reached |= f.covered;
    while (st_tile_fragment_next(&f)) {
      best[f.p] = min(best[f.p], st_visibility_word(f.depth, f.r->source));
      ++depth_count[f.p];
      ++fragments;
    }
  }
  uint deepest = 0;
  for (ulong live = reached; live != 0; live &= live - 1ul) {
    const uint p = (uint)popcount((live & (0ul - live)) - 1ul);
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (x < width && y < height) { /* the tile's own pixel, and launches run in turn */
      __global ulong* word = &visibility[y * width + x];
      *word = min(*word, best[p]);
    }
    deepest = max(deepest, depth_count[p]);
  }
  if (capture_depth_complexity) {
    for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
      const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
      if (x < width && y < height) depth_complexity[y * width + x] = depth_count[p];
    }
  }
  st_report_counts_alone(counters, fragments, deepest);
}
