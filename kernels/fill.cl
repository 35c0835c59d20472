/* fill.cl: buffer clears. A kernel rather than clEnqueueFillBuffer: the same on every driver,
 * and a store every checking tool sees (Oclgrind's uninitialised-value checker does not count a
 * fill as initialising memory). */

/* Sets words [0, count) of dst to `pattern`. */
__kernel __attribute__((reqd_work_group_size(ST_LINEAR_WG, 1, 1)))
void fill_words(__global uint* dst, const uint pattern, const ulong count) {
  const size_t i = get_global_id(0);
  if (i < count) dst[i] = pattern;
}

/* Sets every pixel of the image to the view's background and its fragment count to 0: the
 * image of a frame before a method draws only the tiles that hold something. */
__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void fill_background(__constant StViewConstants* view, __global uchar4* image,
                     __global uint* pixel_fragments) {
  const int x = get_global_id(0), y = get_global_id(1);
  const int width = view->width;
  if (x >= width || y >= view->height) return;
  image[y * width + x] = st_background_rgba8(view, x, y);
  pixel_fragments[y * width + x] = 0;
}
