/* texture.cl: base-colour texturing of a fragment from the texture atlas (engine/features/texture_atlas.h
 * describes the layout and the sampling rules; sampleAtlas there is the same code on the host).
 * Used by every method's resolve: the fragment's flat colour times the sampled texel. */

inline int st_mod_pos(int a, int n) {
  const int m = a % n;
  return m < 0 ? m + n : m;
}

inline int st_ceil_div_pow2(int a, int level) {
  const int s = 1 << level;
  return a >= 0 ? (a + s - 1) / s : -((-a) / s);
}

/* Bilinear setup on one axis: lower texel index (unwrapped) and the upper texel's weight. */
inline int st_bilinear_axis(float u, int n, float* f) {
  ST_NO_CONTRACT
  float x = clamp(u * (float)n - 0.5f, -16777216.0f, 16777216.0f);
  if (isnan(x)) x = 0.0f;
  const float fl = floor(x);
  *f = x - fl;
  return (int)fl;
}

inline int st_nearest_axis(float u, int n) {
  const float x = clamp(u * (float)n, -16777216.0f, 16777216.0f);
  return isnan(x) ? 0 : (int)floor(x);
}

/* Texel index of i under the wrap rule (nearest sampling). */
inline int st_wrap_index(int i, int n, int wrap) {
  if (wrap == ST_WRAP_REPEAT) return st_mod_pos(i, n);
  if (wrap == ST_WRAP_MIRRORED_REPEAT) {
    const int m = st_mod_pos(i, 2 * n);
    return m < n ? m : 2 * n - 1 - m;
  }
  return clamp(i, 0, n - 1);
}

/* Atlas-local indices of the two bilinear texels; -1 and n are the gutter, which holds the
 * wrapped texel of the same texture. */
inline int2 st_atlas_pair(int i0, int n, int wrap) {
  if (wrap == ST_WRAP_REPEAT) {
    const int a = st_mod_pos(i0, n);
    return (int2)(a, a + 1);
  }
  if (wrap == ST_WRAP_MIRRORED_REPEAT) {
    const int m = st_mod_pos(i0, 2 * n);
    if (m < n) return (int2)(m, m + 1);
    const int a = 2 * n - 1 - m;
    return (int2)(a, a - 1);
  }
  const int a = clamp(i0, -1, n - 1);
  return (int2)(a, a + 1);
}

inline float4 st_atlas_texel(__global const uint* texels, uint offset, int width, int x, int y) {
  const uint w = texels[offset + (uint)y * (uint)width + (uint)x];
  return convert_float4((uint4)(w & 255u, (w >> 8) & 255u, (w >> 16) & 255u, w >> 24)) *
         (1.0f / 255.0f);
}

/* One mip level of an atlas entry, nearest or bilinear. */
inline float4 st_atlas_level(__global const uint* texels, const StAtlasTexture* t,
                             __global const StAtlasPage* page, int level, bool linear, float u,
                             float v) {
  ST_NO_CONTRACT
  const int ox = st_ceil_div_pow2(t->cell_x, level) + 1;
  const int oy = st_ceil_div_pow2(t->cell_y, level) + 1;
  const int nx = max(1, t->width >> level), ny = max(1, t->height >> level);
  const int pw = max(1, page->width >> level);
  const uint offset = page->offset[level];
  if (!linear)
    return st_atlas_texel(texels, offset, pw, ox + st_wrap_index(st_nearest_axis(u, nx), nx, t->wrap_s),
                          oy + st_wrap_index(st_nearest_axis(v, ny), ny, t->wrap_t));
  float fx, fy;
  const int2 xs = st_atlas_pair(st_bilinear_axis(u, nx, &fx), nx, t->wrap_s) + ox;
  const int2 ys = st_atlas_pair(st_bilinear_axis(v, ny, &fy), ny, t->wrap_t) + oy;
  const float4 t00 = st_atlas_texel(texels, offset, pw, xs.x, ys.x);
  const float4 t10 = st_atlas_texel(texels, offset, pw, xs.y, ys.x);
  const float4 t01 = st_atlas_texel(texels, offset, pw, xs.x, ys.y);
  const float4 t11 = st_atlas_texel(texels, offset, pw, xs.y, ys.y);
  return (t00 * (1.0f - fx) + t10 * fx) * (1.0f - fy) + (t01 * (1.0f - fx) + t11 * fx) * fy;
}

/* Samples atlas entry `entry` at uv with screen derivatives duv (x: .s01, y: .s23): level from
 * the derivatives (lodFromDerivatives), then nearest / bilinear at round(lod) or trilinear. */
inline float4 st_sample_atlas(__global const uint* atlas, uint entry, float2 uv, float4 duv) {
  ST_NO_CONTRACT
  __global const StAtlasHeader* header = (__global const StAtlasHeader*)atlas;
  if (entry >= header->texture_count) return (float4)(1.0f);
  __global const StAtlasTexture* textures = (__global const StAtlasTexture*)(atlas + 4);
  const StAtlasTexture t = textures[entry];
  __global const StAtlasPage* page =
      (__global const StAtlasPage*)(atlas + 4 + header->texture_count * (uint)(sizeof(StAtlasTexture) / 4)) + t.page;
  __global const uint* texels = atlas + header->texel_word_offset;

  const float2 dx = (float2)(duv.s0 * (float)t.width, duv.s1 * (float)t.height);
  const float2 dy = (float2)(duv.s2 * (float)t.width, duv.s3 * (float)t.height);
  const float rho = max(length(dx), length(dy));
  const float top = (float)max(t.levels - 1, 0);
  float lod;
  if (!(rho > 0.0f) || !isfinite(rho)) lod = rho > 0.0f ? top : 0.0f;
  else lod = clamp(log2(rho), 0.0f, top);

  if (t.filter != ST_FILTER_TRILINEAR)
    return st_atlas_level(texels, &t, page, min((int)floor(lod + 0.5f), t.levels - 1),
                          t.filter == ST_FILTER_BILINEAR, uv.x, uv.y);
  const int l0 = (int)floor(lod);
  const int l1 = min(l0 + 1, t.levels - 1);
  const float w = lod - (float)l0;
  const float4 a = st_atlas_level(texels, &t, page, l0, true, uv.x, uv.y);
  if (w == 0.0f || l1 == l0) return a;
  const float4 b = st_atlas_level(texels, &t, page, l1, true, uv.x, uv.y);
  return a * (1.0f - w) + b * w;
}

/* The texel that multiplies the colour of source triangle `source`'s fragment at pixel (x, y):
 * (1, 1, 1, 1) unless the scene is textured and the triangle has a texture. */
inline float4 st_fragment_texel(__global const StTexTriangle* tex_tris, __global const uint* atlas,
                                __constant StViewConstants* view, uint source, int x, int y) {
  if (!view->textured) return (float4)(1.0f);
  __global const StTexTriangle* t = tex_tris + source;
  const uint entry = t->texture;
  if (entry == ST_NO_TEXTURE) return (float4)(1.0f);
  float uv[2], duv[4];
  st_texcoords_at_pixel(t, x, y, uv, duv);
  return st_sample_atlas(atlas, entry, (float2)(uv[0], uv[1]),
                         (float4)(duv[0], duv[1], duv[2], duv[3]));
}

/* The colour (RGB, opacity) of source triangle `source`'s fragment at pixel (x, y): its flat
 * colour times its texel. */
inline float4 st_fragment_colour(__global const float4* triangle_colors,
                                 __global const StTexTriangle* tex_tris,
                                 __global const uint* atlas, __constant StViewConstants* view,
                                 uint source, int x, int y) {
  const float4 c = triangle_colors[source];
  if (!view->textured) return c;
  return c * st_fragment_texel(tex_tris, atlas, view, source, x, y);
}
