/* transform.cl: vertices -> clip space (x, y, d, w), d the view-space distance, and the
 * projected, snapped screen vertex setup reads (geometry.cl). */

/* Object -> world with an instance's affine transform, in the order glm evaluates
 * mat4 * vec4(p, 1): (c0 x + c1 y) + (c2 z + c3), never fused, so the world positions equal
 * WorldGeometry::fromScene's bit for bit and batching cannot change the image. */
inline float3 st_instance_point(__global const StInstance* inst, const float3 p) {
#pragma OPENCL FP_CONTRACT OFF
  __global const float* m = inst->m;
  const float3 c0 = (float3)(m[0], m[1], m[2]), c1 = (float3)(m[3], m[4], m[5]);
  const float3 c2 = (float3)(m[6], m[7], m[8]), c3 = (float3)(m[9], m[10], m[11]);
  const float3 a = c0 * p.x;
  const float3 b = c1 * p.y;
  const float3 c = c2 * p.z;
  const float3 ab = a + b;
  const float3 cd = c + c3;
  return ab + cd;
}

/* One launch per run of draw units (engine/batching.h): vertex v of the run is vertex lv of
 * its draw, vertex j of instance i. With transform_instances = 1 the source positions are object
 * space and the instance's transform applies (instancing, unbatched units); the world position
 * is also written for setup's shading. With 0 the source is already world space (static
 * batches) and `world` is not written. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void transform_instances(__global const float* src_positions,
                         __global const StInstance* instances, __global const StDraw* draws,
                         const uint first_draw, const uint draw_count, const uint vertex_total,
                         const uint apply_instances, __constant StViewConstants* view,
                         __global float4* clip, __global StScreenVertex* screen,
                         __global float* world) {
  const uint v = get_global_id(0);
  if (v >= vertex_total) return;
  __global const StDraw* d = &draws[st_find_draw(draws, first_draw, draw_count, v, 0)];
  const uint lv = v - d->vertex_prefix;
  const uint i = lv / d->vertex_count;
  const uint j = lv - i * d->vertex_count;
  float3 p = st_load_point(d->src_first_vertex + j, src_positions);
  const uint dst = d->dst_first_vertex + lv;
  if (apply_instances) {
    p = st_instance_point(&instances[d->first_instance + i], p);
    vstore3(p, dst, world);
  }
  const float4 c = st_clip_position(p, view);
  clip[dst] = c;
  screen[dst] = st_screen_vertex(c, view);
}

/* The unit normal of every triangle of a scene (zero for an invalid one), once per scene: the
 * cells setup shades each triangle from its normal every view, without its corners' positions
 * (builtin:spheres:96 at 1024x1024: setup 94 -> 76 ms). */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void triangle_normals(__global const float* positions, __global const uint* indices,
                      const uint triangle_count, const uint vertex_count,
                      __global float* normals) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  const uint i0 = indices[3 * t], i1 = indices[3 * t + 1], i2 = indices[3 * t + 2];
  const bool valid = i0 < vertex_count && i1 < vertex_count && i2 < vertex_count;
  vstore3(valid ? st_triangle_normal(st_load_point(i0, positions), st_load_point(i1, positions),
                                     st_load_point(i2, positions))
                : (float3)(0.0f),
          t, normals);
}

/* World-space vertices -> projected screen vertices, a work-item per vertex: the transform of
 * the cells and octree methods, whose setup takes triangles in the view's order of cells or
 * leaves, so that each vertex is projected and snapped once per view rather than once per
 * triangle corner. The clip-space positions are not kept: only a triangle with a clipped corner
 * needs them, and setup recomputes its three from the positions it reads anyway. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void transform_vertices(__global const float* positions, const uint vertex_count,
                        __constant StViewConstants* view, __global StScreenVertex* screen) {
  const uint v = get_global_id(0);
  if (v >= vertex_count) return;
  screen[v] = st_screen_vertex(st_clip_position(st_load_point(v, positions), view), view);
}
