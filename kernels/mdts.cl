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

/* ---- Word formats. ----
 * mdts32's quantisation: z = 1 - near / d in [0, 1) with D = depth_bits bits, above a colour
 * index of id_shift = 32 - D bits. mdts ignores it. */
typedef struct {
  float near_plane;
  float levels;   /* 2^D */
  uint max_level; /* 2^D - 1 */
  uint id_shift;
} MdtsFormat;

inline ulong mdts_word_ulong(const MdtsFormat* format, float depth, uint source) {
  return st_visibility_word(depth, source);
}

inline uint mdts_source_ulong(const MdtsFormat* format, ulong w) { return (uint)w; }

inline uint mdts_word_uint(const MdtsFormat* format, float depth, uint source) {
  const float z = 1.0f - format->near_plane / fmax(depth, format->near_plane);
  const uint q = min((uint)(z * format->levels), format->max_level);
  return (q << format->id_shift) | source;
}

inline uint mdts_source_uint(const MdtsFormat* format, uint w) {
  return w & ((1u << format->id_shift) - 1u);
}

/* ---- A pixel's slots, one copy per address space and word size (OpenCL C 1.2 has no generic
 * address space). `slot0` is slot 0 of the pixel; slots are ST_TILE_PIXELS apart.
 * mdts_insert_* runs the insertion chain; it returns 1 when a word fell off the end (a lost
 * fragment), else 0. It is the published chain, an atomic at every slot from slot 0, after one
 * look at the last slot: a fragment behind a full pixel's last word is lost at once. That look is
 * an atomic too (atom_min with EMPTY changes nothing): a plain read of a slot, as a test before
 * each atomic, would race with other work-items' atomics on it.
 * mdts_composite_* composites the kept words front to back, up to the first empty slot. */
#define MDTS_DEFINE_SLOTS(NAME, SPACE, WORD, EMPTY, ATOMIC_MIN)                                   \
  inline void mdts_clear_##NAME(SPACE WORD* slot0, uint k) {                                      \
    for (uint s = 0; s < k; ++s) slot0[s * ST_TILE_PIXELS] = EMPTY;                               \
  }                                                                                               \
  inline uint mdts_insert_##NAME(SPACE WORD* slot0, uint k, WORD v) {                             \
    if (ATOMIC_MIN(slot0 + (k - 1) * ST_TILE_PIXELS, EMPTY) < v) return 1;                        \
    for (uint s = 0; s < k; ++s) {                                                                \
      const WORD old = ATOMIC_MIN(slot0 + s * ST_TILE_PIXELS, v);                                 \
      if (old == EMPTY) return 0;                                                                 \
      v = max(old, v);                                                                            \
    }                                                                                             \
    return 1;                                                                                     \
  }                                                                                               \
  inline void mdts_composite_##NAME(SPACE const WORD* slot0, uint k, const MdtsFormat* format,    \
                                    __global const float4* triangle_colors,                       \
                                    __global const StTexTriangle* tex_tris,                       \
                                    __global const uint* atlas, __constant StViewConstants* view, \
                                    int x, int y, float3* color, float* transmittance) {          \
    for (uint s = 0; s < k; ++s) {                                                                \
      const WORD w = slot0[s * ST_TILE_PIXELS];                                                   \
      if (w == EMPTY) break;                                                                      \
      st_composite_under(color, transmittance,                                                    \
                         st_fragment_colour(triangle_colors, tex_tris, atlas, view,               \
                                            mdts_source_##WORD(format, w), x, y));                \
    }                                                                                             \
  }

MDTS_DEFINE_SLOTS(local_ulong, __local, ulong, ST_VISIBILITY_EMPTY, st_atom64_min_local)
MDTS_DEFINE_SLOTS(global_ulong, __global, ulong, ST_VISIBILITY_EMPTY, st_atom64_min_global)
MDTS_DEFINE_SLOTS(local_uint, __local, uint, MDTS32_EMPTY, atomic_min)
MDTS_DEFINE_SLOTS(global_uint, __global, uint, MDTS32_EMPTY, atomic_min)

/* The serial kernels' chain: a work-item alone on its tile's slots runs the same insertion with
 * plain loads and stores in place of the atomics (min into the slot, the old value back). */
#define MDTS_DEFINE_PLAIN_MIN(NAME, SPACE, WORD)                                                  \
  inline WORD mdts_plain_min_##NAME(SPACE WORD* slot, WORD v) {                                   \
    const WORD old = *slot;                                                                       \
    *slot = min(old, v);                                                                          \
    return old;                                                                                   \
  }
MDTS_DEFINE_PLAIN_MIN(local_ulong, __local, ulong)
MDTS_DEFINE_PLAIN_MIN(global_ulong, __global, ulong)
MDTS_DEFINE_PLAIN_MIN(local_uint, __local, uint)
MDTS_DEFINE_PLAIN_MIN(global_uint, __global, uint)
MDTS_DEFINE_SLOTS(alone_local_ulong, __local, ulong, ST_VISIBILITY_EMPTY,
                  mdts_plain_min_local_ulong)
MDTS_DEFINE_SLOTS(alone_global_ulong, __global, ulong, ST_VISIBILITY_EMPTY,
                  mdts_plain_min_global_ulong)
MDTS_DEFINE_SLOTS(alone_local_uint, __local, uint, MDTS32_EMPTY, mdts_plain_min_local_uint)
MDTS_DEFINE_SLOTS(alone_global_uint, __global, uint, MDTS32_EMPTY, mdts_plain_min_global_uint)

/* ---- Both kernels in both forms: one body per word size (tile_walk.cl: one body for a tile
 * kernel's two forms), the slots in local or global memory (the flag is tested around each step,
 * never around a barrier). In the serial form one work-item owns the tile (a work-group of one:
 * its local slots are its own) and runs the chain with plain loads and stores; the chain keeps
 * the K nearest words whatever the order of arrival, so the slots, and the lost fragments, are
 * those of the work-group form. pixel_count and scratch are the kernel's __local arrays of
 * ST_TILE_PIXELS. ---- */
#define MDTS_DEFINE_RASTER_RESOLVE(WORD)                                                          \
  inline __attribute__((always_inline)) void mdts_raster_resolve_##WORD(                          \
      bool alone, __global const StTriSetup* records, __global const uint* bin_entries,           \
      __global const uint* tile_offsets, uint tiles_x, uint bin_capacity, uint k,                 \
      const MdtsFormat* format, int use_global_slots, __local WORD* local_slots,                  \
      __global WORD* global_slots, __global const float4* triangle_colors,                        \
      __global const StTexTriangle* tex_tris, __global const uint* atlas,                         \
      __constant StViewConstants* view, __global uchar4* image, __global ulong* counters,         \
      __global uint* depth_complexity, int capture_depth_complexity, __local uint* pixel_count,   \
      __local uint* scratch) {                                                                    \
    const uint tile = get_group_id(1) * tiles_x + get_group_id(0);                                \
    uint begin, end;                                                                              \
    st_tile_range_of(tile_offsets, tile, bin_capacity, &begin, &end);                             \
    /* A tile without triangles needs no slots. (Not an early return, though the test is uniform  \
     * over the work-group: with one, PoCL 3.1 reported a wrong group maximum after the           \
     * barriers.) */                                                                              \
    const uint used_k = begin < end ? k : 0;                                                      \
    __global WORD* tile_global = global_slots + (size_t)tile * k * ST_TILE_PIXELS;                \
    ST_FOR_OWNED_PIXELS(p, alone) {                                                               \
      if (use_global_slots) mdts_clear_global_##WORD(tile_global + p, used_k);                    \
      else mdts_clear_local_##WORD(local_slots + p, used_k);                                      \
      pixel_count[p] = 0;                                                                         \
    }                                                                                             \
    barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);                                          \
    const int tx = (int)get_group_id(0) * ST_TILE_SIZE, ty = (int)get_group_id(1) * ST_TILE_SIZE; \
                                                                                                  \
    /* Insert every fragment through the min chain of its pixel. */                               \
    uint lost = 0;                                                                                \
    StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, begin, end, tx, ty);           \
    while (st_tile_triangle_next(&f)) {                                                           \
      while (st_tile_fragment_next(&f)) {                                                         \
        const WORD word = mdts_word_##WORD(format, f.depth, f.r->source);                         \
        if (alone)                                                                                \
          lost += use_global_slots                                                                \
                      ? mdts_insert_alone_global_##WORD(tile_global + f.p, k, word)               \
                      : mdts_insert_alone_local_##WORD(local_slots + f.p, k, word);               \
        else                                                                                      \
          lost += use_global_slots ? mdts_insert_global_##WORD(tile_global + f.p, k, word)        \
                                   : mdts_insert_local_##WORD(local_slots + f.p, k, word);        \
        st_owned_add_uint(alone, &pixel_count[f.p], 1u);                                          \
      }                                                                                           \
    }                                                                                             \
    barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);                                          \
                                                                                                  \
    /* Resolve: the slots are already in front-to-back order. */                                  \
    uint fragments = 0, deepest = 0;                                                              \
    ST_FOR_OWNED_PIXELS(p, alone) {                                                               \
      const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);        \
      fragments += pixel_count[p];                                                                \
      deepest = max(deepest, pixel_count[p]);                                                     \
      if (x >= view->width || y >= view->height) continue;                                        \
      float3 color = (float3)(0.0f);                                                              \
      float transmittance = 1.0f;                                                                 \
      if (use_global_slots)                                                                       \
        mdts_composite_global_##WORD(tile_global + p, used_k, format, triangle_colors, tex_tris,  \
                                     atlas, view, x, y, &color, &transmittance);                  \
      else                                                                                        \
        mdts_composite_local_##WORD(local_slots + p, used_k, format, triangle_colors, tex_tris,   \
                                    atlas, view, x, y, &color, &transmittance);                   \
      color += transmittance * st_background(view, x, y);                                        \
      image[y * view->width + x] = st_pack_rgba8(color);                                          \
      if (capture_depth_complexity) depth_complexity[y * view->width + x] = pixel_count[p];       \
    }                                                                                             \
    st_report_owned_counts(alone, scratch, counters, fragments, deepest, lost);                   \
  }

MDTS_DEFINE_RASTER_RESOLVE(ulong)
MDTS_DEFINE_RASTER_RESOLVE(uint)

#define MDTS_TILE_PARAMS                                                                          \
  __global const StTriSetup *records, __global const uint *bin_entries,                            \
      __global const uint *tile_offsets, const uint tiles_x, const uint bin_capacity, const uint k
#define MDTS_FRAME_PARAMS                                                                         \
  __global const float4 *triangle_colors, __global const StTexTriangle *tex_tris,                  \
      __global const uint *atlas, __constant StViewConstants *view, __global uchar4 *image,        \
      __global ulong *counters, __global uint *depth_complexity, const int capture_depth_complexity
#define MDTS_ARGS(alone, format)                                                                  \
  alone, records, bin_entries, tile_offsets, tiles_x, bin_capacity, k, format, use_global_slots,   \
      local_slots, global_slots, triangle_colors, tex_tris, atlas, view, image, counters,          \
      depth_complexity, capture_depth_complexity, pixel_count, scratch

/* mdts32's quantisation for `depth_bits` bits of depth (see the top). */
inline void mdts32_format(MdtsFormat* format, __constant StViewConstants* view,
                          uint depth_bits) {
  format->near_plane = view->near_distance;
  format->levels = (float)(1u << depth_bits);
  format->max_level = (1u << depth_bits) - 1u;
  format->id_shift = 32u - depth_bits;
}

/* mdts: 64-bit (float depth, triangle id) words. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void mdts_raster_resolve(MDTS_TILE_PARAMS, const int use_global_slots, __local ulong* local_slots,
                         __global ulong* global_slots, MDTS_FRAME_PARAMS) {
  __local uint pixel_count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS];
  const MdtsFormat format = {0.0f, 0.0f, 0u, 0u};
  mdts_raster_resolve_ulong(MDTS_ARGS(false, &format));
}

/* mdts32: one 32-bit word, quantised depth above the colour index (see the top). */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void mdts32_raster_resolve(MDTS_TILE_PARAMS, const uint depth_bits, const int use_global_slots,
                           __local uint* local_slots, __global uint* global_slots,
                           MDTS_FRAME_PARAMS) {
  __local uint pixel_count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS];
  MdtsFormat format;
  mdts32_format(&format, view, depth_bits);
  mdts_raster_resolve_uint(MDTS_ARGS(false, &format));
}

/* The serial forms, for a CPU device: one work-item alone on its tile (same arguments). */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void mdts_raster_resolve_serial(MDTS_TILE_PARAMS, const int use_global_slots,
                                __local ulong* local_slots, __global ulong* global_slots,
                                MDTS_FRAME_PARAMS) {
  __local uint pixel_count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS];
  const MdtsFormat format = {0.0f, 0.0f, 0u, 0u};
  mdts_raster_resolve_ulong(MDTS_ARGS(true, &format));
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void mdts32_raster_resolve_serial(MDTS_TILE_PARAMS, const uint depth_bits,
                                  const int use_global_slots, __local uint* local_slots,
                                  __global uint* global_slots, MDTS_FRAME_PARAMS) {
  __local uint pixel_count[ST_TILE_PIXELS], scratch[ST_TILE_PIXELS];
  MdtsFormat format;
  mdts32_format(&format, view, depth_bits);
  mdts_raster_resolve_uint(MDTS_ARGS(true, &format));
}
