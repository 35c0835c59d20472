#include "engine/features/texture_atlas.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "strata/error.h"

#define STB_RECT_PACK_IMPLEMENTATION
#include <stb/stb_rect_pack.h>

namespace strata {
namespace {

std::string sizeText(glm::ivec2 s) { return std::to_string(s.x) + "x" + std::to_string(s.y); }

int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int ceilDiv(int a, int b) { return -floorDiv(-a, b); }
int modPos(int a, int n) {
  int m = a % n;
  return m < 0 ? m + n : m;
}

int wrapIndex(int i, int n, Wrap w) {
  switch (w) {
    case Wrap::Repeat:
      return modPos(i, n);
    case Wrap::MirroredRepeat: {
      int m = modPos(i, 2 * n);
      return m < n ? m : 2 * n - 1 - m;
    }
    case Wrap::Clamp:
      break;
  }
  return std::clamp(i, 0, n - 1);
}

// Bilinear setup on one axis: the lower texel index (unwrapped) and the weight of the upper one.
// Shared by both samplers so their weights are bit-identical.
void bilinearAxis(float u, int n, int& i0, float& f) {
  float x = std::clamp(u * float(n) - 0.5f, -16777216.0f, 16777216.0f);
  if (!(x == x)) x = 0.0f;  // NaN
  float fl = std::floor(x);
  i0 = int(fl);
  f = x - fl;
}
int nearestAxis(float u, int n) {
  float x = std::clamp(u * float(n), -16777216.0f, 16777216.0f);
  return x == x ? int(std::floor(x)) : 0;
}

// Atlas-local indices (may be -1 or n: the gutter) of the two texels, per the wrap rule.
void atlasPair(int i0, int n, Wrap w, int& a0, int& a1) {
  switch (w) {
    case Wrap::Repeat:
      a0 = modPos(i0, n);
      a1 = a0 + 1;
      return;
    case Wrap::MirroredRepeat: {
      int m = modPos(i0, 2 * n);
      if (m < n) {
        a0 = m;
        a1 = m + 1;
      } else {
        a0 = 2 * n - 1 - m;
        a1 = a0 - 1;
      }
      return;
    }
    case Wrap::Clamp:
      break;
  }
  a0 = std::clamp(i0, -1, n - 1);
  a1 = a0 + 1;
}

glm::vec4 blend(const glm::vec4& t00, const glm::vec4& t10, const glm::vec4& t01,
                const glm::vec4& t11, float fx, float fy) {
  return (t00 * (1.0f - fx) + t10 * fx) * (1.0f - fy) + (t01 * (1.0f - fx) + t11 * fx) * fy;
}

const glm::vec4& texel(const TextureImage& im, int x, int y) {
  return im.texels[size_t(y) * size_t(im.width) + size_t(x)];
}

// The one place that picks levels and weights; `fetch(level, kind, ...)` does the lookups.
template <class SampleLevel>
glm::vec4 sampleLevels(const Sampler& s, float lod, int levels, SampleLevel&& level) {
  float l = std::clamp(std::isfinite(lod) ? lod : 0.0f, 0.0f, float(levels - 1));
  if (s.filter != Filter::Trilinear)
    return level(std::min(int(std::floor(l + 0.5f)), levels - 1), s.filter == Filter::Bilinear);
  int l0 = int(std::floor(l));
  int l1 = std::min(l0 + 1, levels - 1);
  float t = l - float(l0);
  glm::vec4 a = level(l0, true);
  if (t == 0.0f || l1 == l0) return a;
  glm::vec4 b = level(l1, true);
  return a * (1.0f - t) + b * t;
}

glm::ivec2 levelSize(int w, int h, int level) {
  return {std::max(1, w >> level), std::max(1, h >> level)};
}

}  // namespace

std::vector<TextureImage> buildMipChain(const TextureImage& image) {
  validateTexture(image);
  std::vector<TextureImage> chain{image};
  while (chain.back().width > 1 || chain.back().height > 1) {
    const TextureImage& p = chain.back();
    TextureImage n;
    n.width = std::max(1, p.width / 2);
    n.height = std::max(1, p.height / 2);
    n.texels.resize(size_t(n.width) * size_t(n.height));
    for (int y = 0; y < n.height; ++y)
      for (int x = 0; x < n.width; ++x) {
        int x0 = std::min(2 * x, p.width - 1), x1 = std::min(2 * x + 1, p.width - 1);
        int y0 = std::min(2 * y, p.height - 1), y1 = std::min(2 * y + 1, p.height - 1);
        n.texels[size_t(y) * size_t(n.width) + size_t(x)] =
            (texel(p, x0, y0) + texel(p, x1, y0) + texel(p, x0, y1) + texel(p, x1, y1)) * 0.25f;
      }
    chain.push_back(std::move(n));
  }
  return chain;
}

int keptMipLevels(glm::ivec2 size, int gutter_ratio) {
  validateTextureSize(size, "texture");
  int m = std::min(size.x, size.y);
  int k = 0;
  while (k < 30 && (2LL << (k + 1)) * gutter_ratio <= m) ++k;
  return k + 1;
}

int gutterTexels(int kept_levels) { return kept_levels <= 1 ? 1 : 2 << (kept_levels - 1); }

glm::ivec2 levelOrigin(const AtlasPlacement& p, int level) {
  int s = 1 << level;
  return {ceilDiv(p.cell_x, s) + 1, ceilDiv(p.cell_y, s) + 1};
}

AtlasLayout packAtlas(const std::vector<glm::ivec2>& sizes, int page_size, AtlasMode mode,
                      int gutter_ratio) {
  if (page_size <= 0 || page_size > kMaxAtlasPageSide)
    throw Error("atlas: page size " + std::to_string(page_size) + " is out of range (1.." +
                std::to_string(kMaxAtlasPageSide) + ")");
  if (gutter_ratio <= 0)
    throw Error("atlas: gutter ratio " + std::to_string(gutter_ratio) + " must be positive");
  AtlasLayout out;
  out.page_size = page_size;
  out.placements.resize(sizes.size());
  for (size_t i = 0; i < sizes.size(); ++i) {
    validateTextureSize(sizes[i], ("atlas texture " + std::to_string(i)).c_str());
    AtlasPlacement& p = out.placements[i];
    p.w = sizes[i].x;
    p.h = sizes[i].y;
    p.levels = keptMipLevels(sizes[i], gutter_ratio);
    int g = gutterTexels(p.levels);
    p.cell_w = p.w + 2 * g;
    p.cell_h = p.h + 2 * g;
    if (p.cell_w > page_size || p.cell_h > page_size)
      throw Error("atlas texture " + std::to_string(i) + ": size " + sizeText(sizes[i]) +
                  " with its " + std::to_string(g) + "-texel gutter does not fit a " +
                  std::to_string(page_size) + " page");
  }
  if (sizes.empty()) return out;

  if (mode == AtlasMode::Uniform) {
    int sw = 0, sh = 0;
    for (const auto& p : out.placements) sw = std::max(sw, p.cell_w), sh = std::max(sh, p.cell_h);
    int cols = page_size / sw, rows = page_size / sh, per_page = cols * rows;
    for (size_t i = 0; i < sizes.size(); ++i) {
      AtlasPlacement& p = out.placements[i];
      int slot = int(i % size_t(per_page));
      p.page = int(i / size_t(per_page));
      p.cell_x = (slot % cols) * sw;
      p.cell_y = (slot / cols) * sh;
    }
    out.pages = int((sizes.size() + size_t(per_page) - 1) / size_t(per_page));
  } else {
    std::vector<stbrp_rect> todo(sizes.size());
    for (size_t i = 0; i < sizes.size(); ++i) {
      todo[i] = {};
      todo[i].id = int(i);
      todo[i].w = out.placements[i].cell_w;
      todo[i].h = out.placements[i].cell_h;
    }
    std::vector<stbrp_node> nodes(size_t(page_size) + 1);
    while (!todo.empty()) {
      stbrp_context ctx;
      stbrp_init_target(&ctx, page_size, page_size, nodes.data(), int(nodes.size()));
      stbrp_setup_heuristic(&ctx, STBRP_HEURISTIC_Skyline_BF_sortHeight);
      stbrp_pack_rects(&ctx, todo.data(), int(todo.size()));
      std::vector<stbrp_rect> rest;
      for (const stbrp_rect& r : todo) {
        if (!r.was_packed) {
          rest.push_back(r);
          continue;
        }
        AtlasPlacement& p = out.placements[size_t(r.id)];
        p.page = out.pages;
        p.cell_x = r.x;
        p.cell_y = r.y;
      }
      if (rest.size() == todo.size())
        throw Error("atlas: stb_rect_pack placed nothing on an empty page");  // cannot happen
      for (auto& r : rest) r.was_packed = 0;
      todo = std::move(rest);
      ++out.pages;
    }
  }
  double used = 0, cells = 0;
  out.page_heights.assign(size_t(out.pages), 1);
  for (AtlasPlacement& p : out.placements) {
    int& ph = out.page_heights[size_t(p.page)];
    ph = std::max(ph, p.cell_y + p.cell_h);
    glm::ivec2 o = levelOrigin(p, 0);
    p.x = o.x;
    p.y = o.y;
    used += double(p.w) * p.h;
    cells += double(p.cell_w) * p.cell_h;
  }
  double total = 0;
  for (int ph : out.page_heights) total += double(page_size) * ph;
  out.occupancy = used / total;
  out.occupancy_with_gutters = cells / total;
  return out;
}

Atlas buildAtlas(const std::vector<TextureImage>& textures, const std::vector<Sampler>& samplers,
                 int page_size, AtlasMode mode, int gutter_ratio) {
  if (samplers.size() != textures.size())
    throw Error("atlas: " + std::to_string(samplers.size()) + " samplers for " +
                std::to_string(textures.size()) + " textures");
  std::vector<glm::ivec2> sizes;
  for (size_t i = 0; i < textures.size(); ++i) {
    validateTexture(textures[i], ("atlas texture " + std::to_string(i)).c_str());
    sizes.push_back({textures[i].width, textures[i].height});
  }
  Atlas atlas;
  atlas.layout = packAtlas(sizes, page_size, mode, gutter_ratio);
  std::vector<int> page_levels(size_t(atlas.layout.pages), 1);
  for (const auto& p : atlas.layout.placements)
    page_levels[size_t(p.page)] = std::max(page_levels[size_t(p.page)], p.levels);
  atlas.pages.resize(size_t(atlas.layout.pages));
  for (size_t pg = 0; pg < atlas.pages.size(); ++pg)
    for (int l = 0; l < page_levels[pg]; ++l) {
      TextureImage im;
      im.width = std::max(1, page_size >> l);
      im.height = std::max(1, atlas.layout.page_heights[pg] >> l);
      im.texels.assign(size_t(im.width) * size_t(im.height), glm::vec4(0.0f));
      atlas.pages[pg].push_back(std::move(im));
    }
  for (size_t i = 0; i < textures.size(); ++i) {
    const AtlasPlacement& p = atlas.layout.placements[i];
    std::vector<TextureImage> mips = buildMipChain(textures[i]);
    for (int l = 0; l < p.levels; ++l) {
      const TextureImage& src = mips[size_t(l)];
      TextureImage& dst = atlas.pages[size_t(p.page)][size_t(l)];
      glm::ivec2 o = levelOrigin(p, l);
      // The texture and a one-texel ring of gutter, each gutter texel the wrapped texel.
      for (int y = -1; y <= src.height; ++y)
        for (int x = -1; x <= src.width; ++x) {
          int dx = o.x + x, dy = o.y + y;
          if (dx < 0 || dy < 0 || dx >= dst.width || dy >= dst.height)
            throw Error("atlas: internal error, texture " + std::to_string(i) +
                        " leaves its page at level " + std::to_string(l));
          dst.texels[size_t(dy) * size_t(dst.width) + size_t(dx)] =
              texel(src, wrapIndex(x, src.width, samplers[i].wrap_s),
                    wrapIndex(y, src.height, samplers[i].wrap_t));
        }
    }
  }
  return atlas;
}

Atlas buildAtlas(const std::vector<TextureImage>& textures, int page_size, AtlasMode mode,
                 int gutter_ratio) {
  return buildAtlas(textures, std::vector<Sampler>(textures.size()), page_size, mode, gutter_ratio);
}

glm::vec4 sampleTexture(const std::vector<TextureImage>& mips, const Sampler& s, glm::vec2 uv,
                        float lod, int max_levels) {
  if (mips.empty()) throw Error("sampleTexture: empty mip chain");
  int levels = std::clamp(max_levels, 1, int(mips.size()));
  return sampleLevels(s, lod, levels, [&](int l, bool linear) {
    const TextureImage& im = mips[size_t(l)];
    if (!linear)
      return texel(im, wrapIndex(nearestAxis(uv.x, im.width), im.width, s.wrap_s),
                   wrapIndex(nearestAxis(uv.y, im.height), im.height, s.wrap_t));
    int i0, j0;
    float fx, fy;
    bilinearAxis(uv.x, im.width, i0, fx);
    bilinearAxis(uv.y, im.height, j0, fy);
    int x0 = wrapIndex(i0, im.width, s.wrap_s), x1 = wrapIndex(i0 + 1, im.width, s.wrap_s);
    int y0 = wrapIndex(j0, im.height, s.wrap_t), y1 = wrapIndex(j0 + 1, im.height, s.wrap_t);
    return blend(texel(im, x0, y0), texel(im, x1, y0), texel(im, x0, y1), texel(im, x1, y1), fx,
                 fy);
  });
}

glm::vec4 sampleAtlas(const Atlas& atlas, int texture, const Sampler& s, glm::vec2 uv, float lod) {
  if (texture < 0 || size_t(texture) >= atlas.layout.placements.size())
    throw Error("sampleAtlas: no texture " + std::to_string(texture));
  const AtlasPlacement& p = atlas.layout.placements[size_t(texture)];
  return sampleLevels(s, lod, p.levels, [&](int l, bool linear) {
    const TextureImage& page = atlas.pages[size_t(p.page)][size_t(l)];
    glm::ivec2 o = levelOrigin(p, l);
    glm::ivec2 n = levelSize(p.w, p.h, l);
    if (!linear)
      return texel(page, o.x + wrapIndex(nearestAxis(uv.x, n.x), n.x, s.wrap_s),
                   o.y + wrapIndex(nearestAxis(uv.y, n.y), n.y, s.wrap_t));
    int i0, j0, x0, x1, y0, y1;
    float fx, fy;
    bilinearAxis(uv.x, n.x, i0, fx);
    bilinearAxis(uv.y, n.y, j0, fy);
    atlasPair(i0, n.x, s.wrap_s, x0, x1);
    atlasPair(j0, n.y, s.wrap_t, y0, y1);
    return blend(texel(page, o.x + x0, o.y + y0), texel(page, o.x + x1, o.y + y0),
                 texel(page, o.x + x0, o.y + y1), texel(page, o.x + x1, o.y + y1), fx, fy);
  });
}

float lodFromDerivatives(float dudx, float dvdx, float dudy, float dvdy, glm::ivec2 size,
                         int levels) {
  glm::vec2 dx(dudx * float(size.x), dvdx * float(size.y));
  glm::vec2 dy(dudy * float(size.x), dvdy * float(size.y));
  float rho = std::max(glm::length(dx), glm::length(dy));
  if (!(rho > 0.0f) || !std::isfinite(rho))
    return rho > 0.0f ? float(std::max(levels - 1, 0)) : 0.0f;
  return std::clamp(std::log2(rho), 0.0f, float(std::max(levels - 1, 0)));
}

}  // namespace strata
