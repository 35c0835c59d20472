/* cells_order_masks.cl: the pixel masks of the cells order (engine/cells/cell_order.cpp) on the
 * device. Two cells need an order only if they share a pixel centre; the order marks each
 * cell's centres per 8x8 screen tile (strata_shared.h: st_cover_setup, st_cover_inside, the
 * same float steps the host takes, so the bits are the host's). The host sends the cells whose
 * triangles all take the float setup (a cell spanning at most ST_COVER_FLOAT_SPAN pixels: almost
 * every cell of a fine mesh) with each one's pixel rectangle; every tile of a rectangle is one
 * entry, and one work-item computes one entry's mask from its cell's triangles. */

__kernel void cells_order_masks(__global const float2* screen, const uint first_vertex,
                                __global const uint* cell_vertex_first,
                                __global const uint* cell_vertex_index,
                                __global const uint* cell_first,
                                __global const ushort* cell_corners,
                                __global const uint* node_cell, __global const int4* node_rect,
                                __global const uint* entry_first, const uint nodes,
                                const int width, const int height, __global ulong* masks) {
  const uint k = (uint)get_global_id(0);
  if (nodes == 0 || k >= entry_first[nodes]) return;
  /* The node whose entries hold k: the last n with entry_first[n] <= k. */
  uint lo = 0, hi = nodes;
  while (hi - lo > 1) {
    const uint mid = lo + (hi - lo) / 2;
    if (entry_first[mid] <= k) lo = mid;
    else hi = mid;
  }
  const int4 r = node_rect[lo]; /* pixels x0, y0, x1, y1 */
  const uint tiles_w = (uint)((r.z >> ST_TILE_LOG2) - (r.x >> ST_TILE_LOG2) + 1);
  const uint i = k - entry_first[lo];
  const uint row = i / tiles_w; /* the remainder from it (a division and a remainder of the
                                  * same operands become a "freeze" Oclgrind cannot check) */
  const int tx = (r.x >> ST_TILE_LOG2) + (int)(i - row * tiles_w);
  const int ty = (r.y >> ST_TILE_LOG2) + (int)row;
  const int xa = max(r.x, tx * ST_TILE_SIZE), xb = min(r.z, tx * ST_TILE_SIZE + ST_TILE_SIZE - 1);
  const int ya = max(r.y, ty * ST_TILE_SIZE), yb = min(r.w, ty * ST_TILE_SIZE + ST_TILE_SIZE - 1);
  const uint c = node_cell[lo];
  const uint corner0 = cell_vertex_first[c];
  ulong mask = 0;
  for (uint t = cell_first[c]; t < cell_first[c + 1]; ++t) {
    float2 p[3];
    for (int j = 0; j < 3; ++j)
      p[j] = screen[cell_vertex_index[corner0 + cell_corners[3 * t + j]] - first_vertex];
    StCoverEdges e;
    const int kind = st_cover_setup(p[0].x, p[0].y, p[1].x, p[1].y, p[2].x, p[2].y, width,
                                    height, &e);
    if (kind == ST_COVER_EMPTY) continue;
    const int x0 = max(xa, e.x0), x1 = min(xb, e.x1), y0 = max(ya, e.y0), y1 = min(yb, e.y1);
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        /* A wide triangle is never sent (the host keeps cells that span more than float's
         * reach); were one here, its whole bounds would be the safe side. */
        if (kind == ST_COVER_WIDE ||
            st_cover_inside(&e, (float)(x - e.x0), (float)(y - e.y0)))
          mask |= 1ul << ((y - ty * ST_TILE_SIZE) * ST_TILE_SIZE + (x - tx * ST_TILE_SIZE));
  }
  masks[k] = mask;
}
