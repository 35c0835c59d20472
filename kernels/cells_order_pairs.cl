/* cells_order_pairs.cl: the pairs of cells the order must relate, found on the device. Two cells
 * need an order only if their pixel masks (cells_order_masks.cl, or the host's) share a centre in
 * some 8x8 tile. The host lists every cell's masks (entries: tile, node, mask low and high words)
 * node by node, each node's in tile order, and the same entries grouped by tile, each tile's in
 * node order. A work-item per entry meets the later entries of its tile: a pair (w, v), w < v,
 * is reported from the first of w's entries where the two share a centre, with their relation
 * (strata_shared.h: st_order_boxes, st_order_negative_first, the host's own rules), as one
 * word: w, then v | code << 30 (code 1: w first, 2: v first, 3: no order known, 0: none needed). */

/* Whether node v has an entry in tile `tile` sharing a centre with `mask` (its entries are in
 * tile order). */
inline bool st_order_node_meets(__global const uint4* by_node, __global const uint* node_first,
                                uint v, uint tile, ulong mask) {
  for (uint k = node_first[v]; k < node_first[v + 1]; ++k) {
    const uint4 e = by_node[k];
    if (e.x > tile) break;
    if (e.x == tile) return (((ulong)e.w << 32 | e.z) & mask) != 0;
  }
  return false;
}

/* The relation of nodes w and v (cells a and b): +1 w first, -1 v first, 0 none, 2 unknown. */
inline int st_order_relation(uint w, uint v, __global const uint* node_cell,
                             __global const float* node_depth, __global const float* cell_box,
                             __global const uint* neighbour_first,
                             __global const float* neighbours, const float* eye,
                             const float* forward, int perspective) {
  /* View depth ranges (min, max) as floats: float2 loads here crash Oclgrind's checker of
   * uninitialised values. */
  if (node_depth[2 * w + 1] <= node_depth[2 * v]) return 1;
  if (node_depth[2 * v + 1] <= node_depth[2 * w]) return -1;
  const uint a = node_cell[w], b = node_cell[v];
  float alo[3], ahi[3], blo[3], bhi[3];
  for (int k = 0; k < 3; ++k) {
    alo[k] = cell_box[6 * a + k];
    ahi[k] = cell_box[6 * a + 3 + k];
    blo[k] = cell_box[6 * b + k];
    bhi[k] = cell_box[6 * b + 3 + k];
  }
  const int box = st_order_boxes(alo, ahi, blo, bhi, eye, forward, perspective);
  if (box != 0) return box;
  /* a's neighbours, sorted by the other cell: (other, separable, n.x, n.y, n.z, d) each. */
  uint lo = neighbour_first[a], hi = neighbour_first[a + 1];
  while (lo < hi) {
    const uint mid = lo + (hi - lo) / 2;
    if (as_uint(neighbours[6 * mid]) < b) lo = mid + 1;
    else hi = mid;
  }
  if (lo < neighbour_first[a + 1] && as_uint(neighbours[6 * lo]) == b &&
      as_uint(neighbours[6 * lo + 1]) != 0)
    return st_order_negative_first(neighbours[6 * lo + 2], neighbours[6 * lo + 3],
                                   neighbours[6 * lo + 4], neighbours[6 * lo + 5], eye, forward,
                                   perspective);
  return 2;
}

__kernel void cells_order_pairs(__global const uint4* by_node, __global const uint* node_first,
                                __global const uint4* by_tile,
                                __global const uint* tile_position,
                                __global const uint* tile_end, const uint entries,
                                __global const uint* node_cell,
                                __global const float* node_depth, __global const float* cell_box,
                                __global const uint* neighbour_first,
                                __global const float* neighbours,
                                __global const float* view, /* eye, forward: 3 floats each */
                                const int perspective,
                                __global uint* pair_count, const uint capacity,
                                __global ulong* pairs) {
  const uint k = (uint)get_global_id(0);
  if (k >= entries) return;
  const uint4 e = by_node[k];
  const uint w = e.y, tile = e.x;
  const ulong mask = (ulong)e.w << 32 | e.z;
  float eye[3], forward[3];
  for (int i = 0; i < 3; ++i) {
    eye[i] = view[i];
    forward[i] = view[3 + i];
  }
  for (uint j = tile_position[k] + 1; j < tile_end[tile]; ++j) {
    const uint4 o = by_tile[j];
    if ((((ulong)o.w << 32 | o.z) & mask) == 0) continue;
    const uint v = o.y;
    /* Reported once: from w's first entry that meets v. */
    bool earlier = false;
    for (uint p = node_first[w]; p < k && !earlier; ++p) {
      const uint4 f = by_node[p];
      earlier = st_order_node_meets(by_node, node_first, v, f.x, (ulong)f.w << 32 | f.z);
    }
    if (earlier) continue;
    const int r = st_order_relation(w, v, node_cell, node_depth, cell_box, neighbour_first,
                                    neighbours, eye, forward, perspective);
    const uint code = r == 1 ? 1u : r == -1 ? 2u : r == 2 ? 3u : 0u;
    const uint slot = atomic_inc(pair_count);
    /* One 64-bit word (w low, then v and the code): a uint2 built from two values is stored
     * from an undefined vector that Oclgrind reports as uninitialised. */
    if (slot < capacity) pairs[slot] = (ulong)(v | code << 30) << 32 | w;
  }
}
