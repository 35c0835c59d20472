/* bin.cl: tile binning. Each setup record is listed in every screen tile its pixel bounds touch
 * (setup counts them, then an exclusive scan and the fill), so a raster work-group walks only
 * its own tile's triangles. The serial form (CPU devices) counts and fills without atomics:
 * the records are cut into `chunks` contiguous runs, one work-item counts (then fills) its own
 * column of a tile x chunk table, and the scan of that table in (tile, chunk) order gives every
 * run its place in every tile's list, so each list holds its records in slot order. The counts
 * and cursors are stored run by run (st_run_slot), the offsets tile by tile. */

/* The count (and cursor) of scan position i of a table of n = tile_count x runs entries, scanned
 * in (tile, run) order. */
inline uint st_scan_source(uint i, uint n, uint runs) {
  const uint tile = i / runs;
  return st_run_slot(tile, i - tile * runs, n / runs);
}

/* Number of setup record slots in use this frame: one per source triangle, then the overflow
 * pieces of clipped triangles. */
inline uint st_record_count(__global const ulong* counters, uint triangle_count,
                            uint overflow_capacity) {
  return triangle_count +
         (uint)min(counters[ST_COUNTER_SETUP_OVERFLOW], (ulong)overflow_capacity);
}

/* Exclusive scan of tile counts by one work-group: offsets[0..n], offsets[n] = total. The fill
 * cursors start at the offsets. A table of `runs` runs per tile (the serial binners') is read,
 * and its cursors written, run by run (st_scan_source); runs = 1: a plain list of tiles. Where
 * a work-group's items run one after another (ST_WORK_ITEMS_IN_TURN: PoCL's CPU devices), each
 * item sums and then scans its own contiguous run of the counts. Elsewhere (GPUs) those runs
 * made every load of a warp touch a different cache line, twice over the whole table (0.05 ms of
 * a 0.25 ms frame on an H200), so the counts go through local memory in blocks loaded and stored
 * whole: each item scans its run of a block there, and the items' totals are scanned by the
 * work-group (Hillis-Steele). */
#ifdef ST_WORK_ITEMS_IN_TURN
__kernel __attribute__((reqd_work_group_size(ST_SCAN_WG, 1, 1)))
void bin_scan(__global const uint* tile_counts, const uint tile_count,
              __global uint* tile_offsets, __global uint* tile_cursors,
              __global ulong* counters, const uint runs) {
  __local uint partial[ST_SCAN_WG];
  const uint lid = get_local_id(0);
  const uint chunk = (tile_count + ST_SCAN_WG - 1) / ST_SCAN_WG;
  const uint begin = min(lid * chunk, tile_count), end = min(begin + chunk, tile_count);
  /* Position i is run c of tile t: stepped, not divided, per entry. */
  const uint tiles = tile_count / runs, first_tile = begin / runs;
  const uint first_run = begin - first_tile * runs;
  uint sum = 0;
  for (uint i = begin, t = first_tile, c = first_run; i < end; ++i) {
    sum += tile_counts[st_run_slot(t, c, tiles)];
    if (++c == runs) {
      c = 0;
      ++t;
    }
  }
  partial[lid] = sum;
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid == 0) { /* 256 entries: a serial scan is cheaper than a tree here */
    uint run = 0;
    for (uint k = 0; k < ST_SCAN_WG; ++k) {
      const uint v = partial[k];
      partial[k] = run;
      run += v;
    }
    tile_offsets[tile_count] = run;
    counters[ST_COUNTER_BIN_ENTRIES] = run;
  }
  barrier(CLK_LOCAL_MEM_FENCE);
  uint run = partial[lid];
  for (uint i = begin, t = first_tile, c = first_run; i < end; ++i) {
    const uint source = st_run_slot(t, c, tiles);
    tile_offsets[i] = run;
    tile_cursors[source] = run;
    run += tile_counts[source];
    if (++c == runs) {
      c = 0;
      ++t;
    }
  }
}
#else
#define ST_SCAN_RUN 16                             /* counts per work-item in a block */
#define ST_SCAN_BLOCK (ST_SCAN_WG * ST_SCAN_RUN)   /* counts per block */
#define ST_SCAN_SLOT(i) ((i) + ((i) >> 5))         /* one word of padding per 32: no bank conflicts */
__kernel __attribute__((reqd_work_group_size(ST_SCAN_WG, 1, 1)))
void bin_scan(__global const uint* tile_counts, const uint tile_count,
              __global uint* tile_offsets, __global uint* tile_cursors,
              __global ulong* counters, const uint runs) {
  __local uint block[ST_SCAN_SLOT(ST_SCAN_BLOCK)];
  __local uint partial[ST_SCAN_WG];
  const uint lid = get_local_id(0);
  uint carry = 0; /* the counts of the blocks before; the same in every work-item */
  for (uint base = 0; base < tile_count; base += ST_SCAN_BLOCK) {
    for (uint i = lid; i < ST_SCAN_BLOCK; i += ST_SCAN_WG)
      block[ST_SCAN_SLOT(i)] =
          base + i < tile_count ? tile_counts[st_scan_source(base + i, tile_count, runs)] : 0u;
    barrier(CLK_LOCAL_MEM_FENCE);
    uint sum = 0;
    for (uint j = 0; j < ST_SCAN_RUN; ++j) sum += block[ST_SCAN_SLOT(lid * ST_SCAN_RUN + j)];
    partial[lid] = sum;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint d = 1; d < ST_SCAN_WG; d <<= 1) { /* inclusive scan of the runs' totals */
      const uint add = lid >= d ? partial[lid - d] : 0u;
      barrier(CLK_LOCAL_MEM_FENCE);
      partial[lid] += add;
      barrier(CLK_LOCAL_MEM_FENCE);
    }
    uint run = carry + partial[lid] - sum;
    for (uint j = 0; j < ST_SCAN_RUN; ++j) {
      const uint slot = ST_SCAN_SLOT(lid * ST_SCAN_RUN + j);
      const uint v = block[slot];
      block[slot] = run;
      run += v;
    }
    carry += partial[ST_SCAN_WG - 1];
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint i = lid; i < ST_SCAN_BLOCK && base + i < tile_count; i += ST_SCAN_WG) {
      const uint offset = block[ST_SCAN_SLOT(i)];
      tile_offsets[base + i] = offset;
      tile_cursors[st_scan_source(base + i, tile_count, runs)] = offset;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  if (lid == 0) {
    tile_offsets[tile_count] = carry;
    counters[ST_COUNTER_BIN_ENTRIES] = carry;
  }
}
#endif

/* Lists every record in the tiles its packed pixel bounds (setup.cl) touch. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void bin_fill(__global const uint2* bounds, const uint triangle_count,
              const uint overflow_capacity, __global const ulong* counters, const uint tiles_x,
              __global const uint* tile_offsets, __global uint* tile_cursors,
              __global uint* bin_entries, const uint bin_capacity) {
  const uint i = get_global_id(0);
  if (i >= st_record_count(counters, triangle_count, overflow_capacity)) return;
  uint tx0, tx1, ty0, ty1;
  if (!st_bounds_tiles(bounds[i], &tx0, &tx1, &ty0, &ty1)) return; /* culled */
  for (uint ty = ty0; ty <= ty1; ++ty) {
    for (uint tx = tx0; tx <= tx1; ++tx) {
      const uint tile = ty * tiles_x + tx;
      const uint slot = atomic_inc(&tile_cursors[tile]);
      /* Within the tile's own range even if a slot's bounds were not counted this frame. */
      if (slot < min(tile_offsets[tile + 1], bin_capacity)) bin_entries[slot] = i;
    }
  }
}

/* Serial form: the records [begin, end) of run c of `chunks`. */
inline void st_bin_run(__global const ulong* counters, uint triangle_count, uint overflow_capacity,
                       uint chunks, uint c, uint* begin, uint* end) {
  const uint records = st_record_count(counters, triangle_count, overflow_capacity);
  const uint per_chunk = (records + chunks - 1) / chunks;
  *begin = min(c * per_chunk, records);
  *end = min(*begin + per_chunk, records);
}

/* Serial form, one body for both steps: chunk c counts its records' tiles in column c of the
 * tile x chunk table (`table` holds the counts), or lists its records, in slot order, from its
 * cursor in every tile (`table` holds the cursors). */
inline __attribute__((always_inline)) void bin_serial_run(
    bool fill, __global const uint2* bounds, uint triangle_count, uint overflow_capacity,
    __global const ulong* counters, uint chunks, uint tiles_x, uint tile_count,
    __global uint* table, __global uint* bin_entries, uint bin_capacity) {
  const uint c = get_global_id(0);
  uint begin, end;
  st_bin_run(counters, triangle_count, overflow_capacity, chunks, c, &begin, &end);
  for (uint i = begin; i < end; ++i) {
    uint tx0, tx1, ty0, ty1;
    if (!st_bounds_tiles(bounds[i], &tx0, &tx1, &ty0, &ty1)) continue;
    for (uint ty = ty0; ty <= ty1; ++ty) {
      for (uint tx = tx0; tx <= tx1; ++tx) {
        const uint slot = table[st_run_slot(ty * tiles_x + tx, c, tile_count)]++;
        if (fill && slot < bin_capacity) bin_entries[slot] = i;
      }
    }
  }
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bin_count_serial(__global const uint2* bounds, const uint triangle_count,
                      const uint overflow_capacity, __global const ulong* counters,
                      const uint chunks, const uint tiles_x, const uint tile_count,
                      __global uint* chunk_counts) {
  bin_serial_run(false, bounds, triangle_count, overflow_capacity, counters, chunks, tiles_x,
                 tile_count, chunk_counts, 0, 0u);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void bin_fill_serial(__global const uint2* bounds, const uint triangle_count,
                     const uint overflow_capacity, __global const ulong* counters,
                     const uint chunks, const uint tiles_x, const uint tile_count,
                     __global uint* chunk_cursors, __global uint* bin_entries,
                     const uint bin_capacity) {
  bin_serial_run(true, bounds, triangle_count, overflow_capacity, counters, chunks, tiles_x,
                 tile_count, chunk_cursors, bin_entries, bin_capacity);
}

/* Serial form: every tile's list offsets (tile_count + 1 of them) from the scanned table. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void bin_tile_offsets(__global const uint* chunk_offsets, const uint chunks, const uint tile_count,
                      __global uint* tile_offsets) {
  const uint t = get_global_id(0);
  if (t <= tile_count) tile_offsets[t] = chunk_offsets[t * chunks];
}
