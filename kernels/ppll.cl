/* ppll.cl: exact transparency with per-pixel linked lists (Yang et al. 2010): fragments take
 * nodes from one global pool and are pushed on their pixel's list by an atomic head exchange; the
 * resolve sorts each list by (depth, triangle id) and composites front to back.
 * Tile ownership (DESIGN.md) keeps the atomics off shared cache lines: a work-group counts its
 * tile's fragments, reserves that many nodes with one global atomic, then pushes them on list
 * heads held in local memory and stores the heads once. When the pool overflows the requested
 * count keeps rising, so the host re-runs the frame with the pool grown to it. */

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void ppll_build(__global const StTriSetup* records, __global const uint* bin_entries,
                __global const uint* tile_offsets, const uint tiles_x, const uint bin_capacity,
                const int width, const int height, __global uint* heads,
                __global StPpllNode* nodes, const ulong node_capacity,
                __global ulong* counters) {
  __local uint scratch[ST_TILE_PIXELS];
  __local uint tile_heads[ST_TILE_PIXELS];
  __local uint tile_used;
  __local ulong tile_base;
  const uint lid = st_local_index();
  tile_heads[lid] = ST_PPLL_END;
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;

  /* Pass 1: count the tile's fragments (the coverage masks suffice). */
  uint fragments = 0;
  StTileWalk count = st_tile_walk(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&count)) fragments += (uint)popcount(count.covered);
  const uint total = st_group_sum(scratch, fragments);
  if (lid == 0) {
    tile_used = 0;
    tile_base = total ? st_counter_claim(&counters[ST_COUNTER_NODES], (ulong)total) : 0;
    if (total) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)total);
  }
  barrier(CLK_LOCAL_MEM_FENCE);

  /* Pass 2: push the fragments on the tile's lists. */
  if (total && tile_base + total <= node_capacity) {
    StTileWalk f = st_tile_walk(records, bin_entries, begin, end, tx, ty);
    while (st_tile_triangle_next(&f)) {
      while (st_tile_fragment_next(&f)) {
        const uint node = (uint)tile_base + atomic_inc(&tile_used);
        StPpllNode n;
        n.depth = f.depth;
        n.source = f.r->source;
        n.next = atomic_xchg(&tile_heads[f.p], node);
        nodes[node] = n;
      }
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int x = get_global_id(0), y = get_global_id(1);
  if (x < width && y < height) heads[y * width + x] = tile_heads[lid];
}

/* (depth, id) order: nearer first, ties by the lower triangle id. */
inline bool st_fragment_before(float da, uint sa, float db, uint sb) {
  return da < db || (da == db && sa < sb);
}

/* Fragment (d, s) inserted into the sorted depth[0..j+1), source[0..j+1): the entries from j
 * down that it goes before move one place back (a capped insertion passes j = capacity - 2 to
 * drop the farthest). */
inline void ppll_insert(float* depth, uint* source, int j, float d, uint s) {
  while (j >= 0 && st_fragment_before(d, s, depth[j], source[j])) {
    depth[j + 1] = depth[j];
    source[j + 1] = source[j];
    --j;
  }
  depth[j + 1] = d;
  source[j + 1] = s;
}

/* Resolves pixel (x, y), inside the image: sorts its list, composites it front to back over the
 * background into the image. Returns the list's length. */
inline uint st_ppll_resolve_pixel(__global const uint* heads, __global const StPpllNode* nodes,
                                  __global const float4* triangle_colors,
                                  __global const StTexTriangle* tex_tris,
                                  __global const uint* atlas, __constant StViewConstants* view,
                                  __global uchar4* image, __global uint* depth_complexity,
                                  const int capture_depth_complexity, int x, int y) {
  const int width = view->width;
  uint count = 0;
  {
    const uint head = heads[y * width + x];
    float depth[ST_PPLL_SORT_CAPACITY];
    uint source[ST_PPLL_SORT_CAPACITY];
    for (uint n = head; n != ST_PPLL_END; n = nodes[n].next) {
      if (count < ST_PPLL_SORT_CAPACITY) {
        /* insertion sort while gathering */
        const float d = nodes[n].depth;
        const uint s = nodes[n].source;
        ppll_insert(depth, source, (int)count - 1, d, s);
      }
      ++count;
    }
    float3 color = (float3)(0.0f);
    float transmittance = 1.0f;
    if (count <= ST_PPLL_SORT_CAPACITY) {
      for (uint i = 0; i < count; ++i)
        st_composite_under(&color, &transmittance, st_fragment_colour(triangle_colors, tex_tris, atlas, view, source[i], x, y));
    } else {
      /* Deeper than the private array: the list is walked once per ST_PPLL_SORT_CAPACITY
       * fragments, each walk keeping the nearest ones behind the last composited (a capped
       * sorted insertion), so a pixel of n fragments costs n^2 / capacity, not n^2. A pixel that
       * lets less than ST_OPAQUE_TRANSMITTANCE through stops: the rest would change it by less
       * than half an 8-bit step. */
      float last_d = -INFINITY;
      uint last_s = 0;
      bool first = true;
      uint done = 0;
      while (done < count && transmittance >= ST_OPAQUE_TRANSMITTANCE) {
        uint m = 0;
        for (uint n = head; n != ST_PPLL_END; n = nodes[n].next) {
          const float d = nodes[n].depth;
          const uint s = nodes[n].source;
          if (!first && !st_fragment_before(last_d, last_s, d, s)) continue;
          int j;
          if (m < ST_PPLL_SORT_CAPACITY) {
            j = (int)m - 1;
            ++m;
          } else {
            if (!st_fragment_before(d, s, depth[ST_PPLL_SORT_CAPACITY - 1],
                                    source[ST_PPLL_SORT_CAPACITY - 1]))
              continue;
            j = ST_PPLL_SORT_CAPACITY - 2; /* the farthest kept one falls off */
          }
          ppll_insert(depth, source, j, d, s);
        }
        if (m == 0) break;
        for (uint i = 0; i < m; ++i)
          st_composite_under(&color, &transmittance, st_fragment_colour(triangle_colors, tex_tris, atlas, view, source[i], x, y));
        last_d = depth[m - 1];
        last_s = source[m - 1];
        first = false;
        done += m;
      }
    }
    color += transmittance * st_background(view, x, y);
    image[y * width + x] = st_pack_rgba8(color);
    if (capture_depth_complexity) depth_complexity[y * width + x] = count;
  }
  return count;
}

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void ppll_resolve(__global const uint* heads, __global const StPpllNode* nodes,
                  __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,
                  __global const uint* atlas, __constant StViewConstants* view,
                  __global uchar4* image, __global ulong* counters,
                  __global uint* depth_complexity, const int capture_depth_complexity) {
  __local uint scratch[ST_TILE_PIXELS];
  const int x = get_global_id(0), y = get_global_id(1);
  uint count = 0;
  if (x < view->width && y < view->height)
    count = st_ppll_resolve_pixel(heads, nodes, triangle_colors, tex_tris, atlas, view, image,
                                  depth_complexity, capture_depth_complexity, x, y);
  st_report_tile_counts(scratch, counters, 0, count);
}

/* ppll_build for a CPU device: one work-item owns a whole tile, alone (no barriers, no local
 * atomics). Its fragments take nodes in drawing order; the lists hold the same fragments as
 * ppll_build's, in another order, which the resolve's sort removes. A tile of at most
 * ST_PPLL_SERIAL_ONE_WALK bin entries is walked once, reserving nodes in runs of at least
 * ST_PPLL_SERIAL_RUN as it goes (one global atomic per run): ppll 1.25x faster on the horse and
 * the bunny at 1024x1024. A longer list is counted first, so that its nodes form one block: the
 * deep pixels of builtin:spheres:32 resolved 1.25x slower from runs than the counting walk
 * saved. The nodes counter includes the unused tail of a tile's last run, so a pool sized from
 * it always fits. */
#define ST_PPLL_SERIAL_RUN 64u
#define ST_PPLL_SERIAL_ONE_WALK 256u
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void ppll_build_serial(__global const StTriSetup* records, __global const uint* bin_entries,
                       __global const uint* tile_offsets, const uint tiles_x,
                       const uint bin_capacity, const int width, const int height,
                       __global uint* heads, __global StPpllNode* nodes,
                       const ulong node_capacity, __global ulong* counters) {
  uint tile_heads[ST_TILE_PIXELS];
  const uint tile_x = get_global_id(0), tile_y = get_global_id(1);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile_y * tiles_x + tile_x, bin_capacity, &begin, &end);
  const int tx = (int)tile_x * ST_TILE_SIZE, ty = (int)tile_y * ST_TILE_SIZE;
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) tile_heads[p] = ST_PPLL_END;

  uint total = 0;
  ulong node = 0, run_end = 0; /* the current run of reserved nodes: [node, run_end) */
  if (end - begin > ST_PPLL_SERIAL_ONE_WALK) {
    uint counted = 0;
    StTileWalk count = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);
    while (st_tile_triangle_next(&count)) counted += (uint)popcount(count.covered);
    if (counted) {
      node = st_counter_claim(&counters[ST_COUNTER_NODES], (ulong)counted);
      run_end = node + counted;
    }
  }
  StTileWalk f = st_tile_walk_alone(records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    const uint covered = (uint)popcount(f.covered);
    if (covered == 0) continue;
    total += covered;
    if (run_end - node < covered) {
      const ulong run = max((ulong)covered, (ulong)ST_PPLL_SERIAL_RUN);
      node = st_counter_claim(&counters[ST_COUNTER_NODES], run);
      run_end = node + run;
    }
    if (run_end > node_capacity) { /* past the pool: the host grows it and runs the frame again */
      node += covered;
      continue;
    }
    while (st_tile_fragment_next(&f)) {
      StPpllNode n;
      n.depth = f.depth;
      n.source = f.r->source;
      n.next = tile_heads[f.p];
      tile_heads[f.p] = (uint)node;
      nodes[node++] = n;
    }
  }
  if (total) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)total);
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (x < width && y < height) heads[y * width + x] = tile_heads[p];
  }
}

/* ppll_resolve for a CPU device: one work-item resolves a whole tile's pixels. */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void ppll_resolve_serial(__global const uint* heads, __global const StPpllNode* nodes,
                         __global const float4* triangle_colors,
                         __global const StTexTriangle* tex_tris, __global const uint* atlas,
                         __constant StViewConstants* view, __global uchar4* image,
                         __global ulong* counters, __global uint* depth_complexity,
                         const int capture_depth_complexity) {
  const int tx = (int)get_global_id(0) * ST_TILE_SIZE, ty = (int)get_global_id(1) * ST_TILE_SIZE;
  uint deepest = 0;
  for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    if (x < view->width && y < view->height)
      deepest = max(deepest, st_ppll_resolve_pixel(heads, nodes, triangle_colors, tex_tris, atlas,
                                                   view, image, depth_complexity,
                                                   capture_depth_complexity, x, y));
  }
  if (deepest) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)deepest);
}
