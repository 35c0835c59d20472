/* geometry.cl: front-end helpers shared by transform.cl, setup.cl and cells_setup.cl: clip-space
 * positions, the draw table lookup, homogeneous clipping (near plane always, guard band when a
 * vertex would overflow fixed point), perspective divide, snapping to ST_SUBPIXEL_BITS, facing,
 * edge equations with the top-left rule, depth planes, pixel bounds and flat shading. */

/* The view-space distance of world position p. */
inline float st_view_distance(float3 p, __constant StViewConstants* view) {
  return view->view_row[0] * p.x + view->view_row[1] * p.y + view->view_row[2] * p.z +
         view->view_row[3];
}

/* The guard band in clip space, as |x| <= gx w and |y| <= gy w: (gx, gy). A vertex inside it
 * and in front of the near plane needs no clipping. */
inline float2 st_guard_band(__constant StViewConstants* view) {
  return (float2)(2.0f * ST_GUARD_BAND_PIXELS / (float)view->width,
                  2.0f * ST_GUARD_BAND_PIXELS / (float)view->height);
}

/* Whether a triangle's clip-space corners are all finite; one that is not is culled and
 * counted. */
inline bool st_corners_finite(float4 c0, float4 c1, float4 c2, __global ulong* counters) {
  if (all(isfinite(c0)) && all(isfinite(c1)) && all(isfinite(c2))) return true;
  st_counter_claim(&counters[ST_COUNTER_CULLED_NONFINITE], 1);
  return false;
}

/* World position -> clip space (x, y, d, w), d the view-space distance. */
inline float4 st_clip_position(float3 p, __constant StViewConstants* view) {
  __constant const float* m = view->view_proj; /* column-major */
  const float x = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
  const float y = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
  const float w = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
  return (float4)(x, y, st_view_distance(p, view), w);
}

/* The draw of a run that holds run-local item `v` (vertex or triangle): the last draw whose
 * prefix is <= v (draws with no items share their successor's prefix and are skipped). */
inline uint st_find_draw(__global const StDraw* draws, const uint first, const uint count,
                         const uint v, const int by_triangles) {
  uint lo = first, hi = first + count - 1;
  while (lo < hi) {
    const uint mid = (lo + hi + 1) / 2;
    const uint p = by_triangles ? draws[mid].triangle_prefix : draws[mid].vertex_prefix;
    if (p <= v) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}

/* Element l of a run of draw units (a vertex, or a triangle with by_triangles): its draw, the
 * draw's instance it belongs to (*instance) and its index in that instance's mesh (*element). */
inline __global const StDraw* st_draw_element(__global const StDraw* draws, uint first, uint count,
                                              uint l, int by_triangles, uint* instance,
                                              uint* element) {
  __global const StDraw* d = &draws[st_find_draw(draws, first, count, l, by_triangles)];
  const uint in_run = l - (by_triangles ? d->triangle_prefix : d->vertex_prefix);
  const uint per_instance = by_triangles ? d->triangle_count : d->vertex_count;
  *instance = in_run / per_instance;
  *element = in_run - *instance * per_instance;
  return d;
}

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

/* Whether a clip-space vertex lies in front of the near plane and inside the guard band (and
 * is finite): a triangle of three such vertices needs no clipping (almost every triangle). */
inline __attribute__((always_inline)) bool st_vertex_needs_no_clipping(float4 c, float near_d,
                                                                     float gx, float gy) {
  return all(isfinite(c)) && c.z >= near_d && fabs(c.x) <= gx * c.w && fabs(c.y) <= gy * c.w;
}

/* Projects and snaps a clip-space vertex (in front of the near plane, inside the guard band):
 * pixel coordinates with y down, row 0 at the top. */
inline __attribute__((always_inline)) StScreenVertex st_project_vertex(float4 c, int width,
                                                                       int height) {
  const float inv_w = 1.0f / c.w;
  const float px = (c.x * inv_w * 0.5f + 0.5f) * (float)width;
  const float py = (0.5f - c.y * inv_w * 0.5f) * (float)height;
  StScreenVertex v;
  /* rint rounds half to even like convert_int_rte, in one instruction where PoCL emulates the
   * conversion. */
  v.x = convert_int(ST_RINT(px * (float)ST_SUBPIXEL_ONE));
  v.y = convert_int(ST_RINT(py * (float)ST_SUBPIXEL_ONE));
  v.dw = c.z * inv_w;
  v.iw = inv_w;
  return v;
}

/* The transform stage's screen vertex of a clip-space vertex: projected, or marked for the
 * clipping path. */
inline __attribute__((always_inline)) StScreenVertex st_screen_vertex(
    float4 c, __constant StViewConstants* view) {
  const float2 g = st_guard_band(view);
  StScreenVertex v = st_project_vertex(c, view->width, view->height);
  /* Branch-free, so the work-item loop vectorizes. */
  v.x = st_vertex_needs_no_clipping(c, view->near_distance, g.x, g.y) ? v.x : ST_SCREEN_CLIPPED;
  return v;
}

/* Pixel bounds packed as records and binners keep them: x | y << 16 of the top-left pixel,
 * then of the bottom-right one (images are at most ST_MAX_IMAGE_SIDE pixels a side); an empty
 * record has min x > max x (ST_BOUNDS_EMPTY_*). */
inline uint2 st_pack_bounds(int min_x, int min_y, int max_x, int max_y) {
  return (uint2)((uint)min_x | ((uint)min_y << 16), (uint)max_x | ((uint)max_y << 16));
}
/* Packed bounds b as (min x, min y, max x, max y). */
inline int4 st_unpack_bounds(const uint2 b) {
  return (int4)((int)(b.x & 0xFFFFu), (int)(b.x >> 16), (int)(b.y & 0xFFFFu), (int)(b.y >> 16));
}
/* The tiles packed bounds b touch; false for an empty record. */
inline bool st_bounds_tiles(const uint2 b, uint* tx0, uint* tx1, uint* ty0, uint* ty1) {
  const int4 p = st_unpack_bounds(b);
  if (p.x > p.z) return false;
  *tx0 = (uint)p.x >> ST_TILE_LOG2;
  *tx1 = (uint)p.z >> ST_TILE_LOG2;
  *ty0 = (uint)p.y >> ST_TILE_LOG2;
  *ty1 = (uint)p.w >> ST_TILE_LOG2;
  return true;
}

/* Copies record r to global memory a field at a time. A whole-struct copy reads the record as
 * wide vectors, and where its fields were just written one by one into private memory (PoCL's
 * CPU code) those reads wait for the narrow stores to drain: store forwarding fails (a third of
 * the cells setup's time). Field-wide reads forward from the stores. */
inline __attribute__((always_inline)) void st_write_record(__global StTriSetup* dst,
                                                           const StTriSetup* r) {
  dst->corner_x = r->corner_x;
  dst->corner_y = r->corner_y;
  for (int e = 0; e < 2; ++e) {
    dst->edge_a[e] = r->edge_a[e];
    dst->edge_b[e] = r->edge_b[e];
  }
  dst->dw0 = r->dw0;
  dst->dw_dx = r->dw_dx;
  dst->dw_dy = r->dw_dy;
  dst->iw0 = r->iw0;
  dst->iw_dx = r->iw_dx;
  dst->iw_dy = r->iw_dy;
  dst->source = r->source;
  dst->flags = r->flags;
  dst->bounds_min = r->bounds_min;
  dst->bounds_max = r->bounds_max;
}

/* Sets up one triangle of projected, snapped vertices into *out (its depth planes zero unless
 * `planes`). Returns false if it covers no pixel bounds. */
inline __attribute__((always_inline)) bool st_setup_projected(
    StScreenVertex s0, StScreenVertex s1, StScreenVertex s2, const uint source, const bool clipped,
    const bool planes, __constant StViewConstants* view, __global ulong* counters,
    StTriSetup* out) {
  const int width = view->width, height = view->height;
  int vx0 = s0.x, vx1 = s1.x, vx2 = s2.x, vy0 = s0.y, vy1 = s1.y, vy2 = s2.y;
  float dw0 = s0.dw, dw1 = s1.dw, dw2 = s2.dw;
  float iw0 = s0.iw, iw1 = s1.iw, iw2 = s2.iw;
  long area2 = (long)(vx1 - vx0) * (long)(vy2 - vy0) - (long)(vx2 - vx0) * (long)(vy1 - vy0);
  if (area2 == 0) {
    if (!clipped) st_counter_claim(&counters[ST_COUNTER_CULLED_DEGENERATE], 1);
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

  /* Written straight into *out (a local record copied out whole was read back in wide loads
   * right after its narrow stores, a store-forwarding stall on CPUs). Edge e runs from vertex e
   * to vertex e+1: E(p) = (Xb - Xa)(Py - Ya) - (Yb - Ya)(Px - Xa), positive inside. Top-left
   * rule: centres exactly on an edge belong to top or left edges. The edge's constant is not
   * stored: a walk evaluates the edge relative to its first corner (st_edge_at). */
  const int a0 = vy0 - vy1, a1 = vy1 - vy2, a2 = vy2 - vy0;
  const int b0 = vx1 - vx0, b1 = vx2 - vx1, b2 = vx0 - vx2;
  const uint top_left = (st_is_top_left(a0, b0) ? ST_TRI_TOP_LEFT_EDGE0 : 0u) |
                        (st_is_top_left(a1, b1) ? ST_TRI_TOP_LEFT_EDGE0 << 1 : 0u) |
                        (st_is_top_left(a2, b2) ? ST_TRI_TOP_LEFT_EDGE0 << 2 : 0u);
  /* One 16-byte store: st_write_record copies the four edges in one load, which waits for
   * narrower stores to drain (store forwarding fails: setup 20% slower). Its address is the
   * record's plus the offset of edge_a, not edge_a itself: a store of four ints through the
   * two-int array runs past it, and Mesa's rusticl (22.3) kept only its first two lanes. */
  vstore4((int4)(a0, a1, b0, b1), 0,
          (int*)((char*)out + __builtin_offsetof(StTriSetup, edge_a)));
  out->corner_x = vx0;
  out->corner_y = vy0;
  /* Affine planes of d/w and 1/w over the snapped positions, relative to vertex 0. */
  const float inv_one = 1.0f / (float)ST_SUBPIXEL_ONE;
  const float x0 = vx0 * inv_one, y0 = vy0 * inv_one;
  const float dx1 = vx1 * inv_one - x0, dy1 = vy1 * inv_one - y0;
  const float dx2 = vx2 * inv_one - x0, dy2 = vy2 * inv_one - y0;
  if (planes) { /* without: a caller whose frame reads no depth (cells_setup.cl) */
    const float inv_det = 1.0f / ((float)area2 * inv_one * inv_one);
    out->dw0 = dw0;
    out->dw_dx = ((dw1 - dw0) * dy2 - (dw2 - dw0) * dy1) * inv_det;
    out->dw_dy = ((dw2 - dw0) * dx1 - (dw1 - dw0) * dx2) * inv_det;
    out->iw0 = iw0;
    out->iw_dx = ((iw1 - iw0) * dy2 - (iw2 - iw0) * dy1) * inv_det;
    out->iw_dy = ((iw2 - iw0) * dx1 - (iw1 - iw0) * dx2) * inv_det;
  } else {
    out->dw0 = out->dw_dx = out->dw_dy = out->iw0 = out->iw_dx = out->iw_dy = 0.0f;
  }
  out->source = source;
  out->flags = flags | top_left;
  const uint2 packed = st_pack_bounds(min_x, min_y, max_x, max_y);
  out->bounds_min = packed.x;
  out->bounds_max = packed.y;
  return true;
}

/* Projects, snaps and sets up one triangle of clip-space vertices (all in front of the near
 * plane and inside the guard band) into *out. Returns false if it covers no pixel bounds. */
inline bool st_setup_record(float4 c0, float4 c1, float4 c2, const uint source, const bool clipped,
                            __constant StViewConstants* view, __global ulong* counters,
                            StTriSetup* out) {
  /* st_project_vertex on the three corners at once (the same operations per lane, so the same
   * bits), which vectorizes where the transform stage's per-vertex projection is not used. */
  const float3 inv_w = (float3)(1.0f / c0.w, 1.0f / c1.w, 1.0f / c2.w);
  const float3 cx = (float3)(c0.x, c1.x, c2.x), cy = (float3)(c0.y, c1.y, c2.y);
  const float3 px = (cx * inv_w * 0.5f + 0.5f) * (float)view->width;
  const float3 py = (0.5f - cy * inv_w * 0.5f) * (float)view->height;
  const int3 sx = convert_int3(ST_RINT(px * (float)ST_SUBPIXEL_ONE));
  const int3 sy = convert_int3(ST_RINT(py * (float)ST_SUBPIXEL_ONE));
  const float3 dw = (float3)(c0.z, c1.z, c2.z) * inv_w;
  StScreenVertex s0, s1, s2;
  s0.x = sx.x;
  s0.y = sy.x;
  s0.dw = dw.x;
  s0.iw = inv_w.x;
  s1.x = sx.y;
  s1.y = sy.y;
  s1.dw = dw.y;
  s1.iw = inv_w.y;
  s2.x = sx.z;
  s2.y = sy.z;
  s2.dw = dw.z;
  s2.iw = inv_w.z;
  return st_setup_projected(s0, s1, s2, source, clipped, true, view, counters, out);
}

/* Unit normal of a triangle (zero for no area). The shading helpers are always_inline: out of
 * line, PoCL returned their vectors through memory (the shared setup 20% slower on the horse). */
inline __attribute__((always_inline)) float3 st_triangle_normal(float3 p0, float3 p1,
                                                                   float3 p2) {
  const float3 n = cross(p1 - p0, p2 - p0);
  const float len = length(n);
  return len > 0.0f ? n / len : (float3)(0.0f);
}

/* The flat-shaded colour of a triangle of unit normal n: material colour times two-sided
 * diffuse, alpha = opacity. */
inline __attribute__((always_inline)) float4 st_normal_colour(
    float3 n, float4 mat, __constant StViewConstants* view) {
  const float3 light = (float3)(view->light_dir[0], view->light_dir[1], view->light_dir[2]);
  /* mat.w * 1 is exact; not (float4)(mat.xyz * f, mat.w): common.cl */
  const float f = st_diffuse_factor(dot(n, light));
  return mat * (float4)(f, f, f, 1.0f);
}

/* Unit normal of a triangle and its flat-shaded colour; identical to shadeTriangle() on the
 * host. */
inline float4 st_flat_colour(float3 p0, float3 p1, float3 p2, float4 mat,
                             __constant StViewConstants* view, float3* normal) {
  *normal = st_triangle_normal(p0, p1, p2);
  return st_normal_colour(*normal, mat, view);
}

/* Whether a clip-space triangle lies in front of the near plane and inside the guard band, so it
 * needs no clipping (almost every triangle). */
inline bool st_needs_no_clipping(float4 c0, float4 c1, float4 c2, float near_d, float gx,
                                 float gy) {
  const float3 d = (float3)(c0.z, c1.z, c2.z), w = (float3)(c0.w, c1.w, c2.w);
  const float3 x = (float3)(c0.x, c1.x, c2.x), y = (float3)(c0.y, c1.y, c2.y);
  return all(d >= near_d) && all(fabs(x) <= gx * w) && all(fabs(y) <= gy * w);
}

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
  if (!st_corners_finite(c0, c1, c2, counters)) {
    st_store_empty(slot, bounds);
    return;
  }
  /* Clip, then fan-triangulate the polygon; each piece keeps the source triangle's winding. */
  const float2 g = st_guard_band(view);
  float4 poly[ST_MAX_CLIP_VERTS];
  const int count = st_clip_triangle(c0, c1, c2, view->near_distance, g.x, g.y, poly);
  bool own_slot_used = false;
  if (count >= 3) st_counter_claim(&counters[ST_COUNTER_CLIPPED], 1);
  for (int k = 1; k + 1 < count; ++k) {
    if (!st_setup_record(poly[0], poly[k], poly[k + 1], source, true, view, counters, &r)) continue;
    if (!own_slot_used) {
      st_store_record(&r, slot, records, bounds, tile_counts, tiles_x);
      own_slot_used = true;
    } else {
      const ulong extra = st_counter_claim(&counters[ST_COUNTER_SETUP_OVERFLOW], 1);
      if (extra < overflow_capacity)
        st_store_record(&r, triangle_count + (uint)extra, records, bounds, tile_counts, tiles_x);
    }
  }
  if (!own_slot_used) st_store_empty(slot, bounds);
}
