/* mlab.cl: multi-layer alpha blending (Salvi and Vaidyanathan, "Multi-Layer Alpha Blending",
 * I3D 2014). Approximate: each pixel keeps k layers sorted by depth, each a premultiplied colour,
 * a transmittance and a depth. A fragment is inserted in depth order; when that makes k + 1
 * layers, the last two merge into one: the nearer's depth, its colour plus the farther's seen
 * through it, the product of their transmittances. The resolve composites the k layers front to
 * back over the background. Exact while a pixel has at most k fragments; past that, what merges
 * is composited in arrival order behind the k - 1 nearest layers seen so far.
 *
 * The merge makes the result depend on the order in which a pixel's fragments arrive, so the
 * paper needs fragment-shader interlock (pixel synchronisation) to make each update atomic and
 * ordered. Here each pixel's layers live in the tile's local memory and every pixel takes its
 * fragments in drawing order, in both forms of the kernel: a work-item alone on its tile walks
 * the tile's triangles in order; a work-group walks them in rounds (st_ordered_round: each item
 * covers one triangle, then each item takes the round's triangles in order for its own pixel),
 * so no two work-items ever update one pixel and both forms give the same image bit for bit. */

/* Inserts the fragment of colour `c` (straight RGB, opacity c.w) at view distance `depth` into
 * tile pixel p's k layers (local_layers.cl), merging the last two if all k were taken (merging
 * an empty layer changes nothing). */
inline void mlab_insert(__local float* layer, __local float* layer_depth, uint k, uint p, float4 c,
                        float depth) {
  float4 behind = st_fragment_layer(c);
  st_layers_insert(layer, layer_depth, k, p, &behind, &depth);
  /* The (k + 1)-th layer, behind the k-th: merged into it. */
  const float4 front = st_layer(layer, k - 1, p);
  st_set_layer(layer, k - 1, p,
               (float4)(front.x + front.w * behind.x, front.y + front.w * behind.y,
                        front.z + front.w * behind.z, front.w * behind.w));
}

/* One fragment of the ordered walk: inserted and counted. */
#define MLAB_FRAGMENT(r, p, x, y, depth)                                     \
  do {                                                                       \
    mlab_insert(layer, layer_depth, k, p, ST_RECORD_COLOUR(r, x, y), depth); \
    ++count[p];                                                              \
  } while (0)

/* A pixel's layers emptied; the one walk; a pixel's resolve: its layers composited front to
 * back. */
#define MLAB_CLEAR(p) st_layers_clear(layer, layer_depth, k, p)
#define MLAB_STEPS(WALK, PIXELS) WALK(MLAB_FRAGMENT)
#define MLAB_RESOLVE(p, t) st_layers_composite(layer, k, p, t)

/* The tile's layers, its resolve and its counts, in either form (tile_walk.cl: one body for a
 * tile kernel's two forms). `layer` and `layer_depth` hold 4 k and k floats per pixel (__local
 * arguments sized by the host); the others are the kernel's __local arrays of ST_TILE_PIXELS
 * (`cover` and `entry` the ordered walk's round). */
inline __attribute__((always_inline)) void mlab_tile(bool alone, ST_LAYERS_PARAMS,
                                                     __local uint* count, __local uint* scratch,
                                                     __local ulong* cover, __local uint* entry) {
  ST_ORDERED_TILE(alone, MLAB_CLEAR, MLAB_STEPS, MLAB_RESOLVE);
}

/* mlab_blend_resolve: a work-group per tile; _serial: one work-item alone per tile. */
#define MLAB_BODY(ALONE) \
  ST_ORDERED_TILE_TABLES \
  mlab_tile(ALONE, ST_LAYERS_ARGS, count, scratch, cover, entry);
ST_TILE_KERNELS(mlab_blend_resolve, ST_LAYERS_PARAMS, MLAB_BODY)
