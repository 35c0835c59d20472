/* abuffer.cl: FreePipe's A-buffer scheme (ABS; Liu, Huang, Liu and Wu, I3D 2010), a fixed budget
 * of K (depth, triangle id) records per pixel.
 *
 * Step 1 (append): each fragment takes the next record of its pixel through a per-pixel counter
 * and stores its visibility word (depth bits above the triangle id, st_visibility_word) there, in
 * arrival order. Fragments past the K-th of a pixel find no record and are lost; they are counted.
 * Step 2 (resolve): each pixel's records are sorted in a private array (insertion sort by depth,
 * then triangle id) and composited front to back.
 * With tail blending (tail_blend, as NVIDIA's vk_order_independent_transparency sample has it)
 * the fragments past the K-th are not lost but blended into the pixel's tail as they arrive,
 * order-independently (Bavoil and Myers' weighted average, st_blend_tail: the sample blends them
 * in the framebuffer in arrival order, which a work-group here could only do under a per-pixel
 * lock), and the tail is shown behind the K sorted records.
 *
 * Differences from the published method, and why:
 * - The published scheme took each record with one global atomic counter per pixel, contended by
 *   every core that rasterized a fragment of that pixel. Here one work-group owns a screen tile
 *   (DESIGN.md: tile ownership) and the tile's counters live in local memory: the same per-pixel
 *   arrival-order append, without cross-core contention and without global atomics (which cost
 *   about ten stores each on PoCL). The K records per pixel stay in global memory, as published
 *   (K * 64 * 8 bytes per tile can exceed a GPU's local memory), in one contiguous block per tile
 *   (record s of tile pixel p at s * 64 + p, so a work-group's reads of one slot coalesce).
 * - The resolve runs in the same launch as the append, after a barrier, by the work-group that
 *   owns the tile: the records are read back while still in cache and no per-pixel counter has to
 *   go through global memory. The two steps are the published ones; only the launch is shared.
 * - The record holds the triangle id instead of a packed colour (OpenCL has 64-bit atomics and
 *   stores, so nothing is packed); colours come from the triangle colour table at the resolve. */

/* Record s of tile pixel p inside a tile's block of k * ST_TILE_PIXELS records. */
inline uint abuffer_slot(uint s, uint p) { return s * ST_TILE_PIXELS + p; }

/* The tail's sums per tile pixel: premultiplied colour (r, g, b), opacity, fragment count. */
typedef struct {
  __local float *r, *g, *b, *a;
  __local uint* n;
} AbufferTail;

/* Step 2 for tile pixel p at (x, y), inside the image: sorts the pixel's `kept` records in a
 * private array and composites them front to back, then the tail, over the background into the
 * image. */
inline void abuffer_resolve_pixel(__global const ulong* tile_records, uint p, uint kept,
                                  AbufferTail tail, __global const float4* triangle_colors,
                                  __global const StTexTriangle* tex_tris,
                                  __global const uint* atlas, __constant StViewConstants* view,
                                  __global uchar4* image, int x, int y) {
  ulong sorted[ST_MAX_K];
  for (uint i = 0; i < kept; ++i) {
    const ulong w = tile_records[abuffer_slot(i, p)];
    int j = (int)i - 1;
    while (j >= 0 && w < sorted[j]) { /* the word orders by (depth, triangle id) */
      sorted[j + 1] = sorted[j];
      --j;
    }
    sorted[j + 1] = w;
  }
  float3 color = (float3)(0.0f);
  float transmittance = 1.0f;
  for (uint i = 0; i < kept; ++i)
    st_composite_under(
        &color, &transmittance,
        st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)sorted[i], x, y));
  st_blend_tail(&color, &transmittance, (float3)(tail.r[p], tail.g[p], tail.b[p]), tail.a[p],
                tail.n[p]);
  color += transmittance * st_background(view, x, y);
  image[y * view->width + x] = st_pack_rgba8(color);
}

/* Both steps over one tile, in either form (tile_walk.cl: one body for a tile kernel's two
 * forms). In the serial form one work-item owns the whole tile and fragments arrive in drawing
 * order: while no pixel overflows the records are those of the work-group form; past K, each
 * keeps the first K to arrive, as the published scheme does in whatever order its device
 * delivers them (the counts are the same), and the tail takes the others. pixel_count (fragments
 * that arrived at each pixel of the tile), scratch and the tail's tables are the kernel's __local
 * arrays of ST_TILE_PIXELS. */
#define ABUFFER_PARAMS                                                                        \
  __global const StTriSetup *records, __global const uint *bin_entries,                       \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity,         \
      const uint k, __global ulong *fragment_records, __global const float4 *triangle_colors, \
      __global const StTexTriangle *tex_tris, __global const uint *atlas,                     \
      __constant StViewConstants *view, __global uchar4 *image, __global ulong *counters,     \
      __global uint *depth_complexity, const int capture_depth_complexity, const int tail_blend
#define ABUFFER_ARGS                                                                               \
  records, bin_entries, tile_offsets, tiles_x, bin_capacity, k, fragment_records, triangle_colors, \
      tex_tris, atlas, view, image, counters, depth_complexity, capture_depth_complexity,          \
      tail_blend

inline __attribute__((always_inline)) void abuffer_tile(bool alone, ABUFFER_PARAMS,
                                                        __local uint* pixel_count,
                                                        __local uint* scratch, AbufferTail tail) {
  const uint tile = get_group_id(1) * tiles_x + get_group_id(0);
  uint begin, end;
  st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);
  ST_FOR_OWNED_PIXELS(p, alone) {
    pixel_count[p] = tail.n[p] = 0;
    tail.r[p] = tail.g[p] = tail.b[p] = tail.a[p] = 0.0f;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;
  __global ulong* tile_records = fragment_records + (size_t)tile * k * ST_TILE_PIXELS;

  /* Step 1: append every fragment to its pixel's records in arrival order. */
  StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);
  while (st_tile_triangle_next(&f)) {
    while (st_tile_fragment_next(&f)) {
      const uint slot = st_owned_inc_uint(alone, &pixel_count[f.p]);
      if (slot < k) {
        tile_records[abuffer_slot(slot, f.p)] = st_visibility_word(f.depth, f.r->source);
      } else if (tail_blend) {
        const float4 c =
            st_fragment_colour(triangle_colors, tex_tris, atlas, view, f.r->source, f.x, f.y);
        st_owned_add_float(alone, &tail.r[f.p], c.x * c.w);
        st_owned_add_float(alone, &tail.g[f.p], c.y * c.w);
        st_owned_add_float(alone, &tail.b[f.p], c.z * c.w);
        st_owned_add_float(alone, &tail.a[f.p], c.w);
        st_owned_inc_uint(alone, &tail.n[f.p]);
      }
    }
  }
  barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);

  /* Step 2: sort each pixel's records and composite them front to back. */
  uint fragments = 0, lost = 0, deepest = 0;
  ST_FOR_OWNED_PIXELS(p, alone) {
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    const uint arrived = pixel_count[p];
    const uint kept = min(arrived, k);
    if (x < view->width && y < view->height) {
      abuffer_resolve_pixel(tile_records, p, kept, tail, triangle_colors, tex_tris, atlas, view,
                            image, x, y);
      if (capture_depth_complexity) depth_complexity[y * view->width + x] = arrived;
    }
    fragments += arrived;
    if (!tail_blend) lost += arrived - kept;
    deepest = max(deepest, arrived);
  }
  st_report_owned_counts(alone, scratch, counters, fragments, deepest, lost);
}

/* abuffer_raster_resolve: a work-group per tile; _serial (for a CPU device): one work-item owns
 * a whole tile, alone. */
#define ABUFFER_BODY(ALONE)                                                                  \
  __local uint pixel_count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS], tail_n[ST_TILE_PIXELS]; \
  __local float tail_r[ST_TILE_PIXELS], tail_g[ST_TILE_PIXELS], tail_b[ST_TILE_PIXELS];      \
  __local float tail_a[ST_TILE_PIXELS];                                                      \
  const AbufferTail tail = {tail_r, tail_g, tail_b, tail_a, tail_n};                         \
  abuffer_tile(ALONE, ABUFFER_ARGS, pixel_count, scratch, tail);
ST_TILE_KERNELS(abuffer_raster_resolve, ABUFFER_PARAMS, ABUFFER_BODY)
