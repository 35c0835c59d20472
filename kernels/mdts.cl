/* mdts.cl: FreePipe's multi-depth test scheme (MDTS; Liu, Huang, Liu and Wu, I3D 2010): K slots
 * per pixel kept sorted by an atomic-min insertion chain.
 *
 * A fragment atom_min's its word into slot 0; whichever of the two words is larger (the displaced
 * old value, or the fragment itself when it lost) carries on into slot 1, and so on until a carry
 * lands in an empty slot or falls off the end of the array, where it is lost (and counted). Slots
 * only ever decrease, every value entering slot s+1 has passed slot s, so at the end the slots
 * hold the K nearest words of the pixel in increasing order whatever the order of arrival, and
 * every lost word is farther than every kept one. The resolve walks them front to back: no sort.
 *
 * Two word formats:
 * - mdts:   64 bits, full float depth above the 32-bit triangle id (st_visibility_word), so ties
 *           break by the lower id as everywhere, and the result is exact while K >= depth.
 * - mdts32: the published format, one 32-bit word holding a quantised depth above the fragment's
 *           colour, for 32-bit atomic_min (CUDA had no 64-bit atomics then). The depth is what a
 *           z-buffer holds: z = 1 - near / d (the perspective depth of a projection with the
 *           camera's near plane and the far plane at infinity, in [0, 1)), truncated to the high
 *           D = min(24, 32 - id_bits) bits. The low bits hold the colour as an index into the
 *           frame's triangle colour table, which needs id_bits = bits(triangle count) bits (at
 *           least 8). That is the published 24-bit depth + 8-bit colour for scenes of fewer than
 *           256 triangles; larger scenes keep the colour exact and give the depth fewer bits
 *           (15 for horse.ply, 10 for builtin:spheres:32). Fragments whose depths fall in one
 *           quantisation step are ordered by triangle id instead of depth: that is the method's
 *           precision loss (as with any z-buffer it grows with distance over the near plane), and
 *           its error against the reference is its result. One pass, no depth-range pre-pass.
 *
 * Where the slots live (chosen by the host from CL_DEVICE_LOCAL_MEM_SIZE):
 * - local memory (K * 64 * word bytes per work-group): one work-group owns a tile (DESIGN.md), so
 *   the chain's atomics stay in the tile's local memory and the resolve follows in the same launch;
 * - global memory, when K is too large for the device's local memory: the published layout, one
 *   fixed array of K words per pixel in global memory (tile-contiguous blocks, slot s of tile
 *   pixel p at s * 64 + p), each tile clearing its own block first, with global atomics.
 * The published method used global memory with contended atomics for every fragment; the chain
 * itself is the same in both placements. */

#define MDTS32_EMPTY 0xFFFFFFFFu

/* ---- The insertion chain, one copy per address space and word size (OpenCL C 1.2 has no
 * generic address space). `slot0` is slot 0 of the pixel; slots are ST_TILE_PIXELS apart.
 * Returns 1 when a word fell off the end (a lost fragment), else 0.
 * A plain read before each atomic skips the slots that already hold a nearer word: slots only
 * ever decrease, so atom_min there would change nothing and the carried word stays the same
 * (DESIGN.md: testing before the atomic helps when most fragments lose). For the same reason a
 * fragment behind a full pixel's last slot is lost at once. The slots at the end are the ones the
 * published chain (an atomic at every slot from slot 0) leaves. Starting the chain at a slot found
 * by binary search was measured too: about 3% slower on horse and spheres:32. */
#define MDTS_DEFINE_INSERT(NAME, SPACE, WORD, EMPTY, ATOMIC_MIN)       \
  inline uint NAME(SPACE WORD* slot0, uint k, WORD v) {                \
    if (slot0[(k - 1) * ST_TILE_PIXELS] < v) return 1;                 \
    for (uint s = 0; s < k; ++s) {                                     \
      SPACE WORD* a = slot0 + s * ST_TILE_PIXELS;                      \
      if (*a < v) continue;                                            \
      const WORD old = ATOMIC_MIN(a, v);                               \
      if (old == EMPTY) return 0;                                      \
      v = max(old, v);                                                 \
    }                                                                  \
    return 1;                                                          \
  }

MDTS_DEFINE_INSERT(mdts_insert_local, __local, ulong, ST_VISIBILITY_EMPTY, atom_min)
MDTS_DEFINE_INSERT(mdts_insert_global, __global, ulong, ST_VISIBILITY_EMPTY, atom_min)
MDTS_DEFINE_INSERT(mdts32_insert_local, __local, uint, MDTS32_EMPTY, atomic_min)
MDTS_DEFINE_INSERT(mdts32_insert_global, __global, uint, MDTS32_EMPTY, atomic_min)

/* Reports lost fragments (one atomic per group) and writes the depth-complexity map. */
inline void mdts_report(__local uint* scratch, __global ulong* counters, uint lost, uint arrived,
                        bool inside, int x, int y, int width, __global uint* depth_complexity,
                        int capture_depth_complexity) {
  if (inside && capture_depth_complexity) depth_complexity[y * width + x] = arrived;
  const uint group_lost = st_group_sum(scratch, lost);
  if (st_local_index() == 0 && group_lost)
    atom_add(&counters[ST_COUNTER_FRAGMENTS_LOST], (ulong)group_lost);
  st_report_tile_counts(scratch, counters, arrived, arrived);
}

/* ---- mdts: 64-bit (float depth, triangle id) words. ---- */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void mdts_raster_resolve(__global const StTriSetup* records, __global const uint* bin_entries,
                         __global const uint* tile_offsets, const uint tiles_x,
                         const uint bin_capacity, const uint k, const int use_global_slots,
                         __local ulong* local_slots, __global ulong* global_slots,
                         __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,
                 __global const uint* atlas,
                         __constant StViewConstants* view, __global uchar4* image,
                         __global ulong* counters, __global uint* depth_complexity,
                         const int capture_depth_complexity) {
  __local uint pixel_count[ST_TILE_PIXELS];
  __local uint scratch[ST_TILE_PIXELS];
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  /* A tile without triangles needs no slots. (Not an early return, though the test is uniform
   * over the work-group: with one, PoCL 3.1 reported a wrong group maximum after the barriers.) */
  const uint used_k = begin < end ? k : 0;
  const uint lid = st_local_index();
  const uint tile = get_group_id(1) * tiles_x + get_group_id(0);
  __global ulong* tile_global = global_slots + (size_t)tile * k * ST_TILE_PIXELS;
  /* Clear the tile's slots: each work-item its own pixel's K. */
  if (use_global_slots)
    for (uint s = 0; s < used_k; ++s) tile_global[s * ST_TILE_PIXELS + lid] = ST_VISIBILITY_EMPTY;
  else
    for (uint s = 0; s < used_k; ++s) local_slots[s * ST_TILE_PIXELS + lid] = ST_VISIBILITY_EMPTY;
  pixel_count[lid] = 0;
  barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;

  /* Insert every fragment through the atomic-min chain of its pixel. */
  uint lost = 0;
  ST_FOR_EACH_TILE_FRAGMENT(records, bin_entries, begin, end, tx, ty, r, x, y, p, depth) {
    const ulong word = st_visibility_word(depth, r->source);
    lost += use_global_slots ? mdts_insert_global(tile_global + p, k, word)
                             : mdts_insert_local(local_slots + p, k, word);
    atomic_inc(&pixel_count[p]);
  }
  barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);

  /* Resolve: the slots are already in front-to-back order; stop at the first empty one. */
  const int x = get_global_id(0), y = get_global_id(1);
  const bool inside = x < view->width && y < view->height;
  if (inside) {
    float3 color = (float3)(0.0f);
    float transmittance = 1.0f;
    for (uint s = 0; s < used_k; ++s) {
      const ulong w = use_global_slots ? tile_global[s * ST_TILE_PIXELS + lid]
                                       : local_slots[s * ST_TILE_PIXELS + lid];
      if (w == ST_VISIBILITY_EMPTY) break;
      st_composite_under(&color, &transmittance, st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)w, x, y));
    }
    color += transmittance * st_background(view, x, y);
    image[y * view->width + x] = st_pack_rgba8(color);
  }
  mdts_report(scratch, counters, lost, pixel_count[lid], inside, x, y, view->width,
              depth_complexity, capture_depth_complexity);
}

/* ---- mdts32: one 32-bit word, quantised depth above the colour index (see the top). ---- */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void mdts32_raster_resolve(__global const StTriSetup* records, __global const uint* bin_entries,
                           __global const uint* tile_offsets, const uint tiles_x,
                           const uint bin_capacity, const uint k, const uint depth_bits,
                           const int use_global_slots, __local uint* local_slots,
                           __global uint* global_slots, __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,
                 __global const uint* atlas,
                           __constant StViewConstants* view, __global uchar4* image,
                           __global ulong* counters, __global uint* depth_complexity,
                           const int capture_depth_complexity) {
  __local uint pixel_count[ST_TILE_PIXELS];
  __local uint scratch[ST_TILE_PIXELS];
  uint begin, end;
  st_tile_range(tile_offsets, tiles_x, bin_capacity, &begin, &end);
  /* A tile without triangles needs no slots. (Not an early return, though the test is uniform
   * over the work-group: with one, PoCL 3.1 reported a wrong group maximum after the barriers.) */
  const uint used_k = begin < end ? k : 0;
  const uint lid = st_local_index();
  const uint tile = get_group_id(1) * tiles_x + get_group_id(0);
  __global uint* tile_global = global_slots + (size_t)tile * k * ST_TILE_PIXELS;
  if (use_global_slots)
    for (uint s = 0; s < used_k; ++s) tile_global[s * ST_TILE_PIXELS + lid] = MDTS32_EMPTY;
  else
    for (uint s = 0; s < used_k; ++s) local_slots[s * ST_TILE_PIXELS + lid] = MDTS32_EMPTY;
  pixel_count[lid] = 0;
  barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);
  const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE;

  /* z-buffer depth with the far plane at infinity: z = 1 - near / d in [0, 1), D bits. */
  const float near_plane = view->near_distance;
  const uint id_shift = 32u - depth_bits;
  const uint max_level = (1u << depth_bits) - 1u;
  const float levels = (float)(1u << depth_bits);

  /* Insert every fragment's packed word through the chain. */
  uint lost = 0;
  ST_FOR_EACH_TILE_FRAGMENT(records, bin_entries, begin, end, tx, ty, r, x, y, p, depth) {
    const float z = 1.0f - near_plane / fmax(depth, near_plane);
    const uint q = min((uint)(z * levels), max_level);
    const uint word = (q << id_shift) | r->source;
    lost += use_global_slots ? mdts32_insert_global(tile_global + p, k, word)
                             : mdts32_insert_local(local_slots + p, k, word);
    atomic_inc(&pixel_count[p]);
  }
  barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);

  const int x = get_global_id(0), y = get_global_id(1);
  const bool inside = x < view->width && y < view->height;
  if (inside) {
    const uint id_mask = (1u << id_shift) - 1u;
    float3 color = (float3)(0.0f);
    float transmittance = 1.0f;
    for (uint s = 0; s < used_k; ++s) {
      const uint w = use_global_slots ? tile_global[s * ST_TILE_PIXELS + lid]
                                      : local_slots[s * ST_TILE_PIXELS + lid];
      if (w == MDTS32_EMPTY) break;
      st_composite_under(&color, &transmittance, st_fragment_colour(triangle_colors, tex_tris, atlas, view, w & id_mask, x, y));
    }
    color += transmittance * st_background(view, x, y);
    image[y * view->width + x] = st_pack_rgba8(color);
  }
  mdts_report(scratch, counters, lost, pixel_count[lid], inside, x, y, view->width,
              depth_complexity, capture_depth_complexity);
}
