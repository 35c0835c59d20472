/* setup.cl: triangle setup. Per source triangle: flat shading colour, homogeneous clipping
 * (near plane always, guard band when a vertex would overflow fixed point), perspective divide,
 * snapping to ST_SUBPIXEL_BITS, facing, edge equations with the top-left rule, depth planes,
 * pixel bounds. Surviving (sub-)triangles are appended to `records`; the count needed is
 * reported even past `capacity` so the host can grow the buffer and re-run. */

#define ST_MAX_CLIP_VERTS 9

/* Signed distance of a clip-space vertex (x, y, d, w) to clip plane `plane`; all four components
 * are affine in world position, so linear interpolation along an edge is exact. */
inline float st_plane_distance(float4 v, int plane, float near_d, float gx, float gy) {
  switch (plane) {
    case 0: return v.z - near_d;
    case 1: return gx * v.w - v.x;
    case 2: return gx * v.w + v.x;
    case 3: return gy * v.w - v.y;
    default: return gy * v.w + v.y;
  }
}

/* Sutherland-Hodgman against one plane; returns the new vertex count. */
inline int st_clip_polygon(const float4* in, int n, float4* out, int plane, float near_d, float gx,
                           float gy) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const float4 a = in[i];
    const float4 b = in[(i + 1) % n];
    const float da = st_plane_distance(a, plane, near_d, gx, gy);
    const float db = st_plane_distance(b, plane, near_d, gx, gy);
    if (da >= 0.0f) out[m++] = a;
    /* Interpolate from the inside vertex, so the two triangles sharing an edge compute the
     * same point bit for bit and clipped neighbours leave no crack or overlap. */
    if (da >= 0.0f && db < 0.0f) out[m++] = a + (b - a) * (da / (da - db));
    if (da < 0.0f && db >= 0.0f) out[m++] = b + (a - b) * (db / (db - da));
  }
  return m;
}

/* floor(a / ST_SUBPIXEL_ONE) for a >= -4 * ST_SUBPIXEL_ONE (no signed-shift assumptions). */
inline int st_floor_div_one(int a) { return (a + 4 * ST_SUBPIXEL_ONE) / ST_SUBPIXEL_ONE - 4; }

inline bool st_is_top_left(int a, int b) { return a > 0 || (a == 0 && b > 0); }

__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void setup_triangles(__global const float* positions, __global const uint* indices,
                     __global const uint* triangle_material, __global const float4* material_colors,
                     const uint vertex_count, const uint triangle_count,
                     __global const float4* clip, __constant StViewConstants* view,
                     __global float4* triangle_colors, __global StTriSetup* records,
                     const uint capacity, __global ulong* counters) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  const uint i0 = indices[3 * t], i1 = indices[3 * t + 1], i2 = indices[3 * t + 2];
  if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) return;

  /* Flat shading, identical to shadeTriangle() on the host. */
  const float3 p0 = vload3(i0, positions), p1 = vload3(i1, positions), p2 = vload3(i2, positions);
  float3 n = cross(p1 - p0, p2 - p0);
  const float len = length(n);
  n = len > 0.0f ? n / len : (float3)(0.0f);
  const float3 light = (float3)(view->light_dir[0], view->light_dir[1], view->light_dir[2]);
  const float4 mat = material_colors[triangle_material[t]];
  triangle_colors[t] = (float4)(mat.xyz * st_diffuse_factor(dot(n, light)), mat.w);

  float4 poly[ST_MAX_CLIP_VERTS], tmp[ST_MAX_CLIP_VERTS];
  poly[0] = clip[i0];
  poly[1] = clip[i1];
  poly[2] = clip[i2];
  for (int k = 0; k < 3; ++k) {
    if (!all(isfinite(poly[k]))) {
      atom_inc(&counters[ST_COUNTER_CULLED_NONFINITE]);
      return;
    }
  }
  const int width = view->width, height = view->height;
  const float near_d = view->near_distance;
  const float gx = 2.0f * ST_GUARD_BAND_PIXELS / (float)width;
  const float gy = 2.0f * ST_GUARD_BAND_PIXELS / (float)height;

  /* Clip only against planes some vertex is outside of (almost always none). */
  int count = 3;
  bool clipped = false;
  for (int plane = 0; plane < 5 && count >= 3; ++plane) {
    bool outside = false;
    for (int k = 0; k < count; ++k)
      outside |= st_plane_distance(poly[k], plane, near_d, gx, gy) < 0.0f;
    if (!outside) continue;
    clipped = true;
    count = st_clip_polygon(poly, count, tmp, plane, near_d, gx, gy);
    for (int k = 0; k < count; ++k) poly[k] = tmp[k];
  }
  if (count < 3) return;
  if (clipped) atom_inc(&counters[ST_COUNTER_CLIPPED]);

  /* Project and snap: pixel coordinates with y down, row 0 at the top. */
  int sx[ST_MAX_CLIP_VERTS], sy[ST_MAX_CLIP_VERTS];
  float dw[ST_MAX_CLIP_VERTS], iw[ST_MAX_CLIP_VERTS];
  for (int k = 0; k < count; ++k) {
    const float inv_w = 1.0f / poly[k].w;
    const float px = (poly[k].x * inv_w * 0.5f + 0.5f) * (float)width;
    const float py = (0.5f - poly[k].y * inv_w * 0.5f) * (float)height;
    sx[k] = convert_int_rte(px * (float)ST_SUBPIXEL_ONE);
    sy[k] = convert_int_rte(py * (float)ST_SUBPIXEL_ONE);
    dw[k] = poly[k].z * inv_w;
    iw[k] = inv_w;
  }

  /* Fan-triangulate the clipped polygon; each piece keeps the source triangle's winding. */
  for (int k = 1; k + 1 < count; ++k) {
    int vx[3] = {sx[0], sx[k], sx[k + 1]}, vy[3] = {sy[0], sy[k], sy[k + 1]};
    float vdw[3] = {dw[0], dw[k], dw[k + 1]}, viw[3] = {iw[0], iw[k], iw[k + 1]};
    long area2 = (long)(vx[1] - vx[0]) * (long)(vy[2] - vy[0]) -
                 (long)(vx[2] - vx[0]) * (long)(vy[1] - vy[0]);
    if (area2 == 0) {
      if (!clipped) atom_inc(&counters[ST_COUNTER_CULLED_DEGENERATE]);
      continue;
    }
    /* Counter-clockwise in NDC (y up) is front facing: negative area with y down. */
    const uint flags = area2 < 0 ? ST_TRI_FRONT_FACING : 0u;
    if (area2 < 0) { /* orient so the inside of every edge is positive */
      int ti = vx[1]; vx[1] = vx[2]; vx[2] = ti;
      ti = vy[1]; vy[1] = vy[2]; vy[2] = ti;
      float tf = vdw[1]; vdw[1] = vdw[2]; vdw[2] = tf;
      tf = viw[1]; viw[1] = viw[2]; viw[2] = tf;
      area2 = -area2;
    }
    /* Pixel bounds: pixel x has its centre at x * ONE + ONE / 2. */
    const int centre = ST_SUBPIXEL_ONE / 2;
    const int lo_x = min(vx[0], min(vx[1], vx[2])), hi_x = max(vx[0], max(vx[1], vx[2]));
    const int lo_y = min(vy[0], min(vy[1], vy[2])), hi_y = max(vy[0], max(vy[1], vy[2]));
    const int one = ST_SUBPIXEL_ONE;
    const int min_x = max(0, st_floor_div_one(clamp(lo_x, -one, (width + 1) * one) - centre + one - 1));
    const int min_y = max(0, st_floor_div_one(clamp(lo_y, -one, (height + 1) * one) - centre + one - 1));
    const int max_x = min(width - 1, st_floor_div_one(clamp(hi_x, -one, (width + 1) * one) - centre));
    const int max_y = min(height - 1, st_floor_div_one(clamp(hi_y, -one, (height + 1) * one) - centre));
    if (min_x > max_x || min_y > max_y) continue;

    StTriSetup r;
    for (int e = 0; e < 3; ++e) {
      const int a = (e + 1) % 3;
      /* E(p) = (Xa - Xe)(Py - Ye) - (Ya - Ye)(Px - Xe): positive inside. */
      const int ea = vy[e] - vy[a];
      const int eb = vx[a] - vx[e];
      long c = -((long)ea * (long)vx[e] + (long)eb * (long)vy[e]);
      /* Top-left rule: pixel centres exactly on an edge belong to top or left edges only. */
      if (!st_is_top_left(ea, eb)) c -= 1;
      r.edge_a[e] = ea;
      r.edge_b[e] = eb;
      r.edge_c[e] = c;
    }
    r.min_x = min_x;
    r.min_y = min_y;
    r.max_x = max_x;
    r.max_y = max_y;
    /* Affine planes of d/w and 1/w over the snapped positions, relative to vertex 0. */
    const float inv_one = 1.0f / (float)ST_SUBPIXEL_ONE;
    const float x0 = vx[0] * inv_one, y0 = vy[0] * inv_one;
    const float dx1 = vx[1] * inv_one - x0, dy1 = vy[1] * inv_one - y0;
    const float dx2 = vx[2] * inv_one - x0, dy2 = vy[2] * inv_one - y0;
    const float inv_det = 1.0f / ((float)area2 * inv_one * inv_one);
    r.origin_x = x0;
    r.origin_y = y0;
    r.dw0 = vdw[0];
    r.dw_dx = ((vdw[1] - vdw[0]) * dy2 - (vdw[2] - vdw[0]) * dy1) * inv_det;
    r.dw_dy = ((vdw[2] - vdw[0]) * dx1 - (vdw[1] - vdw[0]) * dx2) * inv_det;
    r.iw0 = viw[0];
    r.iw_dx = ((viw[1] - viw[0]) * dy2 - (viw[2] - viw[0]) * dy1) * inv_det;
    r.iw_dy = ((viw[2] - viw[0]) * dx1 - (viw[1] - viw[0]) * dx2) * inv_det;
    r.source = t;
    r.flags = flags;
    const ulong slot = atom_inc(&counters[ST_COUNTER_SETUP_TRIANGLES]);
    if (slot < capacity) records[slot] = r;
  }
}
