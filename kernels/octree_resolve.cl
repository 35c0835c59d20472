/* octree_resolve.cl: the octree method's raster and resolve (engine/methods/octree.cpp). One
 * work-group owns a block of screen tiles, one tile after the other (as cells_composite), and
 * walks the tile's bin list, which the ordered binner keeps in the view's front-to-back leaf
 * order, leaf by leaf (a leaf's records carry its position in the order, record_group).
 *
 * Per leaf and pixel only the fragments the leaf claims count (strata_shared.h,
 * st_octree_leaf_interval: t_in <= depth < t_out on the pixel's ray), so a triangle that several
 * leaves reference is composited once, by the leaf holding the fragment. The leaf's claimed
 * fragments are then taken in depth order, k at a time: every walk over the leaf's triangles
 * keeps, per pixel, the k nearest claimed words at or behind the pixel's lower bound (a sorted
 * local k-buffer filled by 64-bit atomic-min insertion, as MDTS), composites them front to back
 * and moves the bound behind the last one. With k = 1 a walk is one depth-peeling iteration.
 * How many walks a tile needs comes from the count of claimed fragments per pixel:
 *  - ST_OCTREE_COUNT_COVERAGE: a coverage-only walk first (the leaf's depth histogram, here per
 *    tile), then exactly as many walks as the tile's deepest pixel needs;
 *  - ST_OCTREE_COUNT_FIRST: the first walk appends the claimed words unsorted (up to k per
 *    pixel) and counts them; a pixel whose words all fit is sorted and done in that walk, the
 *    others take the k nearest per walk from then on (the fixed per-pixel budget, falling back
 *    to k-at-a-time peeling only where a pixel exceeds it);
 *  - ST_OCTREE_COUNT_NONE: walks until one leaves a pixel's k-buffer not full (with k = 1, the
 *    occlusion-query loop of per-block peeling: the last walk finds nothing).
 * No count is read back: the loop runs inside the work-group, and its exits are uniform (a flag
 * in local memory after a barrier). Nothing is ever dropped for want of room; only a tile whose
 * walks would read more than tile_reads entries stops its leaves early (octree_max_walks).
 * The running result (colour, transmittance; translucency also the inside count and the last
 * depth) persists between batches in the accumulator that cells_composite also uses, and
 * fragments are composited with that method's rule (st_cells_composite). */

/* Inserts a word into a pixel's sorted k-buffer (slot s of the pixel at slot0[s * ST_TILE_PIXELS],
 * as MDTS, so a work-group's reads of one slot are contiguous; empty slots hold
 * ST_VISIBILITY_EMPTY): the atomic-min chain keeps the k smallest words, sorted, whatever the
 * order of the insertions. Every access is atomic (other work-items insert into the same pixel);
 * the first one, an atom_min that cannot change the last slot, reads it to skip words behind a
 * full buffer. */
inline void octree_kbuffer_insert(__local ulong* slot0, uint k, ulong word) {
  if (word >= st_atom64_min_local(&slot0[(k - 1) * ST_TILE_PIXELS], ST_VISIBILITY_EMPTY)) return;
  ulong w = word;
  for (uint i = 0; i < k; ++i) {
    const ulong old = st_atom64_min_local(&slot0[i * ST_TILE_PIXELS], w);
    if (old == ST_VISIBILITY_EMPTY) return;
    w = max(old, w);
  }
}

/* The pixel (x, y)'s ray for the claim rule (Camera::pixelRay): origin, direction and its
 * inverse. dot(dir, forward) = 1, so its parameter is the view distance the raster
 * interpolates; ray_tan[0..1] are 0 for orthographic views, ray_tan[2..3] for perspective ones. */
inline void octree_pixel_ray(int x, int y, __constant StViewConstants* view, float* ray_o,
                             float* ray_d, float* ray_inv) {
  const int width = view->width, height = view->height;
  const float ndc_x = (((float)x + 0.5f) / (float)width) * 2.0f - 1.0f;
  const float ndc_y = 1.0f - (((float)y + 0.5f) / (float)height) * 2.0f;
  const float3 fwd = (float3)(view->forward[0], view->forward[1], view->forward[2]);
  const float3 right = (float3)(view->right[0], view->right[1], view->right[2]);
  const float3 up = (float3)(view->up[0], view->up[1], view->up[2]);
  const float3 o = (float3)(view->eye[0], view->eye[1], view->eye[2]) +
                   right * (ndc_x * view->ray_tan[2]) + up * (ndc_y * view->ray_tan[3]);
  const float3 dir = fwd + right * (ndc_x * view->ray_tan[0]) + up * (ndc_y * view->ray_tan[1]);
  ray_o[0] = o.x;
  ray_o[1] = o.y;
  ray_o[2] = o.z;
  ray_d[0] = dir.x;
  ray_d[1] = dir.y;
  ray_d[2] = dir.z;
  for (int a = 0; a < 3; ++a) ray_inv[a] = 1.0f / ray_d[a];
}

/* After a first walk of ST_OCTREE_COUNT_FIRST appended a pixel's `total` claimed words unsorted
 * (slot s at mine[s * ST_TILE_PIXELS]): when they all fit they are sorted and the pixel is done
 * in that walk; otherwise they are dropped and the next walks take the k nearest at a time. */
inline void octree_first_walk_words(__local ulong* mine, uint total, uint k) {
  if (total <= k) {
    for (uint i = 1; i < total; ++i) { /* insertion sort: a handful of words */
      const ulong w = mine[i * ST_TILE_PIXELS];
      uint j = i;
      for (; j > 0 && mine[(j - 1) * ST_TILE_PIXELS] > w; --j)
        mine[j * ST_TILE_PIXELS] = mine[(j - 1) * ST_TILE_PIXELS];
      mine[j * ST_TILE_PIXELS] = w;
    }
  } else {
    for (uint i = 0; i < k; ++i) mine[i * ST_TILE_PIXELS] = ST_VISIBILITY_EMPTY;
  }
}

/* Composites a pixel's sorted words of this walk front to back, emptying their slots; returns
 * how many, the last in *last. */
inline uint octree_take_words(__local ulong* mine, uint k, StCellsPixel* px,
                              __global const StTriSetup* records,
                              __global const float4* record_color,
                              __global const float4* record_normal,
                              __global const StTexTriangle* tex_tris, __global const uint* atlas,
                              __constant StViewConstants* view, ulong* last) {
  uint m = 0;
  while (m < k && mine[m * ST_TILE_PIXELS] != ST_VISIBILITY_EMPTY) {
    *last = mine[m * ST_TILE_PIXELS];
    st_cells_composite(px, *last, records, record_color, record_normal, tex_tris, atlas, view);
    mine[m * ST_TILE_PIXELS] = ST_VISIBILITY_EMPTY;
    ++m;
  }
  return m;
}

/* The walks a leaf may take in a tile: the tile's entry reads (coverage walks included) stay
 * within tile_reads, so one deep leaf (thousands of coincident or stacked faces the tree cannot
 * split) costs a bounded time; what lies behind a leaf's last walk is counted lost, not
 * composited. Every leaf takes the walks that take its nearest k fragments per pixel, and the
 * leaves in front have the budget first. tile_reads = 0: no bound. */
inline uint octree_max_walks(uint tile_reads, ulong used, uint entries, int count_mode) {
  if (tile_reads == 0) return UINT_MAX;
  const uint coverage = count_mode == ST_OCTREE_COUNT_COVERAGE ? 1u : 0u;
  /* A first walk that counts keeps a pixel's words only when they all fit: a second takes the
   * nearest k of the others. */
  const uint least = count_mode == ST_OCTREE_COUNT_FIRST ? 2u : 1u;
  /* Signed, and no clamp at zero: Oclgrind lacks the saturating subtraction LLVM makes of one. */
  const long left = (long)tile_reads - (long)used, per_walk = (long)max(entries, 1u);
  if (left < per_walk * (long)(coverage + least + 1u)) return least;
  return (uint)(left / per_walk) - coverage;
}

/* octree_kbuffer_insert for a work-item alone on its tile: the same chain with plain min and
 * max, so the same k smallest words in the same slots. */
inline void octree_kbuffer_insert_alone(__local ulong* slot0, uint k, ulong word) {
  if (word >= slot0[(k - 1) * ST_TILE_PIXELS]) return;
  ulong w = word;
  for (uint i = 0; i < k; ++i) {
    const ulong old = slot0[i * ST_TILE_PIXELS];
    slot0[i * ST_TILE_PIXELS] = min(old, w);
    if (old == ST_VISIBILITY_EMPTY) return;
    w = max(old, w);
  }
}

/* The kernel's arguments (both forms take the same). */
#define OCTREE_RESOLVE_PARAMS                                                                     \
  __global const StTriSetup *records, __global const uint *record_group,                           \
      __global const float4 *record_color, __global const float4 *record_normal,                   \
      __global const StTexTriangle *tex_tris, __global const uint *atlas,                          \
      __global const uint *bin_entries, __global const uint *chunk_offsets, const uint chunks,     \
      const uint tiles_x, const uint bin_capacity, __constant StViewConstants *view,               \
      __global const StOctreeLeaf *leaves, const int claim, const uint k, const int count_mode,    \
      const uint tile_reads, __local ulong *layers, __global ushort4 *accum,                       \
      __global float2 *accum_extra, const int first_batch, const int last_batch,                   \
      const int background_filled, __global uchar4 *image, __global ulong *counters,               \
      __global uint *pixel_fragments, __global uint *leaf_walks, const float saturated,            \
      const uint4 block_range /* the serial kernel's */, __global ulong *batch_counters
#define OCTREE_RESOLVE_ARGS                                                                       \
  records, record_group, record_color, record_normal, tex_tris, atlas, bin_entries,                \
      chunk_offsets, chunks, tiles_x, bin_capacity, view, leaves, claim, k, count_mode,            \
      tile_reads, layers, accum, accum_extra, first_batch, last_batch, background_filled, image,   \
      counters, pixel_fragments, leaf_walks, saturated, block_range, batch_counters

/* A tile's tables that every work-item of a work-group reads (__local in both forms). */
typedef struct {
  __local ulong* lower;  /* per pixel: the next walk takes words >= this */
  __local float* t_in;   /* per pixel: the leaf's claim interval */
  __local float* t_out;
  __local uint* count;   /* per pixel: claimed fragments of the leaf */
  __local uint* shared_end;
  __local int* more;     /* per walk parity: some pixel has fragments left */
  __local int* live;     /* early out: some pixel of the tile still lets light through */
} OctreeTables;

/* What the launch adds to the frame counters, summed over the tiles a work-item resolves. */
typedef struct {
  uint fragments, deepest_pixel;
  ulong walks, entry_reads, lost;
} OctreeTotals;

/* The state of the pixels a work-item owns (its one pixel in a work-group, all ST_TILE_PIXELS
 * alone), indexed by OCTREE_OWNED(p): private arrays, so a work-group's item keeps its pixel's
 * state in registers. */
#define OCTREE_OWNED(p) (alone ? (p) : 0u)
typedef struct {
  StCellsPixel* px;
  uint* depth_count;
  float (*ray)[9]; /* origin, direction, 1 / direction */
  uint* total;     /* the leaf's claimed fragments */
  uint* taken;     /* of those, composited so far */
} OctreeOwned;

/* Every tile of block (block_x, block_y), in either form of the kernel (tile_walk.cl: one body
 * for a tile kernel's two forms): the leaves of each tile in the order's sequence, each taking
 * its walks until its claimed fragments are composited or its bound is reached. Every work-item
 * walks the same leaf boundaries and loop exits, so barriers are uniform. */
inline __attribute__((always_inline)) void octree_resolve_block(
    bool alone, OCTREE_RESOLVE_PARAMS, uint block_x, uint block_y, OctreeTables t,
    OctreeOwned own, OctreeTotals* sum) {
  const uint lid = st_local_index();
  const int width = view->width, height = view->height;
  const uint tiles_y = ((uint)height + ST_TILE_SIZE - 1) / ST_TILE_SIZE;
  /* With background_filled (fill_background wrote the background and zero fragment counts)
   * empty tiles have nothing to do, and an empty block walks none (cells_composite.cl). */
  const uint block_tiles = st_block_tile_count(background_filled, chunk_offsets, chunks, tiles_x,
                                               tiles_y, bin_capacity, block_x, block_y);
  for (uint sub = 0; sub < block_tiles; ++sub) {
    const StBlockTile bt = st_block_tile_at(chunk_offsets, chunks, bin_capacity, tiles_x, tiles_y,
                                            block_x, block_y, sub);
    const bool tile_valid = bt.valid;
    const uint begin = bt.begin, end = bt.end;
    if (begin == end && background_filled) continue; /* uniform: no barrier skipped by some */
    const int tx = (int)(bt.x * ST_TILE_SIZE), ty = (int)(bt.y * ST_TILE_SIZE);
    ulong inside = 0; /* bit p: pixel p lies on the image */
    ST_FOR_OWNED_PIXELS(p, alone) {
      const uint q = OCTREE_OWNED(p);
      const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
      const bool inside_image = tile_valid && x < width && y < height;
      if (inside_image) inside |= 1ul << p;
      own.px[q] = st_cells_pixel_begin(x, y, inside_image,
                                       inside_image ? (uint)(y * width + x) : 0u, first_batch,
                                       background_filled, view, accum, accum_extra,
                                       pixel_fragments, &own.depth_count[q]);
      octree_pixel_ray(x, y, view, &own.ray[q][0], &own.ray[q][3], &own.ray[q][6]);
      for (uint i = 0; i < k; ++i) layers[i * ST_TILE_PIXELS + p] = ST_VISIBILITY_EMPTY;
    }
    if (lid == 0) *t.live = 0;
    barrier(CLK_LOCAL_MEM_FENCE);
    ulong tile_used = 0; /* entry reads of the tile's walks so far (the same in every item) */
    for (uint e = begin; e < end;) {
      if (lid == 0) {
        const uint leaf = record_group[bin_entries[e]] & ST_CELLS_PASS_MASK;
        uint stop = e + 1;
        while (stop < end && (record_group[bin_entries[stop]] & ST_CELLS_PASS_MASK) == leaf)
          ++stop;
        *t.shared_end = stop;
        t.more[0] = 0;
        t.more[1] = 0;
      }
      const uint leaf = record_group[bin_entries[e]] & ST_CELLS_PASS_MASK;
      /* Early out: a pixel that lets less than `saturated` through claims nothing more (what is
       * behind it changes it by less than that), and a tile of such pixels skips the leaf. */
      ST_FOR_OWNED_PIXELS(p, alone) {
        const uint q = OCTREE_OWNED(p);
        const bool opaque_now = own.px[q].transmittance < saturated;
        const bool on_image = (inside >> p & 1ul) != 0;
        if (on_image && !opaque_now) *t.live = 1;
        if (!on_image || opaque_now) {
          t.t_in[p] = INFINITY;
          t.t_out[p] = -INFINITY;
        } else if (claim) {
          const StOctreeLeaf box = leaves[leaf];
          float a, b;
          st_octree_leaf_interval(box.lo, box.hi, &own.ray[q][0], &own.ray[q][3],
                                  &own.ray[q][6], &a, &b);
          t.t_in[p] = a;
          t.t_out[p] = b;
        } else {
          t.t_in[p] = -INFINITY;
          t.t_out[p] = INFINITY;
        }
        t.lower[p] = 0ul;
        t.count[p] = 0;
        own.taken[q] = 0;
      }
      barrier(CLK_LOCAL_MEM_FENCE);
      const uint leaf_end = *t.shared_end;
      if (saturated > 0.0f && !*t.live) { /* uniform: every work-item read the same flag */
        barrier(CLK_LOCAL_MEM_FENCE);
        e = leaf_end;
        continue; /* live stays 0: nothing can set it again in this tile */
      }

      int again = 1;
      if (count_mode == ST_OCTREE_COUNT_COVERAGE) {
        /* The leaf's depth histogram for this tile: claimed fragments per pixel, no depth test. */
        StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, e, leaf_end, tx, ty);
        while (st_tile_triangle_next(&f))
          while (st_tile_fragment_next(&f))
            if (st_octree_claims(t.t_in[f.p], t.t_out[f.p], fmax(f.depth, 0.0f)))
              st_owned_add_uint(alone, &t.count[f.p], 1u);
        sum->entry_reads += lid == 0 ? leaf_end - e : 0;
        barrier(CLK_LOCAL_MEM_FENCE);
        ST_FOR_OWNED_PIXELS(p, alone) {
          if (t.count[p] > 0) t.more[1] = 1;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        again = t.more[1];
      }
      ST_FOR_OWNED_PIXELS(p, alone) {
        own.total[OCTREE_OWNED(p)] = count_mode == ST_OCTREE_COUNT_COVERAGE ? t.count[p] : 0u;
      }
      uint walks = 0;
      const uint max_walks = octree_max_walks(tile_reads, tile_used, leaf_end - e, count_mode);
      while (again && walks < max_walks) {
        const bool count_now = count_mode == ST_OCTREE_COUNT_FIRST && walks == 0;
        StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, e, leaf_end, tx, ty);
        while (st_tile_triangle_next(&f)) {
          while (st_tile_fragment_next(&f)) {
            const uint p = f.p;
            if (!st_octree_claims(t.t_in[p], t.t_out[p], fmax(f.depth, 0.0f))) continue;
            const ulong word = st_visibility_word(f.depth, f.record);
            if (count_now) {
              const uint slot = st_owned_inc_uint(alone, &t.count[p]);
              if (slot < k) layers[slot * ST_TILE_PIXELS + p] = word;
            } else if (word >= t.lower[p]) {
              if (alone) octree_kbuffer_insert_alone(layers + p, k, word);
              else octree_kbuffer_insert(layers + p, k, word);
            }
          }
        }
        sum->entry_reads += lid == 0 ? leaf_end - e : 0;
        barrier(CLK_LOCAL_MEM_FENCE);
        /* The other parity's flag was last read before this walk's barrier. */
        if (lid == 0) t.more[(walks + 1) & 1] = 0;
        ST_FOR_OWNED_PIXELS(p, alone) {
          const uint q = OCTREE_OWNED(p);
          __local ulong* mine = layers + p; /* slot s at mine[s * ST_TILE_PIXELS] */
          if (count_now) {
            own.total[q] = t.count[p];
            octree_first_walk_words(mine, own.total[q], k);
          }
          ulong last = 0;
          const uint m = octree_take_words(mine, k, &own.px[q], records, record_color,
                                           record_normal, tex_tris, atlas, view, &last);
          own.taken[q] += m;
          if (m) t.lower[p] = last + 1ul;
          /* A finished pixel takes nothing more (later walks may still run for others). */
          if (count_mode != ST_OCTREE_COUNT_NONE && own.taken[q] == own.total[q])
            t.lower[p] = ST_VISIBILITY_EMPTY;
          const bool pixel_more =
              count_mode == ST_OCTREE_COUNT_NONE ? m == k : own.taken[q] < own.total[q];
          if (pixel_more) t.more[walks & 1] = 1;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        again = t.more[walks & 1];
        ++walks;
      }
      if (again && count_mode == ST_OCTREE_COUNT_NONE) {
        /* The leaf reached its bound with fragments left somewhere (uniform), and there is no
         * count yet: one more walk counts what lies behind the last word taken. */
        ST_FOR_OWNED_PIXELS(p, alone) t.count[p] = 0;
        barrier(CLK_LOCAL_MEM_FENCE);
        StTileWalk f = st_tile_walk_owned(alone, records, bin_entries, e, leaf_end, tx, ty);
        while (st_tile_triangle_next(&f))
          while (st_tile_fragment_next(&f))
            if (st_octree_claims(t.t_in[f.p], t.t_out[f.p], fmax(f.depth, 0.0f)) &&
                st_visibility_word(f.depth, f.record) >= t.lower[f.p])
              st_owned_add_uint(alone, &t.count[f.p], 1u);
        sum->entry_reads += lid == 0 ? leaf_end - e : 0;
        barrier(CLK_LOCAL_MEM_FENCE);
      }
      ST_FOR_OWNED_PIXELS(p, alone) {
        const uint q = OCTREE_OWNED(p);
        /* What the bound left is counted as the pixel's fragments, not composited. */
        const uint lost = !again                            ? 0u
                          : count_mode == ST_OCTREE_COUNT_NONE ? t.count[p]
                                                               : own.total[q] - own.taken[q];
        own.depth_count[q] += own.taken[q] + lost;
        sum->fragments += own.taken[q] + lost;
        sum->lost += lost;
      }
      tile_used += (ulong)(leaf_end - e) *
                   (walks + (count_mode == ST_OCTREE_COUNT_COVERAGE ? 1u : 0u) +
                    (again && count_mode == ST_OCTREE_COUNT_NONE ? 1u : 0u));
      if (lid == 0 && walks) {
        atomic_max(&leaf_walks[leaf], walks + (count_mode == ST_OCTREE_COUNT_COVERAGE ? 1u : 0u));
        sum->walks += walks;
      }
      e = leaf_end;
      if (lid == 0) *t.live = 0; /* read at this segment's start, barriers ago */
      barrier(CLK_LOCAL_MEM_FENCE);
    }

    ST_FOR_OWNED_PIXELS(p, alone) {
      const uint q = OCTREE_OWNED(p);
      const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
      const bool inside_image = (inside >> p & 1ul) != 0;
      st_cells_pixel_end(&own.px[q], inside_image, inside_image ? (uint)(y * width + x) : 0u,
                         last_batch, background_filled, view, accum, accum_extra, image,
                         pixel_fragments, own.depth_count[q]);
      sum->deepest_pixel = max(sum->deepest_pixel, own.depth_count[q]);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
}

/* The kernels' __local tables and the owned pixels' private state, N of them. */
#define OCTREE_RESOLVE_STATE(N)                                                                   \
  __local uint scratch[ST_TILE_PIXELS];                                                           \
  __local ulong lower[ST_TILE_PIXELS];                                                            \
  __local float t_in[ST_TILE_PIXELS], t_out[ST_TILE_PIXELS];                                      \
  __local uint count[ST_TILE_PIXELS];                                                             \
  __local uint shared_end;                                                                        \
  __local int more[2];                                                                            \
  __local int live;                                                                               \
  const OctreeTables tables = {lower, t_in, t_out, count, &shared_end, more, &live};              \
  StCellsPixel px[N];                                                                             \
  uint depth_count[N], total[N], taken[N];                                                        \
  float ray[N][9];                                                                                \
  const OctreeOwned owned = {px, depth_count, ray, total, taken};                                 \
  OctreeTotals sum = {0u, 0u, 0ul, 0ul, 0ul}

/* The launch's totals into the frame counters: one atomic each per work-group. */
inline __attribute__((always_inline)) void octree_report(bool alone, __local uint* scratch,
                                                         __global ulong* counters,
                                                         const OctreeTotals* sum) {
  if (st_local_index() == 0) {
    if (sum->walks) st_counter_add(&counters[ST_COUNTER_OCTREE_WALKS], sum->walks);
    if (sum->entry_reads) st_counter_add(&counters[ST_COUNTER_OCTREE_ENTRY_READS], sum->entry_reads);
  }
  if (sum->lost) st_counter_add(&counters[ST_COUNTER_FRAGMENTS_LOST], sum->lost);
  st_report_owned_counts(alone, scratch, counters, sum->fragments, sum->deepest_pixel, 0u);
}

/* A work-group per block of tiles (its global id's), one work-item per tile pixel. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void octree_resolve(OCTREE_RESOLVE_PARAMS) {
  OCTREE_RESOLVE_STATE(1);
  const uint block_x = (uint)get_global_id(0) / ST_TILE_SIZE;
  const uint block_y = (uint)get_global_id(1) / ST_TILE_SIZE;
  octree_resolve_block(false, OCTREE_RESOLVE_ARGS, block_x, block_y, tables, owned, &sum);
  octree_report(false, scratch, counters, &sum);
}

/* The serial form (docs/raster.md): one work-item per block of tiles, walking each tile's whole
 * list alone, the launch's blocks dealt as in the serial cells composite (st_block_deal_next).
 * The same walks, claims and composites, so the same image and counts. */
__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void octree_resolve_serial(OCTREE_RESOLVE_PARAMS) {
  OCTREE_RESOLVE_STATE(ST_TILE_PIXELS);
  StBlockDeal deal = st_block_deal_begin();
  uint block_x, block_y;
  while (st_block_deal_next(&deal, block_range, &batch_counters[ST_CELLS_BATCH_NEXT_BLOCK],
                            &block_x, &block_y))
    octree_resolve_block(true, OCTREE_RESOLVE_ARGS, block_x, block_y, tables, owned, &sum);
  octree_report(true, scratch, counters, &sum);
}
