/* tile_walk.cl: the tile walk the raster stages share. One work-group owns one ST_TILE_SIZE^2
 * tile and walks its bin list; pixel centres are tested against integer edge functions (top-left
 * rule folded into the setup). */

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

/* A work-item's walk over the fragments of its work-group's tile. The work-group walks the bin
 * list range, one triangle per work-item at a time (stride ST_TILE_PIXELS), so the cost is
 * proportional to fragments plus tile-triangle pairs rather than pairs times tile pixels (real
 * meshes at these sizes have triangles of a few pixels); each work-item visits its triangle's
 * covered pixels inside the tile row by row:
 *   StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
 *   while (st_tile_triangle_next(&f)) {
 *     ... per triangle: f.r, f.record ...
 *     while (st_tile_fragment_next(&f)) {
 *       ... per fragment: f.x, f.y, f.p, f.depth ...
 *     }
 *   }
 * Kernels follow the walk with barriers: never `return` from inside it.
 * Two loops rather than one `while (next fragment)`: that single loop re-enters the pixel loop
 * at every fragment and ran 10-20% more instructions on PoCL. The walk functions are
 * always_inline: PoCL otherwise keeps one out of line with the walk state in memory. */
typedef struct {
  /* The current fragment. */
  __global const StTriSetup* r; /* its triangle's setup record */
  uint record;                  /* that record's index (the bin entry) */
  int x, y;                     /* the pixel, in image coordinates */
  uint p;                       /* the pixel's index inside the tile */
  float depth;                  /* the view distance at the pixel centre (st_covers) */
  /* Walk state. */
  __global const StTriSetup* records;
  __global const uint* bin_entries;
  uint next, end;  /* bin entry of the next triangle; end of the range */
  int tx, ty;      /* the tile's top-left pixel */
  int x0, x1, y1;  /* the current triangle's pixel span, clipped to the tile */
} StTileWalk;

/* A walk over bin entries [begin, end) of the tile whose top-left pixel is (tx, ty). */
inline __attribute__((always_inline)) StTileWalk st_tile_walk(
    __global const StTriSetup* records, __global const uint* bin_entries, uint begin, uint end,
    int tx, int ty) {
  StTileWalk w;
  w.records = records;
  w.bin_entries = bin_entries;
  w.next = begin + st_local_index();
  w.end = end;
  w.tx = tx;
  w.ty = ty;
  w.r = 0;
  w.record = 0;
  w.x = w.x0 = w.x1 = 0; /* no current triangle: its span is done */
  w.y = w.y1 = 0;
  w.p = 0;
  w.depth = 0.0f;
  return w;
}

/* Moves to this work-item's next triangle (w->r, w->record; no pixel yet); false when none is
 * left. */
inline __attribute__((always_inline)) bool st_tile_triangle_next(StTileWalk* w) {
  if (w->next >= w->end) return false;
  w->record = w->bin_entries[w->next];
  w->next += ST_TILE_PIXELS;
  __global const StTriSetup* r = &w->records[w->record];
  w->r = r;
  const int x0 = max(r->min_x, w->tx), x1 = min(r->max_x, w->tx + ST_TILE_SIZE - 1);
  const int y0 = max(r->min_y, w->ty), y1 = min(r->max_y, w->ty + ST_TILE_SIZE - 1);
  if (x0 > x1 || y0 > y1) { /* nothing inside the tile: the span is done */
    w->x = w->x1 = w->y = w->y1 = 0;
    return true;
  }
  w->x0 = x0;
  w->x1 = x1;
  w->y1 = y1;
  w->x = x0 - 1; /* the first step lands on (x0, y0) */
  w->y = y0;
  return true;
}

/* Moves to the current triangle's next covered pixel (w->x, w->y, w->p, w->depth); false when
 * its span is done. */
inline __attribute__((always_inline)) bool st_tile_fragment_next(StTileWalk* w) {
  for (;;) {
    while (w->x < w->x1) {
      ++w->x;
      if (st_covers(w->r, w->x, w->y, &w->depth)) {
        w->p = (uint)((w->y - w->ty) * ST_TILE_SIZE + (w->x - w->tx));
        return true;
      }
    }
    if (w->y >= w->y1) return false;
    ++w->y;
    w->x = w->x0 - 1;
  }
}
