/* stochastic.cl: stochastic transparency (Enderton, Sintorn, Shirley and Luebke, "Stochastic
 * Transparency", I3D 2010). Approximate, unbiased in expectation: each pixel has S samples,
 * and a fragment of opacity a covers a random subset of them of expected size a S (a stratified
 * count n = floor(a S + u), u uniform), drawn from a hash of the fragment, the pixel and the
 * seed, independently of every other fragment: the first n samples of one of
 * ST_STOCHASTIC_MASK_ROWS random orders of the S samples (the host's table of their prefix
 * masks, as the paper draws from a table of masks), turned by a random rotation, so every sample
 * is covered with probability exactly a. The first walk keeps each sample's nearest covering
 * depth (a depth buffer per sample) and the exact total transmittance prod(1 - a_i); then each
 * pixel with many fragments sorts its samples' depths, and the second walk adds each fragment's
 * premultiplied colour and its opacity times vis, the share of the samples whose nearest depth is
 * not in front of it (a binary search, or a count where the pixel has few fragments), an unbiased
 * estimate of the light that reaches it. The paper's alpha correction then scales the colour to the
 * exact total opacity: C = sum(C_i a_i vis_i) (1 - prod(1 - a_i)) / sum(a_i vis_i), shown over the
 * background through prod(1 - a_i). Without it (alpha_correction = 0) the colour is the plain sum
 * and the background shows through the uncovered samples: the estimator whose expectation is the
 * exact image. Noise falls as 1 / sqrt(S).
 *
 * Both walks commute: the minima and the sums do not depend on the order of a pixel's
 * fragments. Each pixel still takes them in drawing order (ST_ORDERED_FRAGMENTS), so the float
 * sums, and so the image, are the same in both kernel forms and from run to run: a seed gives
 * one image.
 *
 * Sample s of tile pixel p: its nearest covering depth at sample_depth[s * ST_TILE_PIXELS + p]
 * (+inf: uncovered). */

#define STOCHASTIC_PARAMS                                                                 \
  __global const StTriSetup *records, __global const uint *bin_entries,                   \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,     \
      const uint samples, const uint seed, const int alpha_correction,                    \
      __global const ulong *masks, __global const float4 *triangle_colors,                \
      __global const StTexTriangle *tex_tris, __global const uint *atlas,                 \
      __constant StViewConstants *view, __global uchar4 *image, __global ulong *counters, \
      __global uint *depth_complexity, const int capture_depth_complexity,                \
      __local float *sample_depth
#define STOCHASTIC_ARGS                                                                       \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, samples, seed, alpha_correction, \
      masks, triangle_colors, tex_tris, atlas, view, image, counters, depth_complexity,       \
      capture_depth_complexity, sample_depth

/* A 32-bit integer hash with good avalanche (Wellons' "lowbias32"), the generator's step. */
inline uint stochastic_hash(uint v) {
  v = (v ^ (v >> 16)) * 0x7feb352du;
  v = (v ^ (v >> 15)) * 0x846ca68bu;
  return v ^ (v >> 16);
}

/* The next uniform number in [0, 1) of the stream *state. */
inline float stochastic_uniform(uint* state) {
  *state = stochastic_hash(*state + 0x9e3779b9u);
  return (float)(*state >> 8) * (1.0f / 16777216.0f);
}

/* The samples a fragment of opacity a covers: its stream starts from the triangle, the pixel,
 * the fragment's depth (instances of one triangle differ there) and the seed; it gives the count
 * n, the order (a row of `masks`, whose entry n is the mask of that order's first n samples) and
 * the rotation. Keeps each covered sample's nearest depth. */
inline void stochastic_cover(__local float* sample_depth, uint samples, uint seed,
                             __global const ulong* masks, uint p, uint source, int x, int y,
                             float depth, float a) {
  uint state = stochastic_hash(
      seed ^ stochastic_hash(source ^ stochastic_hash((uint)x * 0x10000u + (uint)y ^
                                                      stochastic_hash(as_uint(depth)))));
  const uint taken =
      (uint)min(floor(a * (float)samples + stochastic_uniform(&state)), (float)samples);
  const uint pick = stochastic_hash(state);
  ulong mask = masks[(pick % ST_STOCHASTIC_MASK_ROWS) * (samples + 1) + taken];
  const uint turn = (pick / ST_STOCHASTIC_MASK_ROWS) % samples;
  if (turn != 0) {
    const ulong all = samples == 64 ? ~0ul : (1ul << samples) - 1ul;
    mask = ((mask << turn) | (mask >> (samples - turn))) & all;
  }
  while (mask != 0) {
    const uint s = 63u - (uint)clz(mask & (~mask + 1ul)); /* the lowest covered sample */
    __local float* d = &sample_depth[s * ST_TILE_PIXELS + p];
    *d = fmin(*d, depth);
    mask &= mask - 1ul;
  }
}

/* Pixel p's sample depths in ascending order (insertion sort; S is at most 64). */
inline void stochastic_sort_samples(__local float* sample_depth, uint samples, uint p) {
  for (uint i = 1; i < samples; ++i) {
    const float d = sample_depth[i * ST_TILE_PIXELS + p];
    uint j = i;
    for (; j > 0 && sample_depth[(j - 1) * ST_TILE_PIXELS + p] > d; --j)
      sample_depth[j * ST_TILE_PIXELS + p] = sample_depth[(j - 1) * ST_TILE_PIXELS + p];
    sample_depth[j * ST_TILE_PIXELS + p] = d;
  }
}

/* A pixel with at least this many fragments sorts its sample depths and finds each fragment's
 * vis by binary search; with fewer, counting over the samples per fragment costs less than the
 * sort. The count is the same either way. */
#define STOCHASTIC_SORT_FROM 8u

/* vis of a fragment at `depth`: the share of pixel p's samples whose nearest covering depth is
 * not in front of it (its own samples count: a fragment does not hide itself); `sorted`: the
 * sample depths are in ascending order. */
inline float stochastic_visibility(__local const float* sample_depth, uint samples, uint p,
                                   bool sorted, float depth) {
  uint in_front = 0;
  if (sorted) {
    uint hi = samples; /* in_front becomes the first sample not in front of `depth` */
    while (in_front < hi) {
      const uint mid = (in_front + hi) / 2;
      if (sample_depth[mid * ST_TILE_PIXELS + p] < depth)
        in_front = mid + 1;
      else
        hi = mid;
    }
  } else {
    for (uint s = 0; s < samples; ++s) in_front += sample_depth[s * ST_TILE_PIXELS + p] < depth;
  }
  return (float)(samples - in_front) / (float)samples;
}

/* The first walk: the fragment's samples, its transmittance, its count. */
#define STOCHASTIC_COVER(r, p, px, py, depth)                                                  \
  do {                                                                                         \
    const float4 c_ = ST_RECORD_COLOUR(r, px, py);                                             \
    stochastic_cover(sample_depth, samples, seed, masks, p, (r)->source, px, py, depth, c_.w); \
    total_t[p] *= 1.0f - c_.w;                                                                 \
    ++count[p];                                                                                \
  } while (0)

/* The second walk: the fragment's premultiplied colour and opacity seen through its vis. */
#define STOCHASTIC_COMPOSITE(r, p, px, py, depth)                                           \
  do {                                                                                      \
    const float4 c_ = ST_RECORD_COLOUR(r, px, py);                                          \
    const float w_ = c_.w * stochastic_visibility(sample_depth, samples, p,                 \
                                                  count[p] >= STOCHASTIC_SORT_FROM, depth); \
    sum_r[p] += w_ * c_.x;                                                                  \
    sum_g[p] += w_ * c_.y;                                                                  \
    sum_b[p] += w_ * c_.z;                                                                  \
    sum_a[p] += w_;                                                                         \
  } while (0)

/* A pixel's resolve: with the alpha correction its colour sum scaled to the exact total opacity,
 * the background through the exact transmittance; without, the plain sum, the background through
 * the uncovered samples. */
inline float3 stochastic_resolve(__local const float* sample_depth, uint samples,
                                 int alpha_correction, __local const float* sum_r,
                                 __local const float* sum_g, __local const float* sum_b,
                                 __local const float* sum_a, __local const float* total_t,
                                 __local const uint* count, uint p, float* t) {
  float3 color = (float3)(sum_r[p], sum_g[p], sum_b[p]);
  if (alpha_correction) {
    *t = total_t[p];
    if (sum_a[p] > 0.0f) color *= (1.0f - *t) / sum_a[p];
  } else {
    *t =
        stochastic_visibility(sample_depth, samples, p, count[p] >= STOCHASTIC_SORT_FROM, INFINITY);
  }
  return color;
}
#define STOCHASTIC_RESOLVE(p, t)                                                                   \
  stochastic_resolve(sample_depth, samples, alpha_correction, sum_r, sum_g, sum_b, sum_a, total_t, \
                     count, p, t)

/* A pixel's samples uncovered and its sums emptied. */
#define STOCHASTIC_CLEAR(p)                                                                   \
  do {                                                                                        \
    for (uint s_ = 0; s_ < samples; ++s_) sample_depth[s_ * ST_TILE_PIXELS + (p)] = INFINITY; \
    sum_r[p] = sum_g[p] = sum_b[p] = sum_a[p] = 0.0f;                                         \
    total_t[p] = 1.0f;                                                                        \
  } while (0)
/* Between the walks, a deep pixel's sample depths sorted. */
#define STOCHASTIC_SORT(p) \
  if (count[p] >= STOCHASTIC_SORT_FROM) stochastic_sort_samples(sample_depth, samples, p)
#define STOCHASTIC_STEPS(WALK, PIXELS) \
  WALK(STOCHASTIC_COVER) PIXELS(STOCHASTIC_SORT) WALK(STOCHASTIC_COMPOSITE)

/* The tile's two walks and its resolve, in either form (tile_walk.cl: one body for a tile
 * kernel's two forms). `sample_depth` holds `samples` floats per pixel (a __local argument sized
 * by the host); the others are the kernel's __local arrays of ST_TILE_PIXELS (`cover` and
 * `entry` the ordered walk's round). */
inline __attribute__((always_inline)) void stochastic_tile(
    bool alone, STOCHASTIC_PARAMS, __local uint* count, __local uint* scratch, __local ulong* cover,
    __local uint* entry, __local float* sum_r, __local float* sum_g, __local float* sum_b,
    __local float* sum_a, __local float* total_t) {
  ST_ORDERED_TILE(alone, STOCHASTIC_CLEAR, STOCHASTIC_STEPS, STOCHASTIC_RESOLVE);
}

/* stochastic_cover_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define STOCHASTIC_BODY(ALONE)                                                               \
  ST_ORDERED_TILE_TABLES                                                                     \
  __local float sum_r[ST_TILE_PIXELS], sum_g[ST_TILE_PIXELS], sum_b[ST_TILE_PIXELS];         \
  __local float sum_a[ST_TILE_PIXELS], total_t[ST_TILE_PIXELS];                              \
  stochastic_tile(ALONE, STOCHASTIC_ARGS, count, scratch, cover, entry, sum_r, sum_g, sum_b, \
                  sum_a, total_t);
ST_TILE_KERNELS(stochastic_cover_resolve, STOCHASTIC_PARAMS, STOCHASTIC_BODY)
