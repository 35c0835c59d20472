/* setup.cl: triangle setup of a run of draw units: per source triangle its flat shading colour,
 * clipping, setup records and their tile counts (the steps, st_setup_triangle, are in
 * geometry.cl, which the cells' setup shares). */

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
  uint i, k;
  __global const StDraw* d = st_draw_element(draws, first_draw, draw_count, l, 1, &i, &k);
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
