/* wboit.cl: weighted blended order-independent transparency (McGuire and Bavoil, "Weighted
 * Blended Order-Independent Transparency", JCGT 2(2), 2013). Approximate: fragments are not
 * sorted. Each pixel sums, over its fragments i of colour C_i and opacity a_i at view distance
 * z_i, the weighted premultiplied colour sum(C_i a_i w_i), the weighted coverage sum(a_i w_i),
 * with w_i = w(z_i, a_i), and the revealage prod(1 - a_i), then shows
 *   sum(C a w) / clamp(sum(a w), 1e-4, 5e4) * (1 - revealage) + background * revealage.
 * The revealage is exact; the colour is a weighted average, exact where a pixel's fragments
 * share one colour or where one fragment covers it.
 *
 * The weight w(z, a) is one of the paper's equations (7) to (10) (WboitWeight): (7) to (9) of
 * the view distance z, in the scene's units as the paper has it, (10) of the depth-buffer value
 * d, here d = 1 - near / z, the value of a perspective depth buffer whose far plane is at
 * infinity: nearer fragments weigh more, independently of the scene's units.
 *
 * The paper's sums are additive blending in a framebuffer. Here one work-group owns a screen
 * tile (DESIGN.md) and keeps the tile's sums in local memory; in the work-group form its
 * work-items add with compare-and-swap loops on the float words (OpenCL 1.2 has no float atomic
 * add), so the order of a pixel's additions, and so its last bits, may vary from run to run on
 * a GPU; alone on its tile a work-item adds in drawing order. */

/* The paper's w(z, a) of a fragment of opacity a at view distance z, by its equation `weight`. */
inline float wboit_weight(int weight, float a, float z, float near_distance) {
  float w;
  if (weight == ST_WBOIT_EQ7) {
    const float s = z / 5.0f, t = z / 200.0f;
    w = 10.0f / (1e-5f + s * s + t * t * t * t * t * t);
  } else if (weight == ST_WBOIT_EQ8) {
    const float s = z / 10.0f, t = z / 200.0f;
    w = 10.0f / (1e-5f + s * s * s + t * t * t * t * t * t);
  } else if (weight == ST_WBOIT_EQ9) {
    const float t = z / 200.0f;
    w = 0.03f / (1e-5f + t * t * t * t);
  } else {
    const float reach = near_distance / fmax(z, near_distance); /* 1 - d */
    w = 3e3f * reach * reach * reach;
  }
  return a * clamp(w, 1e-2f, 3e3f);
}

#define WBOIT_PARAMS ST_TILE_RESOLVE_PARAMS, const int weight
#define WBOIT_ARGS ST_TILE_RESOLVE_ARGS, weight

/* A pixel's resolve: the weighted average colour over the coverage the revealage leaves. */
inline float3 wboit_resolve(__local const float* sum_r, __local const float* sum_g,
                            __local const float* sum_b, __local const float* sum_a,
                            __local const float* reveal, uint p, float* t) {
  *t = reveal[p];
  const float3 average =
      (float3)(sum_r[p], sum_g[p], sum_b[p]) / clamp(sum_a[p], 1e-4f, 5e4f);
  return average * (1.0f - *t);
}
#define WBOIT_RESOLVE(p, t) wboit_resolve(sum_r, sum_g, sum_b, sum_a, reveal, p, t)

/* The tile's sums, its resolve and its counts, in either form (tile_walk.cl: one body for a tile
 * kernel's two forms). The tables are the kernel's __local arrays of ST_TILE_PIXELS: the
 * weighted colour (r, g, b) and coverage sums, the revealage and the fragment count. */
inline __attribute__((always_inline)) void wboit_tile(bool alone, WBOIT_PARAMS,
                                                      __local float* sum_r, __local float* sum_g,
                                                      __local float* sum_b, __local float* sum_a,
                                                      __local float* reveal, __local uint* count,
                                                      __local uint* scratch) {
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  ST_FOR_OWNED_PIXELS(p, alone) {
    sum_r[p] = sum_g[p] = sum_b[p] = sum_a[p] = 0.0f;
    reveal[p] = 1.0f;
    count[p] = 0;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  const float near_distance = view->near_distance;

  StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const float4 c =
          st_fragment_colour(triangle_colors, tex_tris, atlas, view, f.r->source, f.x, f.y);
      /* C_i w(z_i, a_i) with C_i premultiplied, and a_i w(z_i, a_i): the paper's equation (6) */
      const float aw = c.w * wboit_weight(weight, c.w, f.depth, near_distance);
      st_owned_add_float(alone, &sum_r[f.p], c.x * aw);
      st_owned_add_float(alone, &sum_g[f.p], c.y * aw);
      st_owned_add_float(alone, &sum_b[f.p], c.z * aw);
      st_owned_add_float(alone, &sum_a[f.p], aw);
      st_owned_mul_float(alone, &reveal[f.p], 1.0f - c.w);
      st_owned_inc_uint(alone, &count[f.p]);
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE);

  ST_RESOLVE_OWNED_PIXELS(alone, tx, ty, count, scratch, WBOIT_RESOLVE);
}

/* wboit_accumulate_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define WBOIT_BODY(ALONE)                                                                         \
  __local float sum_r[ST_TILE_PIXELS], sum_g[ST_TILE_PIXELS], sum_b[ST_TILE_PIXELS];              \
  __local float sum_a[ST_TILE_PIXELS], reveal[ST_TILE_PIXELS];                                    \
  __local uint count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS];                                    \
  wboit_tile(ALONE, WBOIT_ARGS, sum_r, sum_g, sum_b, sum_a, reveal, count, scratch);
ST_TILE_KERNELS(wboit_accumulate_resolve, WBOIT_PARAMS, WBOIT_BODY)
