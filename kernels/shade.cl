/* shade.cl: shading pass of the opaque method: visibility word -> triangle colour or background. */

__kernel __attribute__((reqd_work_group_size(ST_TILE_SIZE, ST_TILE_SIZE, 1)))
void shade_visibility(__global const ulong* visibility, __global const float4* triangle_colors, __global const StTexTriangle* tex_tris,
                 __global const uint* atlas,
                      __constant StViewConstants* view, __global uchar4* image) {
  const int x = get_global_id(0), y = get_global_id(1);
  const int width = view->width;
  if (x >= width || y >= view->height) return;
  const ulong word = visibility[y * width + x];
  const float3 c = word == ST_VISIBILITY_EMPTY ? st_background(view, x, y)
                                               : st_fragment_colour(triangle_colors, tex_tris, atlas, view, (uint)word, x, y).xyz;
  image[y * width + x] = st_pack_rgba8(c);
}
