/* cells_setup.cl: setup of one batch of convex cells in drawing order. Record slot i of the batch
 * holds the i-th triangle of the batch's cells in the view's order (cells_slots lays them out, a
 * work-item per cell), so a batch's slots, and with them every tile's bin list, run in
 * visibility order. With `projected` the scene's vertices were transformed and snapped once for
 * the view (transform_vertices); without (the octree method under a memory budget or streaming
 * its triangles: no per-vertex buffers) each corner is transformed here. The rare
 * extra pieces of a clipped triangle are reserved together and listed in slot_extra, so the
 * ordered binner can emit them right after their slot. The octree method sets up its leaves
 * with the same kernel: a leaf is a "cell" of its triangle references, and without cell_facing
 * no cell orientation is read; with batch_local (the octree method under a memory budget) the
 * batch's own triangles come in slot order, three corners each, instead of the whole scene. */

/* The relative (and, near zero, absolute) widening of a triangle's depth bounds: far more than
 * the rounding of its corners' distances and of the depth a fragment interpolates. */
#define ST_CELLS_DEPTH_SLACK 0x1p-12f

/* Lays out one batch's slots, a work-item per ordered cell k of the batch: the cell's triangles
 * take slots order_start[k] - order_start[batch_first] on, each with the cell's group tag
 * (record_group) and, unless batch_local, its triangle (slot_triangle). */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void cells_slots(__global const uint* cell_first, __global const uint* cell_triangles,
                 const int batch_local, __global const uint* order_cells,
                 __global const uint* order_start, __global const uint* order_group,
                 const uint batch_first, const uint batch_cells, __global uint* record_group,
                 __global uint* slot_triangle) {
  const uint k = get_global_id(0);
  if (k >= batch_cells) return;
  const uint ordered = batch_first + k;
  const uint base = order_start[batch_first];
  const uint first = order_start[ordered] - base, n = order_start[ordered + 1] - order_start[ordered];
  const uint group = order_group[ordered];
  for (uint j = 0; j < n; ++j) record_group[first + j] = group;
  if (batch_local) return;
  const uint from = cell_first[order_cells[ordered]];
  for (uint j = 0; j < n; ++j) slot_triangle[first + j] = cell_triangles[from + j];
}

/* The same layout a work-item per slot (GPUs, where a work-item per cell serializes a large
 * cell): slot i finds its ordered cell by binary search in order_start. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void cells_slots_by_slot(__global const uint* cell_first, __global const uint* cell_triangles,
                         const int batch_local, __global const uint* order_cells,
                         __global const uint* order_start, __global const uint* order_group,
                         const uint batch_first, const uint batch_cells,
                         __global uint* record_group, __global uint* slot_triangle,
                         const uint batch_slots) {
  const uint i = get_global_id(0);
  if (i >= batch_slots) return;
  const uint target = order_start[batch_first] + i;
  /* The last ordered cell of the batch whose start is at or before the slot. */
  uint lo = batch_first, n = batch_cells;
  while (n > 1) {
    const uint step = n >> 1;
    if (order_start[lo + step] <= target) {
      lo += step;
      n -= step;
    } else {
      n = step;
    }
  }
  record_group[i] = order_group[lo];
  if (!batch_local)
    slot_triangle[i] = cell_triangles[cell_first[order_cells[lo]] + target - order_start[lo]];
}

/* Record r in slot i, with its pixel bounds packed as setup.cl packs them (the ordered binner
 * reads those 8 bytes, not the record); and an empty slot. */
inline __attribute__((always_inline)) void st_cells_put(
    const StTriSetup* r, __global StTriSetup* records, __global uint2* record_bounds,
    const uint i) {
  st_write_record(&records[i], r);
  st_store_uint2(record_bounds, i, r->bounds_min, r->bounds_max);
}
inline void st_cells_put_empty(__global uint2* record_bounds, const uint i) {
  st_store_uint2(record_bounds, i, ST_BOUNDS_EMPTY_MIN, ST_BOUNDS_EMPTY_MAX);
}
/* Stores record r (set up when `ok`) in slot i, marked when it faces the front of its cell
 * (`flip`: the triangle is wound inwards), or marks the slot empty. */
inline __attribute__((always_inline)) void st_cells_store(
    const bool ok, StTriSetup* r, const uint flip, __global StTriSetup* records,
    __global uint2* record_bounds, const uint i) {
  if (!ok) {
    st_cells_put_empty(record_bounds, i);
    return;
  }
  if ((r->flags & ST_TRI_FRONT_FACING) != flip) r->flags |= ST_TRI_CELL_FRONT;
  st_cells_put(r, records, record_bounds, i);
}

__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void cells_setup(__global const float* positions, __global const uint* indices,
                 __global const float* triangle_normals, const int has_normals,
                 __global const uint* triangle_material, __global const float4* material_colors,
                 const uint vertex_count, __global const uchar* triangle_flip,
                 const int cell_facing, const int depth_bounds, const int batch_local,
                 __global const uint* slot_triangle, const uint batch_triangles,
                 const uint batch_capacity, const int projected,
                 __global const StScreenVertex* screen, __constant StViewConstants* view,
                 __global StTriSetup* records, __global uint2* record_bounds,
                 __global uint* record_group,
                 __global float4* record_color, __global float4* record_normal,
                 __global float2* record_depths, __global uint2* slot_extra,
                 const uint overflow_capacity,
                 __global ulong* batch_counters, __global ulong* counters,
                 const int colour_in_record) {
  const uint i = get_global_id(0);
  if (i >= batch_triangles) return;
  /* Slots visit the scene's triangles out of memory order, and PoCL runs the work-items one
   * after another: fetch the indices of a slot 32 ahead and the screen vertices of one 16 ahead
   * (horse, 1024x1024: setup 20-25% faster). */
  if (!batch_local) {
    if (i + 32 < batch_triangles) ST_PREFETCH(&indices[3 * slot_triangle[i + 32]]);
    if (projected && vertex_count > 0 && i + 16 < batch_triangles) {
      const uint ahead = 3 * slot_triangle[i + 16];
      ST_PREFETCH(&screen[min(indices[ahead], vertex_count - 1)]);
      ST_PREFETCH(&screen[min(indices[ahead + 1], vertex_count - 1)]);
      ST_PREFETCH(&screen[min(indices[ahead + 2], vertex_count - 1)]);
    }
  }
  /* batch_local: the batch's triangles were uploaded in slot order, three corners each. */
  const uint t = batch_local ? i : slot_triangle[i];
  slot_extra[i] = (uint2)(0u, 0u);
  const uint i0 = batch_local ? 3 * t : indices[3 * t];
  const uint i1 = batch_local ? 3 * t + 1 : indices[3 * t + 1];
  const uint i2 = batch_local ? 3 * t + 2 : indices[3 * t + 2];
  if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) {
    st_cells_put_empty(record_bounds, i);
    return;
  }
  /* The corners' positions only where they are needed: without the scene's normals
   * (triangle_normals), for the depth bounds, and to clip (below). */
  float3 p0 = (float3)(0.0f), p1 = p0, p2 = p0;
  const bool corners = !has_normals || depth_bounds;
  if (corners) {
    p0 = st_load_point(i0, positions);
    p1 = st_load_point(i1, positions);
    p2 = st_load_point(i2, positions);
  }
  const float3 n =
      has_normals ? st_load_point(t, triangle_normals) : st_triangle_normal(p0, p1, p2);
  const float4 colour = st_normal_colour(n, material_colors[triangle_material[t]], view);
  const float4 normal = (float4)(n, 0.0f);
  if (!colour_in_record) record_color[i] = colour;
  /* Only translucency reads the normal (its Fresnel term); otherwise the host sizes the buffer
   * for nothing. */
  const bool normals = view->effect == ST_EFFECT_TRANSLUCENCY;
  if (normals) record_normal[i] = normal;
  /* The view distances the triangle spans (its corners', widened for rounding; pieces clipped
   * from it span less): the composite's order check compares fragments by these first, so only
   * a frame drawn with an earlier view's order needs them (depth_bounds; never the octree). */
  float2 depths = (float2)(0.0f);
  if (depth_bounds) {
    const float d0 = st_view_distance(p0, view), d1 = st_view_distance(p1, view),
                d2 = st_view_distance(p2, view);
    const float lo = min(d0, min(d1, d2)), hi = max(d0, max(d1, d2));
    depths = (float2)(lo - (fabs(lo) * ST_CELLS_DEPTH_SLACK + ST_CELLS_DEPTH_SLACK),
                      hi + (fabs(hi) * ST_CELLS_DEPTH_SLACK + ST_CELLS_DEPTH_SLACK));
    st_store_float2(record_depths, i, depths);
  }

  const uint flip = cell_facing ? triangle_flip[t] : 0u;
  if (projected) { /* transform_vertices projected the scene's vertices for this view */
    const StScreenVertex s0 = screen[i0], s1 = screen[i1], s2 = screen[i2];
    if (s0.x != ST_SCREEN_CLIPPED && s1.x != ST_SCREEN_CLIPPED && s2.x != ST_SCREEN_CLIPPED) {
      StTriSetup record; /* its own, kept in registers (setup.cl, st_setup_triangle) */
      const bool ok =
          st_setup_projected(s0, s1, s2, t, false, !colour_in_record, view, counters, &record);
      if (colour_in_record) st_cells_colour_in_record(&record, colour);
      st_cells_store(ok, &record, flip, records, record_bounds, i);
      return;
    }
  }
  /* A corner to clip, or no projected vertices: clip space from the positions (the transform's
   * own computation, so the same bits). */
  if (!corners) {
    p0 = st_load_point(i0, positions);
    p1 = st_load_point(i1, positions);
    p2 = st_load_point(i2, positions);
  }
  const float4 c0 = st_clip_position(p0, view), c1 = st_clip_position(p1, view),
               c2 = st_clip_position(p2, view);
  if (!st_corners_finite(c0, c1, c2, counters)) {
    st_cells_put_empty(record_bounds, i);
    return;
  }
  const float near_d = view->near_distance;
  const float2 g = st_guard_band(view);
  StTriSetup r;
  if (st_needs_no_clipping(c0, c1, c2, near_d, g.x, g.y)) {
    const bool ok = st_setup_record(c0, c1, c2, t, false, view, counters, &r);
    if (colour_in_record) st_cells_colour_in_record(&r, colour);
    st_cells_store(ok, &r, flip, records, record_bounds, i);
    return;
  }

  /* Clipped (setup.cl's rule): the first piece takes the slot, the others are reserved together
   * in the overflow region after the batch's slots. */
  float4 poly[ST_MAX_CLIP_VERTS];
  const int count = st_clip_triangle(c0, c1, c2, near_d, g.x, g.y, poly);
  if (count >= 3) st_counter_claim(&counters[ST_COUNTER_CLIPPED], 1);
  StTriSetup pieces[ST_CELLS_MAX_CLIP_PIECES];
  uint kept = 0;
  for (int k = 1; k + 1 < count && kept < ST_CELLS_MAX_CLIP_PIECES; ++k) {
    if (st_setup_record(poly[0], poly[k], poly[k + 1], t, true, view, counters, &pieces[kept])) {
      if ((pieces[kept].flags & ST_TRI_FRONT_FACING) != flip) pieces[kept].flags |= ST_TRI_CELL_FRONT;
      if (colour_in_record) st_cells_colour_in_record(&pieces[kept], colour);
      ++kept;
    }
  }
  if (kept == 0) {
    st_cells_put_empty(record_bounds, i);
    return;
  }
  st_cells_put(&pieces[0], records, record_bounds, i);
  if (kept > 1) {
    const uint extra = kept - 1;
    const ulong start = st_counter_claim(&batch_counters[ST_CELLS_BATCH_EXTRA], (ulong)extra);
    st_counter_max(&counters[ST_COUNTER_SETUP_OVERFLOW], start + extra);
    if (start + extra <= overflow_capacity) {
      const uint group = record_group[i]; /* cells_slots */
      for (uint k = 0; k < extra; ++k) {
        const uint slot = batch_capacity + (uint)start + k;
        st_cells_put(&pieces[k + 1], records, record_bounds, slot);
        record_group[slot] = group;
        if (!colour_in_record) record_color[slot] = colour;
        if (normals) record_normal[slot] = normal;
        if (depth_bounds) st_store_float2(record_depths, slot, depths);
      }
      slot_extra[i] = (uint2)((uint)start, extra);
    }
  }
}
