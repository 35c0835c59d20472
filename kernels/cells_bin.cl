/* cells_bin.cl: ordered tile binning for the convex-cells and octree methods. A tile's list must
 * keep the batch's slot order (visibility order), which atomic appends do not. Two forms give the
 * same lists. Serial (CPU devices): the slots are cut into `chunks` contiguous runs; one
 * work-item walks a run in order and counts (then fills) its own column of a tile x chunk table,
 * without atomics; an exclusive scan of the table in (tile, chunk) order (bin_scan) gives every
 * run its place in every tile's list, in order. Group (GPUs, where a few dozen serial walkers
 * leave the device idle): a work-item per slot counts and appends with atomics, each entry keyed
 * by its slot, and a work-group per tile sorts the tile's keys (bitonic, in local memory). */

/* Record j of slot s: the slot's own (j = 0), then its slot_extra[s].y extra pieces. */
inline uint cells_slot_record(__global const uint2* slot_extra, uint s, uint j,
                              uint batch_capacity) {
  return j == 0 ? s : batch_capacity + slot_extra[s].x + j - 1;
}

/* Piece j of slot s: its record and the tiles its packed bounds touch; false for a piece that
 * was not stored (past the overflow capacity) or an empty one. */
inline __attribute__((always_inline)) bool st_slot_piece_tiles(
    __global const uint2* record_bounds, __global const uint2* slot_extra, uint s, uint j,
    uint batch_capacity, uint overflow_capacity, uint* rec, uint* tx0, uint* tx1, uint* ty0,
    uint* ty1) {
  *rec = cells_slot_record(slot_extra, s, j, batch_capacity);
  return *rec < batch_capacity + overflow_capacity &&
         st_bounds_tiles(record_bounds[*rec], tx0, tx1, ty0, ty1);
}

/* Both passes of both forms, one body (`fill` and `serial` literals at each kernel). Serial: the
 * work-item of run c walks its slots in order and, per tile of each stored piece, counts it in
 * its column of the table (`table` holds the counts) or writes the piece's record at its cursor
 * there (`table` holds the cursors). Group: a work-item per slot counts its records' tiles
 * (`table` holds the counts), or appends its records to their tiles' lists in any order (`table`
 * holds the cursors), each as the key (slot << 32 | record), which sorts a tile's list into slot
 * order (a slot's own record before its extra pieces, which were reserved in order). */
inline __attribute__((always_inline)) void cells_bin_pass(
    bool fill, bool serial, __global const uint2* record_bounds, __global const uint2* slot_extra,
    uint batch_triangles, uint batch_capacity, uint overflow_capacity, uint chunk_slots,
    uint tiles_x, uint tile_count, __global uint* table, __global const uint* tile_offsets,
    __global uint* bin_entries, __global ulong* bin_keys, uint bin_capacity) {
  const uint c = get_global_id(0);
  const uint begin = serial ? c * chunk_slots : c;
  const uint end = min(serial ? begin + chunk_slots : c + 1, batch_triangles);
  for (uint s = begin; s < end; ++s) {
    for (uint j = 0, n = 1u + slot_extra[s].y; j < n; ++j) {
      uint rec, tx0, tx1, ty0, ty1;
      if (!st_slot_piece_tiles(record_bounds, slot_extra, s, j, batch_capacity, overflow_capacity,
                               &rec, &tx0, &tx1, &ty0, &ty1))
        continue;
      for (uint ty = ty0; ty <= ty1; ++ty) {
        for (uint tx = tx0; tx <= tx1; ++tx) {
          const uint tile = ty * tiles_x + tx;
          if (serial) {
            const uint at = table[st_run_slot(tile, c, tile_count)]++;
            if (fill && at < bin_capacity) bin_entries[at] = rec;
          } else {
            const uint at = atomic_inc(&table[tile]);
            if (fill && at < min(tile_offsets[tile + 1], bin_capacity))
              bin_keys[at] = ((ulong)s << 32) | (ulong)rec;
          }
        }
      }
    }
  }
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void cells_bin_count(__global const uint2* record_bounds, __global const uint2* slot_extra,
                     const uint batch_triangles, const uint batch_capacity,
                     const uint overflow_capacity, const uint chunk_slots, const uint chunks,
                     const uint tiles_x, const uint tile_count, __global uint* chunk_counts) {
  cells_bin_pass(false, true, record_bounds, slot_extra, batch_triangles, batch_capacity,
                 overflow_capacity, chunk_slots, tiles_x, tile_count, chunk_counts, 0, 0, 0, 0u);
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void cells_bin_fill(__global const uint2* record_bounds, __global const uint2* slot_extra,
                    const uint batch_triangles, const uint batch_capacity,
                    const uint overflow_capacity, const uint chunk_slots, const uint chunks,
                    const uint tiles_x, const uint tile_count, __global uint* chunk_cursors,
                    __global const uint* chunk_offsets, const uint table_size,
                    __global uint* bin_entries, const uint bin_capacity,
                    __global ulong* counters) {
  if (get_global_id(0) == 0)
    st_counter_max(&counters[ST_COUNTER_CELLS_ENTRIES], (ulong)chunk_offsets[table_size]);
  cells_bin_pass(true, true, record_bounds, slot_extra, batch_triangles, batch_capacity,
                 overflow_capacity, chunk_slots, tiles_x, tile_count, chunk_cursors, 0, bin_entries,
                 0, bin_capacity);
}

__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void cells_bin_count_atomic(__global const uint2* record_bounds, __global const uint2* slot_extra,
                            const uint batch_triangles, const uint batch_capacity,
                            const uint overflow_capacity, const uint tiles_x,
                            __global uint* tile_counts) {
  cells_bin_pass(false, false, record_bounds, slot_extra, batch_triangles, batch_capacity,
                 overflow_capacity, 0u, tiles_x, 0u, tile_counts, 0, 0, 0, 0u);
}

__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void cells_bin_fill_atomic(__global const uint2* record_bounds, __global const uint2* slot_extra,
                           const uint batch_triangles, const uint batch_capacity,
                           const uint overflow_capacity, const uint tiles_x,
                           __global uint* tile_cursors, __global const uint* tile_offsets,
                           const uint tile_count, __global ulong* bin_keys,
                           const uint bin_capacity, __global ulong* counters) {
  if (get_global_id(0) == 0)
    st_counter_max(&counters[ST_COUNTER_CELLS_ENTRIES], (ulong)tile_offsets[tile_count]);
  cells_bin_pass(true, false, record_bounds, slot_extra, batch_triangles, batch_capacity,
                 overflow_capacity, 0u, tiles_x, tile_count, tile_cursors, tile_offsets, 0, bin_keys,
                 bin_capacity);
}

/* Sorts keys[0, size) ascending (size a power of two, at most ST_BIN_SORT_KEYS) by the
 * work-group: bitonic, each compare-exchange done by the work-item of its lower index. */
inline void st_bitonic_sort_local(__local ulong* keys, const uint size) {
  const uint lid = get_local_id(0);
  for (uint k = 2; k <= size; k <<= 1) {
    for (uint j = k >> 1; j > 0; j >>= 1) {
      for (uint i = lid; i < size; i += ST_BIN_SORT_WG) {
        const uint partner = i ^ j;
        if (partner > i) {
          const ulong a = keys[i], b = keys[partner];
          if ((a > b) == ((i & k) == 0)) {
            keys[i] = b;
            keys[partner] = a;
          }
        }
      }
      barrier(CLK_LOCAL_MEM_FENCE);
    }
  }
}

/* Keys of run[0, n) below `key` (the run sorted ascending). */
inline uint st_keys_below(__global const ulong* run, uint n, const ulong key) {
  uint lo = 0;
  while (n > 0) {
    const uint step = n >> 1;
    if (run[lo + step] < key) {
      lo += step + 1;
      n -= step + 1;
    } else {
      n = step;
    }
  }
  return lo;
}

/* Group form: a work-group per tile puts the tile's keyed entries in slot order and writes their
 * records to bin_entries. A list of up to ST_BIN_SORT_KEYS is sorted in local memory; a longer
 * one is sorted in runs of that size, written back, and each entry then placed at its rank (the
 * keys are distinct: a record is listed once per tile), found by binary search in the other runs. */
__kernel __attribute__((reqd_work_group_size(ST_BIN_SORT_WG, 1, 1)))
void cells_bin_sort(__global ulong* bin_keys, __global const uint* tile_offsets,
                    const uint bin_capacity, __global uint* bin_entries) {
  __local ulong keys[ST_BIN_SORT_KEYS];
  const uint tile = get_group_id(0), lid = get_local_id(0);
  const uint begin = min(tile_offsets[tile], bin_capacity);
  const uint n = min(tile_offsets[tile + 1], bin_capacity) - begin;
  for (uint run = 0; run < n; run += ST_BIN_SORT_KEYS) {
    const uint m = min(n - run, (uint)ST_BIN_SORT_KEYS);
    uint size = 2;
    while (size < m) size <<= 1;
    for (uint i = lid; i < size; i += ST_BIN_SORT_WG)
      keys[i] = i < m ? bin_keys[begin + run + i] : ULONG_MAX;
    barrier(CLK_LOCAL_MEM_FENCE);
    st_bitonic_sort_local(keys, size);
    if (n <= ST_BIN_SORT_KEYS) {
      for (uint i = lid; i < m; i += ST_BIN_SORT_WG) bin_entries[begin + i] = (uint)keys[i];
      return; /* the whole work-group: n is the tile's */
    }
    for (uint i = lid; i < m; i += ST_BIN_SORT_WG) bin_keys[begin + run + i] = keys[i];
    barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);
  }
  for (uint i = lid; i < n; i += ST_BIN_SORT_WG) {
    const ulong key = bin_keys[begin + i];
    const uint own = i / ST_BIN_SORT_KEYS * ST_BIN_SORT_KEYS;
    uint rank = i - own;
    for (uint run = 0; run < n; run += ST_BIN_SORT_KEYS)
      if (run != own)
        rank += st_keys_below(bin_keys + begin + run, min(n - run, (uint)ST_BIN_SORT_KEYS), key);
    bin_entries[begin + rank] = (uint)key;
  }
}
