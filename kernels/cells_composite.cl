/* cells_composite.cl: the convex-cells raster and composite. One work-group owns one screen tile
 * (DESIGN.md: tile ownership) and walks the tile's ordered bin list once, group by group (a
 * group: one convex cell, or cells merged because no order exists between them). Groups come in
 * passes whose groups do not overlap on screen (the host's ordering), and in each tile the host
 * joins consecutive passes that share no pixel centre there into segments, so a pixel sees at
 * most one group per segment: the segment's triangles are rasterized by the work-items in
 * parallel into the tile's layers in local memory; after a barrier each work-item composites
 * its pixel's layers into the pixel's running result and clears them for the next segment.
 *  - A single convex cell has at most one front and one back fragment per pixel (its faces
 *    facing the viewer, by the cell's own orientation, and those facing away): two 64-bit
 *    layers of depth above record index. A strict cell's layer has one writer per pixel, so
 *    it is stored; a cell of the paper's test (maybe not convex) is written with the paper's
 *    atomic max (the front layer takes the complement of the word, so its max is the nearest
 *    fragment; the back layer keeps the farthest).
 *  - A merged group appends up to k_capacity fragments per pixel and sorts them; the most any
 *    pixel needed is reported, and the host re-runs the frame with a larger budget.
 * The running result (colour, transmittance; translucency also the inside count and the last
 * depth) persists between batches in a per-pixel accumulator. With the background written
 * first (background_filled), a batch touches only the pixels it composites a fragment at: the
 * image holds every other pixel's result so far, and the accumulator is read only where the
 * pixel's fragment count says an earlier batch wrote it. */

/* Sorts a pixel's k-buffer words[0, n) ascending (insertion sort: a handful of fragments). */
inline void st_sort_layer_words(__local ulong* words, const uint n) {
  for (uint i = 1; i < n; ++i) {
    const ulong w = words[i];
    uint j = i;
    while (j > 0 && words[j - 1] > w) {
      words[j] = words[j - 1];
      --j;
    }
    words[j] = w;
  }
}

/* Composites one pixel's fragments of one group front to back: a single cell's two layers (0 =
 * empty; the front layer holds the complement of its word), or the n fragments of a merged group
 * in `mine` (sorted here). Returns the fragments composited. Not forced inline: inlined into the
 * group kernel, PoCL 3.1 composited the repair launch's k-buffers wrong (Oclgrind's images were
 * right). */
inline uint st_cells_flush(StCellsPixel* px, ulong front_word, ulong back_word, uint n,
                           __local ulong* mine, uint k_capacity,
                           __global const StTriSetup* records, __global const float4* record_color,
                           __global const float4* record_normal,
                           __global const StTexTriangle* tex_tris, __global const uint* atlas,
                           __constant StViewConstants* view) {
  if (n == 0) {
    uint done = 0;
    if (front_word != 0) {
      st_cells_composite(px, ~front_word, records, record_color, record_normal, tex_tris, atlas, view);
      ++done;
    }
    if (back_word != 0) {
      st_cells_composite(px, back_word, records, record_color, record_normal, tex_tris, atlas, view);
      ++done;
    }
    return done;
  }
  const uint kept = min(n, k_capacity);
  st_sort_layer_words(mine, kept);
  for (uint i = 0; i < kept; ++i)
    st_cells_composite(px, mine[i], records, record_color, record_normal, tex_tris, atlas, view);
  return n;
}

/* The order check of a pixel's group just composited (st_cells_flush, which sorted `mine`): the
 * depths a pixel composites never decrease, group after group (a word's upper half, ordered as
 * the floats): the front layer, then the back one, or the sorted k-buffer. *last_depth is the
 * deepest composited so far. Returns false where they decrease. */
inline bool st_cells_order_ascends(ulong front_word, ulong back_word, uint n,
                                   __local const ulong* mine, uint k_capacity, uint* last_depth) {
  uint first, last;
  bool ok = true;
  if (n) {
    first = (uint)(mine[0] >> 32);
    last = (uint)(mine[min(n, k_capacity) - 1] >> 32);
  } else if (front_word | back_word) {
    const uint f = (uint)(~front_word >> 32), b = (uint)(back_word >> 32);
    first = front_word ? f : b;
    last = back_word ? b : f;
    ok = first <= last; /* not the back layer nearer than the front one */
  } else {
    return true;
  }
  ok = ok && first >= *last_depth;
  *last_depth = max(*last_depth, last);
  return ok;
}

/* The end of the segment that starts at bin entry e of a tile's list [.., end): the first
 * entry whose pass reaches the tile's next break above e's pass (*next_break: the cursor in the
 * tile's breaks, which only moves forward), or, not segmented, the first of a later pass. The
 * passes never decrease along a list (drawing order), so the end is found by a galloping search
 * (probes 1, 2, 4, ... entries on, then bisection): one work-item does it while the others
 * composite, and a walk entry by entry made a long segment a chain of dependent loads. */
inline uint st_cells_segment_end(uint e, uint end, __global const uint* record_group,
                                 __global const uint* bin_entries, __global const uint* tile_breaks,
                                 uint* next_break, uint breaks_end, int segmented) {
  const uint pass = record_group[bin_entries[e]] & ST_CELLS_PASS_MASK;
  while (*next_break < breaks_end && tile_breaks[*next_break] <= pass) ++*next_break;
  const uint limit = !segmented                 ? pass + 1
                     : *next_break < breaks_end ? tile_breaks[*next_break]
                                                : 0xFFFFFFFFu;
  uint lo = e + 1, hi = end; /* the end lies in [lo, hi] */
  for (uint span = 1; lo < hi; span <<= 1) {
    const uint probe = min(lo + span - 1, hi - 1);
    if ((record_group[bin_entries[probe]] & ST_CELLS_PASS_MASK) < limit) {
      lo = probe + 1;
    } else {
      hi = probe;
      break;
    }
  }
  while (lo < hi) {
    const uint mid = lo + (hi - lo) / 2;
    if ((record_group[bin_entries[mid]] & ST_CELLS_PASS_MASK) < limit) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

/* The composite's arguments (both forms take the same; record_depths is the serial form's
 * order check, block_range and batch_counters its blocks, colour_in_record its plain tiles). */
#define CELLS_COMPOSITE_PARAMS                                                                    \
  __global const StTriSetup *records, __global const uint *record_group,                           \
      __global const float4 *record_color, __global const float4 *record_normal,                   \
      __global const StTexTriangle *tex_tris, __global const uint *atlas,                          \
      __global const uint *bin_entries, __global const uint *chunk_offsets, const uint chunks,     \
      const uint tiles_x, const uint bin_capacity, const int segmented,                            \
      __global const uint *tile_break_first, __global const uint *tile_breaks,                     \
      __constant StViewConstants *view, const int layer_write, __local ulong *layers,              \
      const uint k_capacity, __global ushort4 *accum, __global float2 *accum_extra,                \
      const int first_batch, const int last_batch, const int background_filled,                    \
      __global uchar4 *image, __global ulong *counters, __global uint *pixel_fragments,            \
      const int order_check, __global ulong *tile_flags, __global const float2 *record_depths,     \
      const uint4 block_range, __global ulong *batch_counters, const int colour_in_record

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void cells_composite(CELLS_COMPOSITE_PARAMS) {
  __local uint scratch[ST_TILE_PIXELS];
  __local uint tile_disordered[2]; /* the pixels where the order check failed (two halves) */
  __local ulong front[ST_TILE_PIXELS], back[ST_TILE_PIXELS]; /* pair layers; 0 = empty */
  __local uint count[ST_TILE_PIXELS];                       /* k-buffer fill per pixel */
  __local uint shared_segment_end;
  const uint lid = st_local_index();
  const int width = view->width, height = view->height;
  const uint tiles_y = ((uint)height + ST_TILE_SIZE - 1) / ST_TILE_SIZE;
  __local ulong* mine = layers + lid * k_capacity;
  uint deepest_group = 0, fragments = 0, deepest_pixel = 0, flagged = 0, flagged_pixels = 0;
  const bool check = order_check == ST_CELLS_ORDER_CHECK;
  const bool repair = order_check == ST_CELLS_ORDER_REPAIR;
  /* Cleared here, then by the exchanges that read it at the end of each tile (atomics, which
   * the compiler cannot hoist out of lid 0's branch into the other items' code). */
  if (lid == 0) tile_disordered[0] = tile_disordered[1] = 0;
  /* A work-group owns a block of tiles; launches may cover only the batch's blocks (a global
   * offset), so blocks come from global ids. Out-of-image tiles simply have no entries and no
   * pixels. */
  const uint block_x = (uint)get_global_id(0) / ST_TILE_SIZE, block_y = (uint)get_global_id(1) / ST_TILE_SIZE;
  const uint block_tiles = st_block_tile_count(background_filled, chunk_offsets, chunks, tiles_x,
                                               tiles_y, bin_capacity, block_x, block_y);
  for (uint sub = 0; sub < block_tiles; ++sub) {
  uint tile_x, tile_y;
  const bool tile_valid = st_block_tile(block_x, block_y, sub, tiles_x, tiles_y, &tile_x, &tile_y);
  const int x = (int)(tile_x * ST_TILE_SIZE + get_local_id(0)), y = (int)(tile_y * ST_TILE_SIZE + get_local_id(1));
  const bool inside_image = tile_valid && x < width && y < height;
  const uint pixel = inside_image ? (uint)(y * width + x) : 0u;

  const uint tile = tile_y * tiles_x + tile_x;
  /* The repair composites only the pixels the check flagged (the test is uniform over the
   * work-group: a tile with none is skipped). */
  const ulong redo = repair ? (tile_valid ? tile_flags[tile] : 0ul) : ~0ul;
  if (redo == 0) continue;
  uint begin, end;
  st_chunked_tile_range(chunk_offsets, chunks, bin_capacity, tile_valid, tile, &begin, &end);
  /* An empty tile of a block that holds something: no pixel state and no barriers (the test is
   * uniform over the work-group). */
  if (begin == end && background_filled) continue;
  uint last_depth = 0; /* the order check's: the deepest key this pixel composited */

  uint depth_count;
  StCellsPixel px =
      st_cells_pixel_begin(x, y, inside_image, pixel, first_batch, background_filled, view, accum,
                           accum_extra, pixel_fragments, &depth_count);
  const int tx = (int)(tile_x * ST_TILE_SIZE), ty = (int)(tile_y * ST_TILE_SIZE);
  /* The list is walked in segments: runs of passes that share no pixel centre in this tile
   * (the host's tile_breaks: the passes that start a new one), so a pixel still sees at most
   * one group per segment. Every work-item walks the same boundaries, so the loop and its
   * barriers are uniform. One work-item finds where each segment ends, the first before the
   * loop and the next while compositing the current one, so that no barrier is spent on it. */
  uint next_break = tile_valid && segmented ? tile_break_first[tile] : 0u;
  const uint breaks_end = tile_valid && segmented ? tile_break_first[tile + 1] : 0u;
  /* The repair takes the whole list as one segment of one merged group. */
  if (lid == 0 && begin < end)
    shared_segment_end =
        repair ? end
               : st_cells_segment_end(begin, end, record_group, bin_entries, tile_breaks,
                                      &next_break, breaks_end, segmented);
  front[lid] = back[lid] = 0;
  count[lid] = 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint e = begin; e < end;) {
    const uint segment_end = shared_segment_end;
    /* Raster the segment's triangles, one per work-item at a time, into the tile's layers. */
    StTileWalk f = st_tile_walk(records, bin_entries, e, segment_end, tx, ty);
    while (st_tile_triangle_next(&f)) {
      f.covered &= redo;
      /* Per triangle: its record and layer rule; then its pixels. */
      const uint rec = f.record;
      const bool single = !repair && (record_group[rec] & ST_CELLS_SINGLE_CELL) != 0;
      const bool cell_front = (f.r->flags & ST_TRI_CELL_FRONT) != 0;
      __local ulong* layer = cell_front ? front : back;
      const ulong flip = cell_front ? ~0ul : 0ul; /* the front layer keeps the complement */
      while (st_tile_fragment_next(&f)) {
        const uint p = f.p;
        const ulong word = st_visibility_word(f.depth, rec);
        if (!repair) ++fragments; /* the check's launch counted them */
        if (single) {
          if (check) {
            /* An earlier view's order may put two groups of one segment on this pixel now: a
             * strict cell has one fragment per layer, so a word already there is another's. */
            if (st_atom64_xchg_local(&layer[p], word ^ flip))
              atomic_or(&tile_disordered[p >> 5], 1u << (p & 31u));
          } else if (layer_write == ST_CELLS_LAYER_STORE) {
            layer[p] = word ^ flip;
          } else {
            ST_ATOM64_MAX(&layer[p], word ^ flip);
          }
        } else {
          const uint slot = atomic_inc(&count[p]);
          if (slot < k_capacity) layers[p * k_capacity + slot] = word;
          else st_counter_claim(&counters[ST_COUNTER_FRAGMENTS_LOST], 1);
        }
      }
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    /* Composite the pixel's layers front to back (a pixel sees one group per segment), then
     * clear them for the next segment. */
    const uint n = count[lid];
    if (n) deepest_group = max(deepest_group, n);
    depth_count += st_cells_flush(&px, front[lid], back[lid], n, mine, k_capacity, records,
                                  record_color, record_normal, tex_tris, atlas, view);
    /* An earlier view's order (checked): the pixel's segments ascend in depth, and none mixes a
     * single cell's layers with a merged group's k-buffer (which the flush ignores). */
    if (check &&
        (!st_cells_order_ascends(front[lid], back[lid], n, mine, k_capacity, &last_depth) ||
         (n && (front[lid] | back[lid]))))
      atomic_or(&tile_disordered[lid >> 5], 1u << (lid & 31u));
    front[lid] = back[lid] = 0;
    count[lid] = 0;
    if (lid == 0 && segment_end < end)
      shared_segment_end = st_cells_segment_end(segment_end, end, record_group, bin_entries,
                                                tile_breaks, &next_break, breaks_end, segmented);
    barrier(CLK_LOCAL_MEM_FENCE);
    e = segment_end;
  }

  /* The repair leaves the pixels the check passed as they are. */
  if (redo >> lid & 1ul)
    st_cells_pixel_end(&px, inside_image, pixel, last_batch, background_filled, view, accum,
                       accum_extra, image, pixel_fragments, depth_count);
  deepest_pixel = max(deepest_pixel, depth_count);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid == 0) {
    const ulong disordered = (ulong)atomic_xchg(&tile_disordered[0], 0u) |
                             ((ulong)atomic_xchg(&tile_disordered[1], 0u) << 32);
    if (disordered) {
      tile_flags[tile] = disordered;
      ++flagged;
      flagged_pixels += (uint)popcount(disordered);
    }
  }
  }
  if (lid == 0 && flagged) {
    st_counter_add(&counters[ST_COUNTER_CELLS_REPAIR_TILES], (ulong)flagged);
    st_counter_add(&counters[ST_COUNTER_CELLS_REPAIR_PIXELS], (ulong)flagged_pixels);
  }
  /* The repair's groups are whole pixels: its k-buffer is sized apart (the host's). */
  st_report_group_counts(scratch, counters, fragments, deepest_pixel, deepest_group,
                         repair ? ST_COUNTER_CELLS_REPAIR_DEPTH : ST_COUNTER_CELLS_GROUP_DEPTH);
}

/* The same composite for a CPU device (the host picks it on PoCL): one work-item owns a block of
 * tiles and walks each tile's list alone, so there is no barrier and no segment to wait for.
 * PoCL runs the code between two barriers as a loop over a work-group's items with their live
 * state in memory, and the group kernel above pays that twice per segment for a handful of
 * triangles. Here each pixel keeps its group's layers until a fragment of a later group reaches
 * it (the host tags this kernel's records with their group's rank in drawing order, not their
 * pass), then composites them: for the view's own order, where a pixel meets at most one group
 * per pass, the same fragments in the same order as the group kernel, so the same image,
 * counts and reports. The tile's per-pixel state is the work-item's own. It takes the group
 * kernel's arguments, so the host sets them once; the segments go unused. */
/* The serial composite's order check of a group pixel (x, y) just composited: a single cell's
 * layers (words whose low half is the record) or a merged group's sorted k-buffer (words with
 * their depths). Its first fragment must lie no nearer than the last one the pixel composited
 * before (*last_rec, of depth at most *last_hi; ST_CELLS_NO_RECORD: none), and a single cell's
 * front no farther than its back. The records' depth bounds (cells_setup) settle almost every
 * comparison; the fragments' depths are computed only where the bounds overlap, so the layers
 * need no depth. The same verdicts as st_cells_order_ascends while each fragment's
 * interpolated depth stays within its triangle's bounds (widened far beyond its rounding).
 * Returns false where the order fails. */
#define ST_CELLS_NO_RECORD 0xFFFFFFFFu
inline __attribute__((always_inline)) bool st_cells_serial_ascends(
    ulong front_word, ulong back_word, uint n, __local const ulong* mine, uint k_capacity, int x,
    int y, __global const StTriSetup* records, __global const float2* record_depths,
    uint* last_rec, float* last_hi) {
  uint first, last;
  float first_lo, last_hi_new, first_depth = 0.0f;
  bool ok = true, first_exact = false;
  if (n) {
    const ulong a = mine[0], z = mine[min(n, k_capacity) - 1];
    first = (uint)a;
    last = (uint)z;
    first_depth = first_lo = as_float((uint)(a >> 32));
    first_exact = true;
    last_hi_new = as_float((uint)(z >> 32));
  } else if (front_word | back_word) {
    const uint f = (uint)~front_word, b = (uint)back_word;
    first = front_word ? f : b;
    last = back_word ? b : f;
    first_lo = record_depths[first].x;
    last_hi_new = record_depths[last].y;
    if (front_word && back_word && record_depths[f].y > record_depths[b].x)
      ok = st_record_depth(&records[f], st_record_origin(&records[f]), x, y) <=
           st_record_depth(&records[b], st_record_origin(&records[b]), x, y);
  } else {
    return true;
  }
  if (*last_rec != ST_CELLS_NO_RECORD && first_lo < *last_hi) {
    __global const StTriSetup* r = &records[*last_rec];
    const float before = st_record_depth(r, st_record_origin(r), x, y);
    if (!first_exact)
      first_depth = st_record_depth(&records[first], st_record_origin(&records[first]), x, y);
    ok = ok && first_depth >= before;
  }
  *last_rec = last;
  *last_hi = last_hi_new;
  return ok;
}

/* The serial composite's pixel p is done with the group it holds: composite its layers (or
 * k-buffer) into its result, clear them, and count the group's depth. Returns the fragments
 * composited. `plain` (flat colours composited under): a single cell's layers take
 * their colours straight from the words' records, inline; as calls, passing a dozen arguments
 * per pixel and group, the flushes were a sixth of the composite on PoCL. */
inline __attribute__((always_inline)) uint st_cells_serial_flush(
    uint p, StCellsPixel* px, ulong* front, ulong* back, uint* count, uint* deepest_group,
    __local ulong* layers, uint k_capacity, __global const StTriSetup* records,
    __global const float4* record_color, __global const float4* record_normal,
    __global const StTexTriangle* tex_tris, __global const uint* atlas,
    __constant StViewConstants* view, bool check, __global const float2* record_depths,
    uint* last_rec, float* last_hi, int tx, int ty, ulong* disordered, bool plain) {
  const uint n = count[p];
  const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
  if (plain && n == 0) {
    uint done = 0;
    const ulong f = front[p], b = back[p];
    if (f) {
      st_composite_under(&px[p].colour, &px[p].transmittance, record_color[(uint)~f]);
      ++done;
    }
    if (b) {
      st_composite_under(&px[p].colour, &px[p].transmittance, record_color[(uint)b]);
      ++done;
    }
    if (check && !st_cells_serial_ascends(f, b, 0u, layers, k_capacity, x, y, records,
                                          record_depths, &last_rec[p], &last_hi[p]))
      *disordered |= 1ul << p;
    front[p] = back[p] = 0;
    return done;
  }
  if (n) *deepest_group = max(*deepest_group, n);
  __local ulong* mine = layers + p * k_capacity;
  const uint done = st_cells_flush(&px[p], front[p], back[p], n, mine, k_capacity, records,
                                   record_color, record_normal, tex_tris, atlas, view);
  if (check && !st_cells_serial_ascends(front[p], back[p], n, mine, k_capacity, x, y, records,
                                        record_depths, &last_rec[p], &last_hi[p]))
    *disordered |= 1ul << p;
  front[p] = back[p] = 0;
  count[p] = 0;
  return done;
}

#define ST_CELLS_SERIAL_AHEAD 12 /* bin entries */
/* A layer word without a depth (st_visibility_word's upper half, never read): non-zero, so the
 * layer is not taken for empty, nor is its complement. */
#define ST_CELLS_DEPTH_FREE_WORD (1ul << 32)

/* The plain composite of one tile by a work-item alone: flat colours composited under, strict
 * cells (layers stored), no order check, the background written first. The tile's list comes in
 * runs of one pass each, and a pass's groups share no pixel, so a pixel meets at most one group
 * per run. A single convex cell's front fragment at a pixel is nearer than its back one, so a
 * run is walked twice: its cells' front records composited at once, straight into the pixels'
 * results, then their back records; a merged group's fragments go to the pixel's k-buffer and
 * are sorted and composited at the end of the run. Nothing waits in a layer, and a record's
 * colour is loaded once and composited over its covered pixels a tile row at a time (eight
 * lanes). The arithmetic per fragment is st_composite_under's, in the same order, so the
 * pixels' results are those of the layered walk bit for bit. */
#define ST_ROW_WEIGHTS (int8)(1, 2, 4, 8, 16, 32, 64, 128)
/* How many bin entries ahead the plain walk prefetches: further than the layered walk
 * (ST_CELLS_SERIAL_AHEAD), its visits being cheaper; a tile's first records are fetched before
 * its walk (at 1024x1024, composite: builtin:spheres:96 187-193 -> 179-180 ms, the horse
 * 3.43-3.61 -> 3.29-3.40). */
#define ST_CELLS_PLAIN_AHEAD 24
/* Fetches what the plain walk reads of record rec: the record, its group and, unless the record
 * carries it, its colour. */
inline __attribute__((always_inline)) void st_cells_plain_prefetch(
    __global const StTriSetup* records, __global const uint* record_group,
    __global const float4* record_color, const int colour_in_record, const uint rec) {
  if (!colour_in_record) ST_PREFETCH(&record_color[rec]);
  ST_PREFETCH(&record_group[rec]);
  ST_PREFETCH(&records[rec]);
}

inline __attribute__((always_inline)) void st_cells_plain_rows(
    float* red, float* green, float* blue, float* trans, uint* depth, ulong covered, int row0,
    int row1, const float4 c) {
  const float keep = 1.0f - c.w;
  for (int y = row0; y <= row1; ++y) {
    const uint bits = (uint)(covered >> (y * ST_TILE_SIZE)) & 0xFFu;
    if (bits == 0) continue;
    const int8 sel = ((int8)(int)bits & ST_ROW_WEIGHTS) != (int8)(0);
    const float8 t = vload8(y, trans);
    const float8 r = vload8(y, red), g = vload8(y, green), b = vload8(y, blue);
    vstore8(select(r, r + t * c.w * c.x, sel), y, red);
    vstore8(select(g, g + t * c.w * c.y, sel), y, green);
    vstore8(select(b, b + t * c.w * c.z, sel), y, blue);
    vstore8(select(t, t * keep, sel), y, trans);
    vstore8(vload8(y, depth) - as_uint8(sel), y, depth); /* sel is -1 where covered */
  }
}

inline __attribute__((always_inline)) void st_cells_plain_tile(
    __global const StTriSetup* records, __global const uint* record_group,
    __global const float4* record_color, const int colour_in_record,
    __global const uint* bin_entries, const uint begin, const uint end, const int tx,
    const int ty, __constant StViewConstants* view,
    __local ulong* layers, const uint k_capacity, __global ushort4* accum,
    __global float2* accum_extra, const int first_batch, const int last_batch,
    __global uchar4* image, __global ulong* counters, __global uint* pixel_fragments,
    uint* fragments, uint* deepest_pixel, uint* deepest_group) {
  float red[ST_TILE_PIXELS], green[ST_TILE_PIXELS], blue[ST_TILE_PIXELS], trans[ST_TILE_PIXELS];
  uint depth[ST_TILE_PIXELS], count[ST_TILE_PIXELS], begin_count[ST_TILE_PIXELS];
  for (int y = 0; y < ST_TILE_SIZE; ++y) {
    vstore8((float8)(0.0f), y, red);
    vstore8((float8)(0.0f), y, green);
    vstore8((float8)(0.0f), y, blue);
    vstore8((float8)(1.0f), y, trans);
    vstore8((uint8)(0u), y, depth);
    vstore8((uint8)(0u), y, count);
    vstore8((uint8)(0u), y, begin_count);
  }
  const int width = view->width;
  ulong touched = 0;
  /* The list's first records, which the walk's own look-ahead does not reach. */
  for (uint e = begin; e < min(end, begin + ST_CELLS_PLAIN_AHEAD); ++e)
    st_cells_plain_prefetch(records, record_group, record_color, colour_in_record, bin_entries[e]);
  uint run_start = begin;
  while (run_start < end) {
    const uint pass = record_group[bin_entries[run_start]] & ST_CELLS_PASS_MASK;
    uint run_end = end;
    bool backs = false;
    ulong merged = 0; /* pixels holding a merged group's fragments */
    for (uint walk = 0; walk < 2; ++walk) {
      const uint stop = walk == 0 ? end : run_end;
      for (uint e = run_start; e < stop; ++e) {
        const uint rec = bin_entries[e];
        if (walk == 0 && e + ST_CELLS_PLAIN_AHEAD < end)
          st_cells_plain_prefetch(records, record_group, record_color, colour_in_record,
                                  bin_entries[e + ST_CELLS_PLAIN_AHEAD]);
        const uint tag = record_group[rec];
        if (walk == 0 && (tag & ST_CELLS_PASS_MASK) != pass) {
          run_end = e;
          break;
        }
        __global const StTriSetup* r = &records[rec];
        const bool single = (tag & ST_CELLS_SINGLE_CELL) != 0;
        /* The first walk takes a single cell's front records (and merged groups' records), the
         * second its back ones. */
        if (single && ((r->flags & ST_TRI_CELL_FRONT) != 0) != (walk == 0)) {
          backs = true;
          continue;
        }
        const int4 b = st_record_tile_rect(r, tx, ty);
        if (b.x > b.z || b.y > b.w) continue;
        ulong covered = st_tile_coverage_inline(r, tx, ty, b.x, b.y, b.z, b.w);
        if (covered == 0) continue;
        *fragments += (uint)popcount(covered);
        if (!first_batch) { /* an earlier batch's result at the pixels reached first */
          for (ulong fresh = covered & ~touched; fresh != 0; fresh &= fresh - 1ul) {
            const uint p = (uint)popcount((fresh & (0ul - fresh)) - 1ul);
            const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
            uint so_far;
            const StCellsPixel px =
                st_cells_pixel_begin(x, y, true, (uint)(y * width + x), first_batch, 1, view,
                                     accum, accum_extra, pixel_fragments, &so_far);
            red[p] = px.colour.x;
            green[p] = px.colour.y;
            blue[p] = px.colour.z;
            trans[p] = px.transmittance;
            depth[p] = begin_count[p] = so_far;
          }
        }
        touched |= covered;
        if (single) {
          st_cells_plain_rows(red, green, blue, trans, depth, covered, b.y - ty, b.w - ty,
                              colour_in_record ? st_cells_record_colour(r) : record_color[rec]);
          continue;
        }
        merged |= covered;
        const float2 origin = st_record_origin(r);
        for (; covered != 0; covered &= covered - 1ul) {
          const uint p = (uint)popcount((covered & (0ul - covered)) - 1ul);
          const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
          const uint slot = count[p]++;
          if (slot < k_capacity)
            layers[p * k_capacity + slot] =
                st_visibility_word(st_record_depth(r, origin, x, y), rec);
          else
            st_counter_claim(&counters[ST_COUNTER_FRAGMENTS_LOST], 1);
        }
      }
      if (!backs) break;
    }
    /* The merged groups' pixels: their fragments sorted, then composited (st_cells_flush). */
    for (; merged != 0; merged &= merged - 1ul) {
      const uint p = (uint)popcount((merged & (0ul - merged)) - 1ul);
      const uint n = count[p], kept = min(n, k_capacity);
      __local ulong* mine = layers + p * k_capacity;
      st_sort_layer_words(mine, kept);
      float3 colour = (float3)(red[p], green[p], blue[p]);
      float transmittance = trans[p];
      for (uint i = 0; i < kept; ++i)
        st_composite_under(&colour, &transmittance, record_color[(uint)mine[i]]);
      red[p] = colour.x;
      green[p] = colour.y;
      blue[p] = colour.z;
      trans[p] = transmittance;
      depth[p] += n;
      *deepest_group = max(*deepest_group, n);
      count[p] = 0;
    }
    run_start = run_end;
  }
  for (; touched != 0; touched &= touched - 1ul) {
    const uint p = (uint)popcount((touched & (0ul - touched)) - 1ul);
    const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
    StCellsPixel px;
    px.colour = (float3)(red[p], green[p], blue[p]);
    px.transmittance = trans[p];
    px.x = x;
    px.y = y;
    px.begin_count = begin_count[p];
    st_cells_pixel_end(&px, true, (uint)(y * width + x), last_batch, 1, view, accum,
                       accum_extra, image, pixel_fragments, depth[p]);
    *deepest_pixel = max(*deepest_pixel, depth[p]);
  }
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void cells_composite_serial(CELLS_COMPOSITE_PARAMS) {
  StCellsPixel px[ST_TILE_PIXELS];
  ulong front[ST_TILE_PIXELS], back[ST_TILE_PIXELS]; /* 0 = empty */
  uint count[ST_TILE_PIXELS], depth_count[ST_TILE_PIXELS];
  /* The order check's: the record of the last fragment each pixel composited, and a bound of
   * its depth (st_cells_serial_ascends). */
  uint last_rec[ST_TILE_PIXELS];
  float last_hi[ST_TILE_PIXELS];
  const int width = view->width, height = view->height;
  const uint tiles_y = ((uint)height + ST_TILE_SIZE - 1) / ST_TILE_SIZE;
  uint deepest_group = 0, deepest_repair = 0, fragments = 0, deepest_pixel = 0, flagged = 0,
       flagged_pixels = 0;
  const bool check = order_check == ST_CELLS_ORDER_CHECK;
  const bool depth_free_layers =
      layer_write == ST_CELLS_LAYER_STORE && view->effect != ST_EFFECT_TRANSLUCENCY;
  const bool plain = !view->textured && view->effect != ST_EFFECT_TRANSLUCENCY;
  /* Tiles the plain composite takes (st_cells_plain_tile); the others take the layered walk. */
  const bool plain_tiles = plain && !check && layer_write == ST_CELLS_LAYER_STORE &&
                           background_filled;
  StBlockDeal deal = st_block_deal_begin();
  uint block_x, block_y;
  while (st_block_deal_next(&deal, block_range, &batch_counters[ST_CELLS_BATCH_NEXT_BLOCK],
                            &block_x, &block_y)) {
    const uint block_tiles = st_block_tile_count(background_filled, chunk_offsets, chunks, tiles_x,
                                                 tiles_y, bin_capacity, block_x, block_y);
    for (uint sub = 0; sub < block_tiles; ++sub) {
      const StBlockTile bt = st_block_tile_at(chunk_offsets, chunks, bin_capacity, tiles_x,
                                              tiles_y, block_x, block_y, sub);
      const bool tile_valid = bt.valid;
      ulong redo = ~0ul; /* the pixels the walk composites: the flagged ones when it repairs */
      const uint begin = bt.begin, end = bt.end;
      if (begin == end && background_filled) continue;
      const int tx = (int)(bt.x * ST_TILE_SIZE), ty = (int)(bt.y * ST_TILE_SIZE);
      if (plain_tiles) {
        st_cells_plain_tile(records, record_group, record_color, colour_in_record, bin_entries,
                            begin, end, tx, ty, view, layers, k_capacity, accum, accum_extra,
                            first_batch, last_batch, image, counters, pixel_fragments, &fragments,
                            &deepest_pixel, &deepest_group);
        continue;
      }
      /* A checked tile whose check fails is repaired at once by a second walk of its list (its
       * records still in the cache), as the repair launch does for the group kernel: only the
       * flagged pixels, every fragment of a pixel sorted in the k-buffer (which the host sizes
       * for the repair too). A frame of one batch only, whose other pixels need no state. So this
       * kernel is never launched to repair (ST_CELLS_ORDER_REPAIR) and leaves tile_flags alone. */
      for (uint walk = 0; walk < 2; ++walk) {
        const bool check_walk = check && walk == 0, repair_walk = walk == 1;
        uint* deepest = repair_walk ? &deepest_repair : &deepest_group;
        ulong disordered = 0; /* the pixels where the order check failed */
        /* With the background already written only the pixels a fragment reaches need a state:
         * set up on its first fragment, finished at the end. Otherwise every pixel carries its
         * accumulator through the batch. */
        ulong untouched = background_filled ? ~0ul : 0ul;
        /* The groups' ranks never decrease along the list (drawing order): the pixels reached by
         * the current group so far hold it. */
        uint current_group = 0xFFFFFFFFu;
        ulong in_group = 0;
        for (uint p = 0; p < ST_TILE_PIXELS; ++p) {
          front[p] = back[p] = 0;
          count[p] = 0;
          last_rec[p] = ST_CELLS_NO_RECORD;
          last_hi[p] = 0.0f;
          if (background_filled) continue;
          const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
          const bool inside_image = tile_valid && x < width && y < height;
          px[p] = st_cells_pixel_begin(x, y, inside_image,
                                       inside_image ? (uint)(y * width + x) : 0u, first_batch,
                                       background_filled, view, accum, accum_extra,
                                       pixel_fragments, &depth_count[p]);
        }
        for (uint e = begin; e < end; ++e) {
          const uint rec = bin_entries[e];
          /* The records a tile lists are scattered; alone on its tiles, the item can look further
           * ahead than the group's walk (a record is one cache line), and fetches the record's
           * colour too, which the pixel's composite reads later. */
          if (e + ST_CELLS_SERIAL_AHEAD < end) {
            const uint ahead_rec = bin_entries[e + ST_CELLS_SERIAL_AHEAD];
            ST_PREFETCH(&record_color[ahead_rec]);
            ST_PREFETCH(&record_group[ahead_rec]);
            if (check_walk) ST_PREFETCH(&record_depths[ahead_rec]);
            ST_PREFETCH(&records[ahead_rec]);
          }
          __global const StTriSetup* r = &records[rec];
          const int4 b = st_record_tile_rect(r, tx, ty);
          if (b.x > b.z || b.y > b.w) continue;
          /* The repair skips a record whose rectangle holds no flagged pixel, before its
           * coverage. */
          if (repair_walk && !(st_tile_rect_mask(b.x - tx, b.y - ty, b.z - tx, b.w - ty) & redo))
            continue;
          ulong covered = st_tile_coverage(r, tx, ty, b.x, b.y, b.z, b.w) & redo;
          if (covered == 0) continue;
          /* The repair takes the whole list as one group: every fragment of a pixel sorted. */
          const uint tag = repair_walk ? 0u : record_group[rec];
          const uint group = tag & ST_CELLS_PASS_MASK; /* the group's rank */
          const bool single = (tag & ST_CELLS_SINGLE_CELL) != 0;
          const bool cell_front = (r->flags & ST_TRI_CELL_FRONT) != 0;
          /* The pixels meeting this group for the first time: their held group (if any) is done. */
          if (group != current_group) {
            current_group = group;
            in_group = 0;
          }
          for (ulong fresh = covered & ~in_group; fresh != 0; fresh &= fresh - 1ul) {
            const uint p = (uint)popcount((fresh & (0ul - fresh)) - 1ul); /* lowest set bit */
            if (untouched >> p & 1ul) { /* the pixel's first fragment */
              untouched &= ~(1ul << p);
              const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
              px[p] = st_cells_pixel_begin(x, y, true, (uint)(y * width + x), first_batch,
                                           background_filled, view, accum, accum_extra,
                                           pixel_fragments, &depth_count[p]);
            } else { /* a later group reaches the pixel: the held one is done */
              depth_count[p] += st_cells_serial_flush(
                  p, px, front, back, count, deepest, layers, k_capacity, records, record_color,
                  record_normal, tex_tris, atlas, view, check_walk, record_depths, last_rec,
                  last_hi, tx, ty, &disordered, plain);
            }
          }
          in_group |= covered;
          if (!repair_walk) fragments += (uint)popcount(covered); /* the check counted them */
          if (single && depth_free_layers) {
            /* A strict cell's layers are stored, not compared, and only translucency composites
             * by depth: the word needs no depth (a division per fragment), only a non-zero
             * marker above the record. */
            const ulong word = ST_CELLS_DEPTH_FREE_WORD | (ulong)rec;
            ulong* layer = cell_front ? front : back;
            const ulong stored = cell_front ? ~word : word;
            for (; covered != 0; covered &= covered - 1ul) {
              const uint p = (uint)popcount((covered & (0ul - covered)) - 1ul);
              /* The order check: a strict cell has one fragment per layer and pixel, and another
               * group's was flushed first, so a filled layer here would be overwritten. */
              if (check_walk && (layer[p] | count[p])) disordered |= 1ul << p;
              layer[p] = stored;
            }
            continue;
          }
          const float2 origin = st_record_origin(r);
          while (covered != 0) {
            const uint p = (uint)popcount((covered & (0ul - covered)) - 1ul);
            covered &= covered - 1ul;
            const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
            const ulong word = st_visibility_word(st_record_depth(r, origin, x, y), rec);
            if (single) {
              /* A strict cell has one fragment per layer and pixel, and another group's was flushed
               * first: a filled layer here would be overwritten (kept as a safety net). */
              if (check_walk && ((cell_front ? front[p] : back[p]) | count[p]))
                disordered |= 1ul << p;
              if (cell_front) {
                front[p] = layer_write == ST_CELLS_LAYER_STORE ? ~word : max(front[p], ~word);
              } else {
                back[p] = layer_write == ST_CELLS_LAYER_STORE ? word : max(back[p], word);
              }
            } else {
              if (check_walk && (front[p] | back[p])) disordered |= 1ul << p;
              const uint slot = count[p]++;
              if (slot < k_capacity) layers[p * k_capacity + slot] = word;
              else st_counter_claim(&counters[ST_COUNTER_FRAGMENTS_LOST], 1);
            }
          }
        }
        for (ulong live = ~untouched; live != 0; live &= live - 1ul) {
          const uint p = (uint)popcount((live & (0ul - live)) - 1ul);
          const int x = tx + (int)(p & (ST_TILE_SIZE - 1)), y = ty + (int)(p >> ST_TILE_LOG2);
          const bool inside_image = tile_valid && x < width && y < height;
          depth_count[p] += st_cells_serial_flush(p, px, front, back, count, deepest, layers,
                                                  k_capacity, records, record_color, record_normal,
                                                  tex_tris, atlas, view, check_walk, record_depths,
                                                  last_rec, last_hi, tx, ty, &disordered, plain);
          st_cells_pixel_end(&px[p], inside_image, inside_image ? (uint)(y * width + x) : 0u,
                             last_batch, background_filled, view, accum, accum_extra, image,
                             pixel_fragments, depth_count[p]);
          deepest_pixel = max(deepest_pixel, depth_count[p]);
        }
        if (disordered) {
          ++flagged;
          flagged_pixels += (uint)popcount(disordered);
        }
        if (!check_walk || !disordered || !background_filled || !first_batch || !last_batch) break;
        redo = disordered;
      }
    }
  }
  if (flagged) {
    st_counter_add(&counters[ST_COUNTER_CELLS_REPAIR_TILES], (ulong)flagged);
    st_counter_add(&counters[ST_COUNTER_CELLS_REPAIR_PIXELS], (ulong)flagged_pixels);
  }
  st_report_counts_alone(counters, fragments, deepest_pixel);
  if (deepest_group) st_counter_max(&counters[ST_COUNTER_CELLS_GROUP_DEPTH], (ulong)deepest_group);
  if (deepest_repair) st_counter_max(&counters[ST_COUNTER_CELLS_REPAIR_DEPTH], (ulong)deepest_repair);
}
