/* local_layers.cl: each pixel's k nearest fragments so far, as layers sorted by depth in the
 * tile's local memory, for the methods that keep a few of a pixel's fragments while the tile is
 * walked in drawing order (mlab, hybrid).
 *
 * Layer i of tile pixel p: its premultiplied colour and transmittance at
 * layer[(4 * i + c) * ST_TILE_PIXELS + p] for c = 0..3, its depth at
 * layer_depth[i * ST_TILE_PIXELS + p]; an empty layer is (0, 0, 0, 1) at depth +inf. Scalar
 * planes and scalar arithmetic: with float4 tables and swizzles Oclgrind 21.10's
 * uninitialised-value checker crashes, or takes a stored layer for an undefined value. */

/* The arguments of a layered method's tile kernel (engine/frontend/local_layers.h), `layer` and
 * `layer_depth` __local tables of 4 k and k floats per tile pixel. */
#define ST_LAYERS_PARAMS                                                                         \
  __global const StTriSetup *records, __global const uint *bin_entries,                          \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,            \
      const uint k, __global const float4 *triangle_colors,                                      \
      __global const StTexTriangle *tex_tris, __global const uint *atlas,                        \
      __constant StViewConstants *view, __global uchar4 *image, __global ulong *counters,        \
      __global uint *depth_complexity, const int capture_depth_complexity, __local float *layer, \
      __local float *layer_depth
#define ST_LAYERS_ARGS                                                                            \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, k, triangle_colors, tex_tris, atlas, \
      view, image, counters, depth_complexity, capture_depth_complexity, layer, layer_depth

inline float4 st_layer(__local const float* layer, uint i, uint p) {
  __local const float* l = layer + 4 * i * ST_TILE_PIXELS + p;
  return (float4)(l[0], l[ST_TILE_PIXELS], l[2 * ST_TILE_PIXELS], l[3 * ST_TILE_PIXELS]);
}

inline void st_set_layer(__local float* layer, uint i, uint p, float4 v) {
  __local float* l = layer + 4 * i * ST_TILE_PIXELS + p;
  l[0] = v.x;
  l[ST_TILE_PIXELS] = v.y;
  l[2 * ST_TILE_PIXELS] = v.z;
  l[3 * ST_TILE_PIXELS] = v.w;
}

/* Pixel p's k layers emptied. */
inline void st_layers_clear(__local float* layer, __local float* layer_depth, uint k, uint p) {
  for (uint i = 0; i < k; ++i) {
    st_set_layer(layer, i, p, (float4)(0.0f, 0.0f, 0.0f, 1.0f));
    layer_depth[i * ST_TILE_PIXELS + p] = INFINITY;
  }
}

/* A fragment of colour c (straight RGB, opacity c.w) as a layer: premultiplied colour and
 * transmittance. */
inline float4 st_fragment_layer(float4 c) {
  return (float4)(c.x * c.w, c.y * c.w, c.z * c.w, 1.0f - c.w);
}

/* Inserts layer *l at *depth into pixel p's k layers in depth order (behind layers of equal
 * depth, so earlier fragments stay in front) and returns in *l and *depth what falls behind the
 * k-th: the farthest of the k + 1, or an empty layer while fewer than k were taken. */
inline void st_layers_insert(__local float* layer, __local float* layer_depth, uint k, uint p,
                             float4* l, float* depth) {
  uint i = 0;
  while (i < k && layer_depth[i * ST_TILE_PIXELS + p] <= *depth) ++i;
  for (; i < k; ++i) {
    const float4 kept = st_layer(layer, i, p);
    const float kept_depth = layer_depth[i * ST_TILE_PIXELS + p];
    st_set_layer(layer, i, p, *l);
    layer_depth[i * ST_TILE_PIXELS + p] = *depth;
    *l = kept;
    *depth = kept_depth;
  }
}

/* Pixel p's k layers composited front to back: their colour, and in *transmittance what they
 * let through. */
inline float3 st_layers_composite(__local const float* layer, uint k, uint p,
                                  float* transmittance) {
  float3 color = (float3)(0.0f);
  float t = 1.0f;
  for (uint i = 0; i < k; ++i) {
    const float4 l = st_layer(layer, i, p);
    color += t * (float3)(l.x, l.y, l.z);
    t *= l.w;
  }
  *transmittance = t;
  return color;
}
