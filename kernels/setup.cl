/* setup.cl: triangle setup. Per source triangle: flat shading colour, homogeneous clipping
 * (near plane always, guard band when a vertex would overflow fixed point), perspective divide,
 * snapping to ST_SUBPIXEL_BITS, facing, edge equations with the top-left rule, depth planes,
 * pixel bounds. */

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

/* Clips a clip-space triangle against the planes some corner is outside of (near plane and
 * guard band) into poly; returns the polygon's corner count (< 3: nothing left). */
inline int st_clip_triangle(float4 c0, float4 c1, float4 c2, float near_d, float gx, float gy,
                            float4* poly) {
  float4 tmp[ST_MAX_CLIP_VERTS];
  poly[0] = c0;
  poly[1] = c1;
  poly[2] = c2;
  int count = 3;
  for (int plane = 0; plane < 5 && count >= 3; ++plane) {
    bool outside = false;
    for (int k = 0; k < count; ++k)
      outside |= st_plane_distance(poly[k], plane, near_d, gx, gy) < 0.0f;
    if (!outside) continue;
    count = st_clip_polygon(poly, count, tmp, plane, near_d, gx, gy);
    for (int k = 0; k < count; ++k) poly[k] = tmp[k];
  }
  return count;
}

/* floor(a / ST_SUBPIXEL_ONE) for a >= -4 * ST_SUBPIXEL_ONE (no signed-shift assumptions). */
inline int st_floor_div_one(int a) { return (a + 4 * ST_SUBPIXEL_ONE) / ST_SUBPIXEL_ONE - 4; }

inline bool st_is_top_left(int a, int b) { return a > 0 || (a == 0 && b > 0); }

/* Projects, snaps and sets up one triangle of clip-space vertices (all in front of the near
 * plane and inside the guard band) into *r. Returns false if it covers no pixel bounds. */
inline bool st_setup_record(float4 c0, float4 c1, float4 c2, const uint source, const bool clipped,
                            __constant StViewConstants* view, __global ulong* counters,
                            StTriSetup* out) {
  const int width = view->width, height = view->height;
  /* Project and snap: pixel coordinates with y down, row 0 at the top. */
  const float3 inv_w = (float3)(1.0f / c0.w, 1.0f / c1.w, 1.0f / c2.w);
  const float3 cx = (float3)(c0.x, c1.x, c2.x), cy = (float3)(c0.y, c1.y, c2.y);
  const float3 px = (cx * inv_w * 0.5f + 0.5f) * (float)width;
  const float3 py = (0.5f - cy * inv_w * 0.5f) * (float)height;
  const int3 sx = convert_int3_rte(px * (float)ST_SUBPIXEL_ONE);
  const int3 sy = convert_int3_rte(py * (float)ST_SUBPIXEL_ONE);
  int vx0 = sx.x, vx1 = sx.y, vx2 = sx.z, vy0 = sy.x, vy1 = sy.y, vy2 = sy.z;
  float dw0 = c0.z * inv_w.x, dw1 = c1.z * inv_w.y, dw2 = c2.z * inv_w.z;
  float iw0 = inv_w.x, iw1 = inv_w.y, iw2 = inv_w.z;
  long area2 = (long)(vx1 - vx0) * (long)(vy2 - vy0) - (long)(vx2 - vx0) * (long)(vy1 - vy0);
  if (area2 == 0) {
    if (!clipped) atom_inc(&counters[ST_COUNTER_CULLED_DEGENERATE]);
    return false;
  }
  /* Counter-clockwise in NDC (y up) is front facing: negative area with y down. */
  const uint flags = area2 < 0 ? ST_TRI_FRONT_FACING : 0u;
  if (area2 < 0) { /* orient so the inside of every edge is positive */
    int ti = vx1; vx1 = vx2; vx2 = ti;
    ti = vy1; vy1 = vy2; vy2 = ti;
    float tf = dw1; dw1 = dw2; dw2 = tf;
    tf = iw1; iw1 = iw2; iw2 = tf;
    area2 = -area2;
  }
  /* Pixel bounds: pixel x has its centre at x * ONE + ONE / 2. */
  const int one = ST_SUBPIXEL_ONE, centre = ST_SUBPIXEL_ONE / 2;
  const int lo_x = min(vx0, min(vx1, vx2)), hi_x = max(vx0, max(vx1, vx2));
  const int lo_y = min(vy0, min(vy1, vy2)), hi_y = max(vy0, max(vy1, vy2));
  const int min_x = max(0, st_floor_div_one(clamp(lo_x, -one, (width + 1) * one) - centre + one - 1));
  const int min_y = max(0, st_floor_div_one(clamp(lo_y, -one, (height + 1) * one) - centre + one - 1));
  const int max_x = min(width - 1, st_floor_div_one(clamp(hi_x, -one, (width + 1) * one) - centre));
  const int max_y = min(height - 1, st_floor_div_one(clamp(hi_y, -one, (height + 1) * one) - centre));
  if (min_x > max_x || min_y > max_y) return false;

  StTriSetup r;
  /* Edge e runs from vertex e to vertex e+1: E(p) = (Xb - Xa)(Py - Ya) - (Yb - Ya)(Px - Xa),
   * positive inside. Top-left rule: centres exactly on an edge belong to top or left edges. */
  const int ax[3] = {vx0, vx1, vx2}, ay[3] = {vy0, vy1, vy2};
  for (int e = 0; e < 3; ++e) {
    const int b = e == 2 ? 0 : e + 1;
    const int ea = ay[e] - ay[b];
    const int eb = ax[b] - ax[e];
    long c = -((long)ea * (long)ax[e] + (long)eb * (long)ay[e]);
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
  const float x0 = vx0 * inv_one, y0 = vy0 * inv_one;
  const float dx1 = vx1 * inv_one - x0, dy1 = vy1 * inv_one - y0;
  const float dx2 = vx2 * inv_one - x0, dy2 = vy2 * inv_one - y0;
  const float inv_det = 1.0f / ((float)area2 * inv_one * inv_one);
  r.origin_x = x0;
  r.origin_y = y0;
  r.dw0 = dw0;
  r.dw_dx = ((dw1 - dw0) * dy2 - (dw2 - dw0) * dy1) * inv_det;
  r.dw_dy = ((dw2 - dw0) * dx1 - (dw1 - dw0) * dx2) * inv_det;
  r.iw0 = iw0;
  r.iw_dx = ((iw1 - iw0) * dy2 - (iw2 - iw0) * dy1) * inv_det;
  r.iw_dy = ((iw2 - iw0) * dx1 - (iw1 - iw0) * dx2) * inv_det;
  r.source = source;
  r.flags = flags;
  *out = r;
  return true;
}

/* Unit normal of a triangle (zero for no area) and its flat-shaded colour: material colour times
 * two-sided diffuse, alpha = opacity; identical to shadeTriangle() on the host. */
inline float4 st_flat_colour(float3 p0, float3 p1, float3 p2, float4 mat,
                             __constant StViewConstants* view, float3* normal) {
  float3 n = cross(p1 - p0, p2 - p0);
  const float len = length(n);
  n = len > 0.0f ? n / len : (float3)(0.0f);
  *normal = n;
  const float3 light = (float3)(view->light_dir[0], view->light_dir[1], view->light_dir[2]);
  return (float4)(mat.xyz * st_diffuse_factor(dot(n, light)), mat.w);
}

/* Whether a clip-space triangle lies in front of the near plane and inside the guard band, so it
 * needs no clipping (almost every triangle). */
inline bool st_needs_no_clipping(float4 c0, float4 c1, float4 c2, float near_d, float gx,
                                 float gy) {
  const float3 d = (float3)(c0.z, c1.z, c2.z), w = (float3)(c0.w, c1.w, c2.w);
  const float3 x = (float3)(c0.x, c1.x, c2.x), y = (float3)(c0.y, c1.y, c2.y);
  return all(d >= near_d) && all(fabs(x) <= gx * w) && all(fabs(y) <= gy * w);
}

/* Marks a record slot as covering nothing (the binner skips it). */
inline void st_empty_record(__global StTriSetup* records, uint slot) {
  records[slot].min_x = 1;
  records[slot].max_x = 0;
}

/* Sets up one source triangle into record slot `slot` (its world id `source`, its vertices
 * i0..i2 in the clip / world buffers, already checked against the vertex count): flat shading
 * into triangle_colors[source], then clipping and the records. The rare extra pieces of a
 * clipped triangle go to an overflow region after the first triangle_count slots, reserved with
 * a global atomic (counted even past overflow_capacity, so the host can grow it and re-run).
 * Slots stay in a fixed order, so per-tile lists are deterministic. */
inline void st_setup_triangle(const uint slot, const uint source, const uint i0, const uint i1,
                              const uint i2, const float4 mat, __global const float* positions,
                              const uint triangle_count, __global const float4* clip,
                              __constant StViewConstants* view,
                              __global float4* triangle_colors, __global StTriSetup* records,
                              const uint overflow_capacity, __global ulong* counters) {
  {
    float3 n;
    triangle_colors[source] = st_flat_colour(vload3(i0, positions), vload3(i1, positions),
                                             vload3(i2, positions), mat, view, &n);
  }
  const float4 c0 = clip[i0], c1 = clip[i1], c2 = clip[i2];
  if (!all(isfinite(c0)) || !all(isfinite(c1)) || !all(isfinite(c2))) {
    atom_inc(&counters[ST_COUNTER_CULLED_NONFINITE]);
    st_empty_record(records, slot);
    return;
  }
  const float near_d = view->near_distance;
  const float gx = 2.0f * ST_GUARD_BAND_PIXELS / (float)view->width;
  const float gy = 2.0f * ST_GUARD_BAND_PIXELS / (float)view->height;
  StTriSetup r;

  if (st_needs_no_clipping(c0, c1, c2, near_d, gx, gy)) {
    if (st_setup_record(c0, c1, c2, source, false, view, counters, &r)) records[slot] = r;
    else st_empty_record(records, slot);
    return;
  }

  /* Clip, then fan-triangulate the polygon; each piece keeps the source triangle's winding. */
  float4 poly[ST_MAX_CLIP_VERTS];
  const int count = st_clip_triangle(c0, c1, c2, near_d, gx, gy, poly);
  bool own_slot_used = false;
  if (count >= 3) atom_inc(&counters[ST_COUNTER_CLIPPED]);
  for (int k = 1; k + 1 < count; ++k) {
    if (!st_setup_record(poly[0], poly[k], poly[k + 1], source, true, view, counters, &r)) continue;
    if (!own_slot_used) {
      records[slot] = r;
      own_slot_used = true;
    } else {
      const ulong extra = atom_inc(&counters[ST_COUNTER_SETUP_OVERFLOW]);
      if (extra < overflow_capacity) records[triangle_count + extra] = r;
    }
  }
  if (!own_slot_used) st_empty_record(records, slot);
}

/* Triangle setup of the whole flattened geometry: source triangle t owns record slot t. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void setup_triangles(__global const float* positions, __global const uint* indices,
                     __global const uint* triangle_material, __global const float4* material_colors,
                     const uint vertex_count, const uint triangle_count,
                     __global const float4* clip, __constant StViewConstants* view,
                     __global float4* triangle_colors, __global StTriSetup* records,
                     const uint overflow_capacity, __global ulong* counters) {
  const uint t = get_global_id(0);
  if (t >= triangle_count) return;
  const uint i0 = indices[3 * t], i1 = indices[3 * t + 1], i2 = indices[3 * t + 2];
  if (i0 >= vertex_count || i1 >= vertex_count || i2 >= vertex_count) {
    st_empty_record(records, t);
    return;
  }
  st_setup_triangle(t, t, i0, i1, i2, material_colors[triangle_material[t]], positions,
                    triangle_count, clip, view, triangle_colors, records, overflow_capacity,
                    counters);
}

/* Triangle setup of one run of draw units (engine/batching.h): triangle l of the run is
 * triangle k of instance i of its draw, its vertices in the draw's clip / world range. The
 * record's source is the world triangle id (source_mode ST_SOURCE_*) and so is its slot: tile
 * lists keep the flattened geometry's order whatever the batching and the draw order, so even
 * a method that keeps the first K fragments it meets (abuffer) renders the same image. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void setup_draws(__global const float* positions, __global const uint* src_indices,
                 __global const StDraw* draws, const uint first_draw, const uint draw_count,
                 const uint triangle_total, const uint source_mode,
                 __global const uint* triangle_ids, __global const StInstance* instances,
                 __global const uint* triangle_material, __global const float4* material_colors,
                 const uint triangle_count, __global const float4* clip,
                 __constant StViewConstants* view, __global float4* triangle_colors,
                 __global StTriSetup* records, const uint overflow_capacity,
                 __global ulong* counters) {
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
    st_empty_record(records, source);
    return;
  }
  const float4 mat = source_mode == ST_SOURCE_INSTANCE
                         ? (float4)(inst->color[0], inst->color[1], inst->color[2], inst->color[3])
                         : material_colors[triangle_material[source]];
  const uint base = d->dst_first_vertex + i * vcount;
  st_setup_triangle(source, source, base + j0, base + j1, base + j2, mat, positions,
                    triangle_count, clip, view, triangle_colors, records, overflow_capacity,
                    counters);
}
