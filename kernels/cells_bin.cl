/* cells_bin.cl: ordered tile binning for the convex-cells method. A tile's list must keep the
 * batch's slot order (visibility order), which atomic appends do not. So the slots are cut into
 * `chunks` contiguous runs; one work-item walks a run in order and counts (then fills) its own
 * column of a tile x chunk table, without atomics; an exclusive scan of the table in
 * (tile, chunk) order (bin_scan) gives every run its place in every tile's list, in order. */

/* Record j of slot s: the slot's own (j = 0), then its slot_extra[s].y extra pieces. */
inline uint cells_slot_record(__global const uint2* slot_extra, uint s, uint j,
                              uint batch_capacity) {
  return j == 0 ? s : batch_capacity + slot_extra[s].x + j - 1;
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void cells_bin_count(__global const uint2* record_bounds, __global const uint2* slot_extra,
                     const uint batch_triangles, const uint batch_capacity,
                     const uint overflow_capacity, const uint chunk_slots, const uint chunks,
                     const uint tiles_x, __global uint* chunk_counts) {
  const uint c = get_global_id(0);
  const uint begin = c * chunk_slots, end = min(begin + chunk_slots, batch_triangles);
  for (uint s = begin; s < end; ++s) {
    for (uint j = 0, n = 1u + slot_extra[s].y; j < n; ++j) {
      const uint rec = cells_slot_record(slot_extra, s, j, batch_capacity);
      if (rec >= batch_capacity + overflow_capacity) continue; /* a piece that was not stored */
      uint tx0, tx1, ty0, ty1;
      if (!st_bounds_tiles(record_bounds[rec], &tx0, &tx1, &ty0, &ty1)) continue; /* empty */
      for (uint ty = ty0; ty <= ty1; ++ty)
        for (uint tx = tx0; tx <= tx1; ++tx) ++chunk_counts[(ty * tiles_x + tx) * chunks + c];
    }
  }
}

__kernel __attribute__((reqd_work_group_size(1, 1, 1)))
void cells_bin_fill(__global const uint2* record_bounds, __global const uint2* slot_extra,
                    const uint batch_triangles, const uint batch_capacity,
                    const uint overflow_capacity, const uint chunk_slots, const uint chunks,
                    const uint tiles_x, __global uint* chunk_cursors,
                    __global const uint* chunk_offsets, const uint table_size,
                    __global uint* bin_entries, const uint bin_capacity,
                    __global ulong* counters) {
  const uint c = get_global_id(0);
  if (c == 0) atom_max(&counters[ST_COUNTER_CELLS_ENTRIES], (ulong)chunk_offsets[table_size]);
  const uint begin = c * chunk_slots, end = min(begin + chunk_slots, batch_triangles);
  for (uint s = begin; s < end; ++s) {
    for (uint j = 0, n = 1u + slot_extra[s].y; j < n; ++j) {
      const uint rec = cells_slot_record(slot_extra, s, j, batch_capacity);
      if (rec >= batch_capacity + overflow_capacity) continue; /* a piece that was not stored */
      uint tx0, tx1, ty0, ty1;
      if (!st_bounds_tiles(record_bounds[rec], &tx0, &tx1, &ty0, &ty1)) continue; /* empty */
      for (uint ty = ty0; ty <= ty1; ++ty) {
        for (uint tx = tx0; tx <= tx1; ++tx) {
          const uint slot = chunk_cursors[(ty * tiles_x + tx) * chunks + c]++;
          if (slot < bin_capacity) bin_entries[slot] = rec;
        }
      }
    }
  }
}
