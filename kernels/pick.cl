/* pick.cl: ID picking (engine/features/picking.cpp). The frame's ID buffers stay on the device: the
 * visibility buffer of raster_visibility ((depth bits << 32) | triangle id, the nearest fragment
 * per pixel) and, for all layers, the per-pixel linked lists of ppll_build. These kernels read
 * back only what a query asks for: the words of a list of pixels, the sorted fragments of those
 * pixels' lists, or the set of objects front-most in a rectangle. */

inline bool st_pick_inside(int2 p, int width, int height) {
  return p.x >= 0 && p.y >= 0 && p.x < width && p.y < height;
}

/* The visibility word of each asked pixel (ST_VISIBILITY_EMPTY: background or outside). */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void pick_front(__global const ulong* visibility, const int width, const int height,
                __global const int2* pixels, const uint count, __global ulong* words) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const int2 p = pixels[i];
  words[i] = st_pick_inside(p, width, height) ? visibility[(size_t)p.y * width + p.x]
                                              : ST_VISIBILITY_EMPTY;
}

/* Every fragment of each asked pixel's linked list as a word like the visibility buffer's
 * (depth bits above the triangle id), so ascending words are the (depth, id) order in which
 * ppll_resolve composites them. A work-item reserves room for its list with one atomic on
 * `used`, stores where its fragments start and how many there are, and, when the output holds
 * them, writes them and sorts them in place (insertion sort: lists are short; exact either way).
 * If `used` ends above `capacity`, the host grows the output to it and runs the kernel again. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void pick_layers(__global const uint* heads, __global const StPpllNode* nodes, const int width,
                 const int height, __global const int2* pixels, const uint count,
                 __global ulong* first, __global uint* counts, __global ulong* fragments,
                 const ulong capacity, __global ulong* used) {
  const uint i = get_global_id(0);
  if (i >= count) return;
  const int2 p = pixels[i];
  const uint head = st_pick_inside(p, width, height) ? heads[(size_t)p.y * width + p.x]
                                                     : ST_PPLL_END;
  uint n = 0;
  for (uint k = head; k != ST_PPLL_END; k = nodes[k].next) ++n;
  const ulong base = n ? st_counter_claim(used, (ulong)n) : 0;
  first[i] = base;
  counts[i] = n;
  if (n == 0 || base + n > capacity) return;
  uint m = 0;
  for (uint k = head; k != ST_PPLL_END; k = nodes[k].next) {
    const ulong word = st_visibility_word(nodes[k].depth, nodes[k].source);
    uint j = m;
    while (j > 0 && fragments[base + j - 1] > word) {
      fragments[base + j] = fragments[base + j - 1];
      --j;
    }
    fragments[base + j] = word;
    ++m;
  }
}

/* Rectangle queries, step 1: marks the run (a stretch of triangles of one object, from the host)
 * of the front-most triangle of every pixel of the rectangle (x0, y0, rect_w x rect_h). */
__kernel void pick_rect_mark(__global const ulong* visibility, const int width, const int x0,
                             const int y0, const int rect_w, const int rect_h,
                             __global const uint* triangle_run, __global uint* run_seen) {
  const int x = get_global_id(0), y = get_global_id(1);
  if (x >= rect_w || y >= rect_h) return;
  const ulong word = visibility[(size_t)(y0 + y) * width + (x0 + x)];
  if (word == ST_VISIBILITY_EMPTY) return;
  const uint run = triangle_run[(uint)word];
  if (run_seen[run] == 0u) run_seen[run] = 1u; /* test first: most pixels repeat a run */
}

/* Step 2: the marked runs, compacted (in no particular order; the host sorts). */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void pick_rect_compact(__global const uint* run_seen, const uint run_count, __global uint* runs,
                       __global uint* found) {
  const uint i = get_global_id(0);
  if (i < run_count && run_seen[i]) runs[atomic_inc(found)] = i;
}
