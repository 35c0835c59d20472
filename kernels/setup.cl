/* setup.cl: triangle setup of a run of draw units: per source triangle its flat shading colour,
 * clipping, setup records and their tile counts (the steps are in geometry.cl). */

/* Stores setup record r into slot `slot`, its packed pixel bounds next to it (the binners read
 * those 8 bytes, not the record), and, when tiles_x is not 0, counts it in every screen tile its
 * bounds touch (the binner's count, done here while the record is in registers; the serial
 * binner counts in its own pass instead, without atomics). */
inline __attribute__((always_inline)) void st_store_record(
    const StTriSetup* r, const uint slot, __global StTriSetup* records, __global uint2* bounds,
    __global uint* tile_counts, const uint tiles_x) {
  st_write_record(&records[slot], r);
  st_store_uint2(bounds, slot, r->bounds_min, r->bounds_max);
  if (tiles_x == 0) return;
  uint tx0, tx1, ty0, ty1;
  st_bounds_tiles((uint2)(r->bounds_min, r->bounds_max), &tx0, &tx1, &ty0, &ty1);
  for (uint ty = ty0; ty <= ty1; ++ty)
    for (uint tx = tx0; tx <= tx1; ++tx) atomic_inc(&tile_counts[ty * tiles_x + tx]);
}

/* Marks record slot `slot` as covering nothing: the binners read only its bounds, so the record
 * itself is left as it is. */
inline void st_store_empty(const uint slot, __global uint2* bounds) {
  st_store_uint2(bounds, slot, ST_BOUNDS_EMPTY_MIN, ST_BOUNDS_EMPTY_MAX);
}

/* Sets up one source triangle into record slot `slot` (its world id `source`, its vertices
 * i0..i2 in the clip / screen / world buffers, already checked against the vertex count): flat
 * shading into triangle_colors[source], then the record from the projected vertices, or, when a
 * vertex needs clipping, clipping and the records of the pieces. The rare extra pieces of a
 * clipped triangle go to an overflow region after the first triangle_count slots, reserved with
 * a global atomic (counted even past overflow_capacity, so the host can grow it and re-run).
 * Slots stay in a fixed order (the draw order, not the thread order). The group form's bin_fill
 * appends to each tile's list with atomics, so a list's order varies between runs: a method
 * whose result depends on it (abuffer keeping the first K fragments of an overflowing pixel) is
 * not deterministic past its budget there; the serial binner keeps every list in slot order. */
inline void st_setup_triangle(const uint slot, const uint source, const uint i0, const uint i1,
                              const uint i2, const float4 mat, __global const float* positions,
                              const uint triangle_count, __global const float4* clip,
                              __global const StScreenVertex* screen,
                              __constant StViewConstants* view,
                              __global float4* triangle_colors, __global StTriSetup* records,
                              __global uint2* bounds, __global uint* tile_counts,
                              const uint tiles_x, const uint overflow_capacity,
                              __global ulong* counters) {
  {
    float3 n;
    triangle_colors[source] =
        st_flat_colour(st_load_point(i0, positions), st_load_point(i1, positions),
                       st_load_point(i2, positions), mat, view, &n);
  }
  const StScreenVertex s0 = screen[i0], s1 = screen[i1], s2 = screen[i2];
  if (s0.x != ST_SCREEN_CLIPPED && s1.x != ST_SCREEN_CLIPPED && s2.x != ST_SCREEN_CLIPPED) {
    /* A record of its own, seen only by this path's helpers (all inlined), so the compiler
     * keeps its fields in registers. The clipping path's record goes to helpers by address and
     * lives in memory: shared with it, this one was built with narrow stores and copied out in
     * wide loads, which stalled store forwarding on CPUs (a quarter of setup's time on PoCL). */
    StTriSetup record;
    if (st_setup_projected(s0, s1, s2, source, false, true, view, counters, &record))
      st_store_record(&record, slot, records, bounds, tile_counts, tiles_x);
    else
      st_store_empty(slot, bounds);
    return;
  }
  StTriSetup r;

  const float4 c0 = clip[i0], c1 = clip[i1], c2 = clip[i2];
  if (!all(isfinite(c0)) || !all(isfinite(c1)) || !all(isfinite(c2))) {
    atom_inc(&counters[ST_COUNTER_CULLED_NONFINITE]);
    st_store_empty(slot, bounds);
    return;
  }
  /* Clip, then fan-triangulate the polygon; each piece keeps the source triangle's winding. */
  const float near_d = view->near_distance;
  const float gx = 2.0f * ST_GUARD_BAND_PIXELS / (float)view->width;
  const float gy = 2.0f * ST_GUARD_BAND_PIXELS / (float)view->height;
  float4 poly[ST_MAX_CLIP_VERTS];
  const int count = st_clip_triangle(c0, c1, c2, near_d, gx, gy, poly);
  bool own_slot_used = false;
  if (count >= 3) atom_inc(&counters[ST_COUNTER_CLIPPED]);
  for (int k = 1; k + 1 < count; ++k) {
    if (!st_setup_record(poly[0], poly[k], poly[k + 1], source, true, view, counters, &r)) continue;
    if (!own_slot_used) {
      st_store_record(&r, slot, records, bounds, tile_counts, tiles_x);
      own_slot_used = true;
    } else {
      const ulong extra = atom_inc(&counters[ST_COUNTER_SETUP_OVERFLOW]);
      if (extra < overflow_capacity)
        st_store_record(&r, triangle_count + (uint)extra, records, bounds, tile_counts, tiles_x);
    }
  }
  if (!own_slot_used) st_store_empty(slot, bounds);
}

/* Triangle setup of one run of draw units (engine/features/batching.h): triangle l of the run is
 * triangle k of instance i of its draw, its vertices in the draw's clip / world range. The
 * record's source is the world triangle id (source_mode ST_SOURCE_*) and so is its slot,
 * whatever the batching and the draw order: the serial binner's tile lists keep the flattened
 * geometry's order, so there even a method that keeps the first K fragments it meets (abuffer)
 * renders the same image. tiles_x 0 leaves the tile counts to that binner. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void setup_draws(__global const float* positions, __global const uint* src_indices,
                 __global const StDraw* draws, const uint first_draw, const uint draw_count,
                 const uint triangle_total, const uint source_mode,
                 __global const uint* triangle_ids, __global const StInstance* instances,
                 __global const uint* triangle_material, __global const float4* material_colors,
                 const uint triangle_count, __global const float4* clip,
                 __global const StScreenVertex* screen, __constant StViewConstants* view,
                 __global float4* triangle_colors, __global StTriSetup* records,
                 __global uint2* bounds, __global uint* tile_counts, const uint tiles_x,
                 const uint overflow_capacity, __global ulong* counters) {
  const uint l = get_global_id(0);
  if (l >= triangle_total) return;
  __global const StDraw* d = &draws[st_find_draw(draws, first_draw, draw_count, l, 1)];
  const uint lt = l - d->triangle_prefix;
  const uint i = lt / d->triangle_count;
  const uint k = lt - i * d->triangle_count;
  const uint src_t = d->src_first_triangle + k;
  const uint vcount = d->vertex_count;
  const uint j0 = src_indices[3 * src_t], j1 = src_indices[3 * src_t + 1],
             j2 = src_indices[3 * src_t + 2];
  uint source;
  __global const StInstance* inst = &instances[d->first_instance + i];
  if (source_mode == ST_SOURCE_INSTANCE) source = inst->world_first_triangle + k;
  else source = source_mode == ST_SOURCE_ID_MAP ? triangle_ids[src_t] : src_t;
  if (j0 >= vcount || j1 >= vcount || j2 >= vcount) {
    st_store_empty(source, bounds);
    return;
  }
  const float4 mat = source_mode == ST_SOURCE_INSTANCE
                         ? (float4)(inst->color[0], inst->color[1], inst->color[2], inst->color[3])
                         : material_colors[triangle_material[source]];
  const uint base = d->dst_first_vertex + i * vcount;
  st_setup_triangle(source, source, base + j0, base + j1, base + j2, mat, positions,
                    triangle_count, clip, screen, view, triangle_colors, records, bounds,
                    tile_counts, tiles_x, overflow_capacity, counters);
}
