/* mboit.cl: moment-based order-independent transparency (Münstermann, Krumpen, Klein and
 * Peters, "Moment-Based Order-Independent Transparency", I3D 2018), with four power moments.
 * Approximate, two additive passes: the first sums each pixel's optical depth
 * b0 = sum(-ln(1 - a_i)) and its moments b_j = sum(-ln(1 - a_i) z_i^j), j = 1..4, over the
 * fragments' warped depths z_i; the second reconstructs from them a bound of the transmittance
 * in front of each fragment (Hamburger's four-moment problem, as in Peters and Klein's moment
 * shadow mapping, with the paper's bias 5e-7 towards (0, 0.375, 0, 0.375) and overestimation
 * 0.25), and sums each fragment's premultiplied colour and its opacity through it. The colour is
 * then scaled to the exact total opacity 1 - exp(-b0), which also shows the background.
 *
 * The depth warp: the paper maps log(view depth) between the near and far planes onto [-1, 1].
 * strata has no far plane, and float moments lose precision when a pixel's depths crowd one end
 * of the range, so a first walk takes each pixel's nearest and farthest fragment and the warp
 * maps log depth between those two onto [-1, 1] (a pixel whose fragments share one depth maps
 * them to 0). Three walks of the tile, each in drawing order in both kernel forms
 * (ST_ORDERED_FRAGMENTS), so the float sums, and the image, are the same in both. */

#define MBOIT_BIAS 5e-7f           /* the paper's bias for four power moments in 32-bit floats */
#define MBOIT_OVERESTIMATION 0.25f /* the paper's overestimation weight */
#define MBOIT_MAX_OPACITY 0.9999f  /* a finite optical depth for opaque fragments */

/* Pixel p's warped depth of a fragment at view distance `depth`. */
inline float mboit_warp(__local const float* near_log, __local const float* far_log, uint p,
                        float depth) {
  const float lo = near_log[p], span = far_log[p] - lo;
  return span > 0.0f ? clamp(2.0f * (log(depth) - lo) / span - 1.0f, -1.0f, 1.0f) : 0.0f;
}

/* The transmittance in front of warped depth z from the optical depth b0 and the normalised
 * power moments b = (b1, b2, b3, b4) / b0 (Peters and Klein's Hamburger 4MSM: a Cholesky
 * factorisation of the biased Hankel matrix, the two other support points of the bound's
 * quadrature, and the absorbance as the weights of those in front of z). */
inline float mboit_transmittance(float b0, float4 b, float z) {
  b = mix(b, (float4)(0.0f, 0.375f, 0.0f, 0.375f), MBOIT_BIAS);
  const float l21d11 = fma(-b.x, b.y, b.z);
  const float d11 = fma(-b.x, b.x, b.y);
  const float inv_d11 = 1.0f / d11;
  const float l21 = l21d11 * inv_d11;
  const float squared_depth_variance = fma(-b.y, b.y, b.w);
  const float d22 = fma(-l21d11, l21, squared_depth_variance);
  /* Solve the Hankel system for the polynomial whose roots are the other support points. */
  float c0 = 1.0f, c1 = z, c2 = z * z;
  c1 -= b.x;
  c2 -= b.y + l21 * c1;
  c1 *= inv_d11;
  c2 *= d11 / d22;
  c1 -= l21 * c2;
  c0 -= c1 * b.x + c2 * b.y;
  const float inv_c2 = 1.0f / c2;
  const float pp = c1 * inv_c2, q = c0 * inv_c2;
  const float r = sqrt(fmax(pp * pp * 0.25f - q, 0.0f));
  const float z1 = -pp * 0.5f - r, z2 = -pp * 0.5f + r;
  /* The weights of the support points in front of z (z itself with the overestimation). */
  const float f0 = MBOIT_OVERESTIMATION, f1 = z1 < z ? 1.0f : 0.0f, f2 = z2 < z ? 1.0f : 0.0f;
  const float f01 = (f1 - f0) / (z1 - z);
  const float f12 = (f2 - f1) / (z2 - z1);
  const float f012 = (f12 - f01) / (z2 - z);
  float poly0 = f01 - f012 * z1;
  const float poly2 = f012;
  const float poly1 = poly0 - f012 * z;
  poly0 = f0 - poly0 * z;
  const float absorbance = poly0 + b.x * poly1 + b.y * poly2;
  const float t = exp(-b0 * absorbance);
  return isfinite(t) ? clamp(t, 0.0f, 1.0f) : 1.0f;
}

/* The tile's per-pixel tables (__local arrays of ST_TILE_PIXELS): the log depth range, the
 * optical depth and four moments, the colour and opacity sums. */
typedef struct {
  __local float *near_log, *far_log;
  __local float *b0, *b1, *b2, *b3, *b4;
  __local float *r, *g, *b, *a;
} MboitTables;

/* The first walk: each pixel's log depth range, and its fragments counted. */
#define MBOIT_RANGE(rec, p, px, py, depth)   \
  do {                                       \
    const float l_ = log(depth);             \
    t.near_log[p] = fmin(t.near_log[p], l_); \
    t.far_log[p] = fmax(t.far_log[p], l_);   \
    ++count[p];                              \
  } while (0)

/* The second walk: the fragment's optical depth and its moments. */
#define MBOIT_MOMENTS(rec, p, px, py, depth)                                     \
  do {                                                                           \
    const float4 c_ = ST_RECORD_COLOUR(rec, px, py);                             \
    const float k_ = -log(1.0f - fmin(c_.w, MBOIT_MAX_OPACITY));                 \
    const float z_ = mboit_warp(t.near_log, t.far_log, p, depth), z2_ = z_ * z_; \
    t.b0[p] += k_;                                                               \
    t.b1[p] += k_ * z_;                                                          \
    t.b2[p] += k_ * z2_;                                                         \
    t.b3[p] += k_ * z2_ * z_;                                                    \
    t.b4[p] += k_ * z2_ * z2_;                                                   \
  } while (0)

/* The third walk: the fragment's premultiplied colour and opacity through the transmittance
 * the moments bound in front of it. */
#define MBOIT_COMPOSITE(rec, p, px, py, depth)                                              \
  do {                                                                                      \
    const float4 c_ = ST_RECORD_COLOUR(rec, px, py);                                        \
    const float b0_ = t.b0[p];                                                              \
    const float w_ =                                                                        \
        c_.w * mboit_transmittance(b0_, (float4)(t.b1[p], t.b2[p], t.b3[p], t.b4[p]) / b0_, \
                                   mboit_warp(t.near_log, t.far_log, p, depth));            \
    t.r[p] += w_ * c_.x;                                                                    \
    t.g[p] += w_ * c_.y;                                                                    \
    t.b[p] += w_ * c_.z;                                                                    \
    t.a[p] += w_;                                                                           \
  } while (0)

/* A pixel's resolve: its colour sum scaled to the exact total opacity 1 - exp(-b0). */
inline float3 mboit_resolve(MboitTables tables, uint p, float* t) {
  *t = exp(-tables.b0[p]);
  float3 color = (float3)(tables.r[p], tables.g[p], tables.b[p]);
  if (tables.a[p] > 0.0f) color *= (1.0f - *t) / tables.a[p];
  return color;
}
#define MBOIT_RESOLVE(p, t_out) mboit_resolve(t, p, t_out)

#define MBOIT_CLEAR(p)                                      \
  do {                                                      \
    t.near_log[p] = INFINITY;                               \
    t.far_log[p] = -INFINITY;                               \
    t.b0[p] = t.b1[p] = t.b2[p] = t.b3[p] = t.b4[p] = 0.0f; \
    t.r[p] = t.g[p] = t.b[p] = t.a[p] = 0.0f;               \
  } while (0)
/* Three walks: each pixel's depth range, its moments, its fragments composited. */
#define MBOIT_STEPS(WALK, PIXELS) WALK(MBOIT_RANGE) WALK(MBOIT_MOMENTS) WALK(MBOIT_COMPOSITE)

/* The tile's three walks and its resolve, in either form (tile_walk.cl: one body for a tile
 * kernel's two forms). */
inline __attribute__((always_inline)) void mboit_tile(bool alone, ST_TILE_RESOLVE_PARAMS,
                                                      __local uint* count, __local uint* scratch,
                                                      __local ulong* cover, __local uint* entry,
                                                      MboitTables t) {
  ST_ORDERED_TILE(alone, MBOIT_CLEAR, MBOIT_STEPS, MBOIT_RESOLVE);
}

/* mboit_moments_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define MBOIT_BODY(ALONE)                                                                    \
  ST_ORDERED_TILE_TABLES                                                                     \
  __local float near_log[ST_TILE_PIXELS], far_log[ST_TILE_PIXELS];                           \
  __local float b0[ST_TILE_PIXELS], b1[ST_TILE_PIXELS], b2[ST_TILE_PIXELS];                  \
  __local float b3[ST_TILE_PIXELS], b4[ST_TILE_PIXELS];                                      \
  __local float sum_r[ST_TILE_PIXELS], sum_g[ST_TILE_PIXELS], sum_b[ST_TILE_PIXELS];         \
  __local float sum_a[ST_TILE_PIXELS];                                                       \
  const MboitTables t = {near_log, far_log, b0, b1, b2, b3, b4, sum_r, sum_g, sum_b, sum_a}; \
  mboit_tile(ALONE, ST_TILE_RESOLVE_ARGS, count, scratch, cover, entry, t);
ST_TILE_KERNELS(mboit_moments_resolve, ST_TILE_RESOLVE_PARAMS, MBOIT_BODY)
