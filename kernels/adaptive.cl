/* adaptive.cl: adaptive transparency (Salvi, Montgomery and Lefohn, "Adaptive Transparency",
 * HPG 2011). Approximate: each pixel's visibility function vis(z), the share of light that
 * reaches depth z, is a step function kept as k nodes (depth, transmittance just behind it).
 * The first walk of the tile inserts every fragment as a node (the nodes behind it darkened by
 * its transmittance); when that makes k + 1 nodes, the node whose removal changes the area
 * under the curve least is removed (its step moves onto the node in front: vis is never
 * overestimated and the total transmittance stays exact). The second walk composites every
 * fragment as its premultiplied colour times vis(its depth), order-independently. Exact while
 * a pixel has at most k fragments (at distinct depths); past that, what is compressed is where
 * the light is absorbed, not how much.
 *
 * The paper builds the function in a resolve over per-pixel lists (or, in its pixel-
 * synchronised form, in the fragment shader under an ordered lock): the compression makes the
 * function depend on the order of insertion. Here each pixel takes its fragments in drawing
 * order in both walks and both forms of the kernel (ST_ORDERED_FRAGMENTS), so no two
 * work-items update one pixel and the forms give the same image bit for bit.
 *
 * Node i of tile pixel p: its transmittance at trans[i * ST_TILE_PIXELS + p], its depth at
 * node_depth[i * ST_TILE_PIXELS + p], for i = 0..k (node k is the spare the insertion uses
 * before compressing); an empty node has depth +inf and the transmittance of the nodes in
 * front, so the last node always holds the pixel's total transmittance. */

#define ADAPTIVE_NODE(table, i, p) (table)[(i)*ST_TILE_PIXELS + (p)]

/* Pixel p's visibility function emptied: vis = 1 everywhere. */
inline void adaptive_clear(__local float* trans, __local float* node_depth, uint k, uint p) {
  for (uint i = 0; i <= k; ++i) {
    ADAPTIVE_NODE(trans, i, p) = 1.0f;
    ADAPTIVE_NODE(node_depth, i, p) = INFINITY;
  }
}

/* Inserts a fragment of transmittance t at view distance `depth` into pixel p's k nodes, then
 * removes one node if that made k + 1 (the paper's compression). Behind nodes of equal depth
 * it is not: it goes in front of them, as a nearer fragment would. */
inline void adaptive_insert(__local float* trans, __local float* node_depth, uint k, uint p,
                            float depth, float t) {
  uint at = 0;
  while (at < k && ADAPTIVE_NODE(node_depth, at, p) < depth) ++at;
  const float in_front = at > 0 ? ADAPTIVE_NODE(trans, at - 1, p) : 1.0f;
  for (uint i = k; i > at; --i) {
    ADAPTIVE_NODE(node_depth, i, p) = ADAPTIVE_NODE(node_depth, i - 1, p);
    ADAPTIVE_NODE(trans, i, p) = ADAPTIVE_NODE(trans, i - 1, p) * t;
  }
  ADAPTIVE_NODE(node_depth, at, p) = depth;
  ADAPTIVE_NODE(trans, at, p) = in_front * t;
  if (ADAPTIVE_NODE(node_depth, k, p) == INFINITY) return; /* an empty node fell off the end */
  /* Removing node i (i >= 1) moves its step onto node i - 1, taking away the area
   * (d_i - d_{i-1}) (T_{i-1} - T_i) under vis; the nearest node is kept. */
  uint removed = 1;
  float least = INFINITY;
  for (uint i = 1; i <= k; ++i) {
    const float area = (ADAPTIVE_NODE(node_depth, i, p) - ADAPTIVE_NODE(node_depth, i - 1, p)) *
                       (ADAPTIVE_NODE(trans, i - 1, p) - ADAPTIVE_NODE(trans, i, p));
    if (area < least) {
      least = area;
      removed = i;
    }
  }
  ADAPTIVE_NODE(trans, removed - 1, p) = ADAPTIVE_NODE(trans, removed, p);
  for (uint i = removed; i < k; ++i) {
    ADAPTIVE_NODE(node_depth, i, p) = ADAPTIVE_NODE(node_depth, i + 1, p);
    ADAPTIVE_NODE(trans, i, p) = ADAPTIVE_NODE(trans, i + 1, p);
  }
  ADAPTIVE_NODE(node_depth, k, p) = INFINITY;
}

/* vis(depth) of pixel p: the transmittance of the last node strictly in front of `depth`. */
inline float adaptive_visibility(__local const float* trans, __local const float* node_depth,
                                 uint k, uint p, float depth) {
  float vis = 1.0f;
  for (uint i = 0; i < k && ADAPTIVE_NODE(node_depth, i, p) < depth; ++i)
    vis = ADAPTIVE_NODE(trans, i, p);
  return vis;
}

/* The first walk: the fragment's transmittance into the visibility function, counted. */
#define ADAPTIVE_BUILD(r, p, px, py, depth)                        \
  do {                                                             \
    const float4 c_ = ST_RECORD_COLOUR(r, px, py);                 \
    adaptive_insert(layer, layer_depth, k, p, depth, 1.0f - c_.w); \
    ++count[p];                                                    \
  } while (0)

/* The second walk: the fragment's premultiplied colour seen through vis(its depth). */
#define ADAPTIVE_COMPOSITE(r, p, px, py, depth)                                   \
  do {                                                                            \
    const float4 c_ = ST_RECORD_COLOUR(r, px, py);                                \
    const float w_ = c_.w * adaptive_visibility(layer, layer_depth, k, p, depth); \
    sum_r[p] += w_ * c_.x;                                                        \
    sum_g[p] += w_ * c_.y;                                                        \
    sum_b[p] += w_ * c_.z;                                                        \
  } while (0)

/* A pixel's resolve: its colour sums, and the total transmittance its last node holds. */
inline float3 adaptive_resolve(__local const float* sum_r, __local const float* sum_g,
                               __local const float* sum_b, __local const float* trans, uint k,
                               uint p, float* t) {
  *t = ADAPTIVE_NODE(trans, k - 1, p);
  return (float3)(sum_r[p], sum_g[p], sum_b[p]);
}
#define ADAPTIVE_RESOLVE(p, t) adaptive_resolve(sum_r, sum_g, sum_b, layer, k, p, t)
#define ADAPTIVE_CLEAR(p)                     \
  do {                                        \
    adaptive_clear(layer, layer_depth, k, p); \
    sum_r[p] = sum_g[p] = sum_b[p] = 0.0f;    \
  } while (0)
/* Two walks: the visibility function built, then every fragment composited through it. */
#define ADAPTIVE_STEPS(WALK, PIXELS) WALK(ADAPTIVE_BUILD) WALK(ADAPTIVE_COMPOSITE)

/* The tile's two walks and its resolve, in either form (tile_walk.cl: one body for a tile
 * kernel's two forms). `layer` and `layer_depth` hold the k + 1 nodes' transmittances and
 * depths per pixel (__local arguments sized by the host); the others are the kernel's __local
 * arrays of ST_TILE_PIXELS (`cover` and `entry` the ordered walk's round). */
inline __attribute__((always_inline)) void adaptive_tile(bool alone, ST_LAYERS_PARAMS,
                                                         __local uint* count, __local uint* scratch,
                                                         __local ulong* cover, __local uint* entry,
                                                         __local float* sum_r, __local float* sum_g,
                                                         __local float* sum_b) {
  ST_ORDERED_TILE(alone, ADAPTIVE_CLEAR, ADAPTIVE_STEPS, ADAPTIVE_RESOLVE);
}

/* adaptive_blend_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define ADAPTIVE_BODY(ALONE)                                                         \
  ST_ORDERED_TILE_TABLES                                                             \
  __local float sum_r[ST_TILE_PIXELS], sum_g[ST_TILE_PIXELS], sum_b[ST_TILE_PIXELS]; \
  adaptive_tile(ALONE, ST_LAYERS_ARGS, count, scratch, cover, entry, sum_r, sum_g, sum_b);
ST_TILE_KERNELS(adaptive_blend_resolve, ST_LAYERS_PARAMS, ADAPTIVE_BODY)
