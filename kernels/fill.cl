/* fill.cl: buffer clears. A kernel rather than clEnqueueFillBuffer: the same on every driver,
 * and a store every checking tool sees (Oclgrind's uninitialised-value checker does not count a
 * fill as initialising memory). */

/* Sets words [0, count) of dst to `pattern`. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void fill_words(__global uint* dst, const uint pattern, const ulong count) {
  const size_t i = get_global_id(0);
  if (i < count) dst[i] = pattern;
}
