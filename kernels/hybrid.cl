/* hybrid.cl: hybrid transparency (Maule, Comba, Torchelsen and Bastos, "Hybrid Transparency",
 * I3D 2013). Approximate: each pixel keeps its k nearest fragments exactly, sorted by depth (the
 * core, local_layers.cl), and blends the others (the tail) order-independently with the
 * weighted average of Bavoil and Myers (2008): the tail's opacity-weighted mean colour C, its
 * mean opacity a over its n fragments, shown as C (1 - (1 - a)^n) behind the core. A fragment
 * pushed out of the core by a nearer one joins the tail. Exact while a pixel has at most k
 * fragments; past that the tail is an average, whatever its order.
 *
 * The core's eviction is a per-pixel read-modify-write (on a GPU, fragment-shader interlock or
 * a spin lock). Here, as for mlab, each pixel takes its fragments in drawing order in both forms
 * of the kernel (ST_ORDERED_FRAGMENTS), so no two work-items update one pixel and the forms give
 * the same image bit for bit. */

/* The tile's tail sums per pixel: premultiplied colour (r, g, b), opacity, fragment count. */
typedef struct {
  __local float *r, *g, *b, *a;
  __local uint* n;
} HybridTail;

/* One fragment: into the core; what the core pushes out (the farthest of k + 1) into the tail. */
inline void hybrid_fragment(__local float* layer, __local float* layer_depth, uint k, uint p,
                            float4 c, float depth, HybridTail tail) {
  float4 behind = st_fragment_layer(c);
  st_layers_insert(layer, layer_depth, k, p, &behind, &depth);
  if (depth < INFINITY) {
    tail.r[p] += behind.x;
    tail.g[p] += behind.y;
    tail.b[p] += behind.z;
    tail.a[p] += 1.0f - behind.w;
    ++tail.n[p];
  }
}

/* Pixel p's core composited front to back, then its tail behind it. */
inline float3 hybrid_resolve(__local const float* layer, uint k, uint p, HybridTail tail,
                             float* t) {
  float3 color = st_layers_composite(layer, k, p, t);
  st_blend_tail(&color, t, (float3)(tail.r[p], tail.g[p], tail.b[p]), tail.a[p], tail.n[p]);
  return color;
}

/* A pixel's core and tail emptied. */
inline void hybrid_clear(__local float* layer, __local float* layer_depth, uint k, uint p,
                         HybridTail tail) {
  st_layers_clear(layer, layer_depth, k, p);
  tail.r[p] = tail.g[p] = tail.b[p] = tail.a[p] = 0.0f;
  tail.n[p] = 0;
}

#define HYBRID_CLEAR(p) hybrid_clear(layer, layer_depth, k, p, tail)
#define HYBRID_STEPS(WALK, PIXELS) WALK(HYBRID_FRAGMENT)
#define HYBRID_RESOLVE(p, t) hybrid_resolve(layer, k, p, tail, t)

#define HYBRID_FRAGMENT(r, p, x, y, depth)                                             \
  do {                                                                                 \
    hybrid_fragment(layer, layer_depth, k, p, ST_RECORD_COLOUR(r, x, y), depth, tail); \
    ++count[p];                                                                        \
  } while (0)

/* The tile's core and tail, its resolve and its counts, in either form (tile_walk.cl: one body
 * for a tile kernel's two forms). `layer` and `layer_depth` hold 4 k and k floats per pixel
 * (__local arguments sized by the host); `count`, `scratch`, `cover`, `entry` and the tail's
 * tables are the kernel's __local arrays of ST_TILE_PIXELS. */
inline __attribute__((always_inline)) void hybrid_tile(bool alone, ST_LAYERS_PARAMS,
                                                       __local uint* count, __local uint* scratch,
                                                       __local ulong* cover, __local uint* entry,
                                                       HybridTail tail) {
  ST_ORDERED_TILE(alone, HYBRID_CLEAR, HYBRID_STEPS, HYBRID_RESOLVE);
}

/* hybrid_blend_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define HYBRID_BODY(ALONE)                                                              \
  ST_ORDERED_TILE_TABLES                                                                \
  __local float tail_r[ST_TILE_PIXELS], tail_g[ST_TILE_PIXELS], tail_b[ST_TILE_PIXELS]; \
  __local float tail_a[ST_TILE_PIXELS];                                                 \
  __local uint tail_n[ST_TILE_PIXELS];                                                  \
  const HybridTail tail = {tail_r, tail_g, tail_b, tail_a, tail_n};                     \
  hybrid_tile(ALONE, ST_LAYERS_ARGS, count, scratch, cover, entry, tail);
ST_TILE_KERNELS(hybrid_blend_resolve, ST_LAYERS_PARAMS, HYBRID_BODY)
