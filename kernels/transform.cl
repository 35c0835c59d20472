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

/* One launch per run of draw units (engine/features/batching.h): vertex v of the run is vertex lv of
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
  uint i, j;
  __global const StDraw* d = st_draw_element(draws, first_draw, draw_count, v, 0, &i, &j);
  float3 p = st_load_point(d->src_first_vertex + j, src_positions);
  const uint dst = d->dst_first_vertex + i * d->vertex_count + j;
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

/* transform_vertices eight vertices a work-item, in the lanes of float8 (CPU devices: PoCL
 * turns explicit vectors into SIMD and leaves the work-item loop scalar; builtin:spheres:96's
 * 3.8M vertices, 15.0 -> 5.1 ms). Every lane takes st_clip_position's and st_screen_vertex's
 * operations in their order, so the same bits; a last partial group of eight, one at a time. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void transform_vertices_lanes(__global const float* positions, const uint vertex_count,
                              __constant StViewConstants* view, __global StScreenVertex* screen) {
  const uint first = get_global_id(0) * 8;
  if (first >= vertex_count) return;
  if (vertex_count - first < 8) {
    for (uint v = first; v < vertex_count; ++v)
      screen[v] = st_screen_vertex(st_clip_position(st_load_point(v, positions), view), view);
    return;
  }
  const float8 p0 = vload8(0, positions + 3 * (size_t)first);
  const float8 p1 = vload8(1, positions + 3 * (size_t)first);
  const float8 p2 = vload8(2, positions + 3 * (size_t)first);
  const float8 x = (float8)(p0.s0, p0.s3, p0.s6, p1.s1, p1.s4, p1.s7, p2.s2, p2.s5);
  const float8 y = (float8)(p0.s1, p0.s4, p0.s7, p1.s2, p1.s5, p2.s0, p2.s3, p2.s6);
  const float8 z = (float8)(p0.s2, p0.s5, p1.s0, p1.s3, p1.s6, p2.s1, p2.s4, p2.s7);
  /* st_clip_position */
  __constant const float* m = view->view_proj;
  const float8 cx = m[0] * x + m[4] * y + m[8] * z + m[12];
  const float8 cy = m[1] * x + m[5] * y + m[9] * z + m[13];
  const float8 cw = m[3] * x + m[7] * y + m[11] * z + m[15];
  const float8 cz = view->view_row[0] * x + view->view_row[1] * y + view->view_row[2] * z +
                    view->view_row[3];
  /* st_screen_vertex: st_project_vertex, and the clipping test */
  const float8 inv_w = 1.0f / cw;
  const float8 px = (cx * inv_w * 0.5f + 0.5f) * (float)view->width;
  const float8 py = (0.5f - cy * inv_w * 0.5f) * (float)view->height;
  const int8 sx = convert_int8(ST_RINT(px * (float)ST_SUBPIXEL_ONE));
  const int8 sy = convert_int8(ST_RINT(py * (float)ST_SUBPIXEL_ONE));
  const float8 dw = cz * inv_w;
  const float2 g = st_guard_band(view);
  const int8 kept = isfinite(cx) & isfinite(cy) & isfinite(cz) & isfinite(cw) &
                    (cz >= view->near_distance) & (fabs(cx) <= g.x * cw) & (fabs(cy) <= g.y * cw);
  const int8 vx = select((int8)(ST_SCREEN_CLIPPED), sx, kept);
  __global int* out = (__global int*)(screen + first);
  const int8 dwi = as_int8(dw), iwi = as_int8(inv_w);
  vstore8((int8)(vx.s0, sy.s0, dwi.s0, iwi.s0, vx.s1, sy.s1, dwi.s1, iwi.s1), 0, out);
  vstore8((int8)(vx.s2, sy.s2, dwi.s2, iwi.s2, vx.s3, sy.s3, dwi.s3, iwi.s3), 1, out);
  vstore8((int8)(vx.s4, sy.s4, dwi.s4, iwi.s4, vx.s5, sy.s5, dwi.s5, iwi.s5), 2, out);
  vstore8((int8)(vx.s6, sy.s6, dwi.s6, iwi.s6, vx.s7, sy.s7, dwi.s7, iwi.s7), 3, out);
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
