// Texture atlas (CPU half): mip chains, packing of textures into atlas pages (uniform slots
// or stb_rect_pack), gutters filled by each texture's wrap rule, and two samplers with the same
// semantics: sampleTexture on the original, un-packed texture (the reference) and sampleAtlas on
// the packed pages (what a kernel will do). No OpenCL here.
//
// Sampling rules (shared by both samplers):
//   - texel centres at (i + 0.5) / size; Nearest picks floor(u * size), Bilinear blends the 2x2
//     texels around u * size - 0.5.
//   - Nearest and Bilinear use the mip level round(lod); Trilinear blends Bilinear at floor(lod)
//     and floor(lod) + 1. lod is clamped to [0, kept levels - 1].
//   - Wrap per axis on integer texel indices: Repeat = i mod n, MirroredRepeat = period 2n with the
//     second half reversed, Clamp = clamp(i, 0, n - 1).
//
// Gutter and mip rule (documented in packAtlas): a texture of w x h keeps K + 1 mip levels with
// K = the largest k such that 2^(k+1) <= min(w, h) / gutter_ratio (K = 0 when none), and its cell
// is (w + 2g) x (h + 2g) with g = 1 when K = 0, else g = 2^(K+1). At level L <= K the texture
// starts at ceil(cell_x / 2^L) + 1 and keeps a gutter of at least one texel on every side that no
// other cell touches, so bilinear filtering at the sub-rectangle's edge reads only the gutter,
// which holds the wrapped texel of the same texture; coarser levels are not kept, so they never
// blend neighbours.
#pragma once

#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/texture.h"  // TextureImage, Sampler, kMaxTextureSize

namespace strata {

enum class AtlasMode { Uniform, Packed };

// Largest page side: the largest texture with the widest gutter the mip rule gives it (2^8).
inline constexpr int kMaxAtlasPageSide = kMaxTextureSize + 512;
inline constexpr int kDefaultGutterRatio = 64;

// Level 0 is the image itself; each next level halves each side (floor, at least 1) with a 2x2
// box filter (texels past an odd edge are clamped), down to 1x1.
std::vector<TextureImage> buildMipChain(const TextureImage& image);

// Mip levels kept for a w x h texture under the rule above, and its gutter at level 0.
int keptMipLevels(glm::ivec2 size, int gutter_ratio = kDefaultGutterRatio);
int gutterTexels(int kept_levels);

struct AtlasPlacement {
  int page = 0;
  int x = 0, y = 0, w = 0, h = 0;  // the texture at level 0 (its gutter lies around it)
  int levels = 1;                  // mip levels kept (0 .. levels - 1)
  int cell_x = 0, cell_y = 0, cell_w = 0, cell_h = 0;  // reserved rectangle, gutters included
};
// The texture's origin in the page at mip level `level` (its size there is max(1, w >> level)).
glm::ivec2 levelOrigin(const AtlasPlacement& p, int level);

struct AtlasLayout {
  int page_size = 0;
  int pages = 0;
  // Each page is page_size wide and page_heights[page] (<= page_size) high: trimmed to the lowest
  // cell on it, so a half-empty last page costs only what it holds.
  std::vector<int> page_heights;
  std::vector<AtlasPlacement> placements;  // one per input size, same order
  double occupancy = 0.0;                  // sum of w * h / atlas texels (sum of page areas)
  double occupancy_with_gutters = 0.0;     // sum of cell_w * cell_h / atlas texels
};

// Uniform: every texture gets a slot of the largest cell's size, in a grid per page. Packed:
// stb_rect_pack (skyline, best fit), filling a page and opening the next with what did not fit.
// Throws strata::Error for absurd sizes or a texture (with its gutter) larger than a page.
AtlasLayout packAtlas(const std::vector<glm::ivec2>& sizes, int page_size, AtlasMode mode,
                      int gutter_ratio = kDefaultGutterRatio);

struct Atlas {
  AtlasLayout layout;
  std::vector<std::vector<TextureImage>>
      pages;  // pages[page][level]; level l is (page_size >> l) x (height >> l), at least 1
};

Atlas buildAtlas(const std::vector<TextureImage>& textures, const std::vector<Sampler>& samplers,
                 int page_size, AtlasMode mode, int gutter_ratio = kDefaultGutterRatio);
// Same with every texture's gutter filled for Repeat on both axes. The gutter is filled for the
// wrap modes the texture is sampled with; a sampler with other wrap modes gets wrong edge texels.
Atlas buildAtlas(const std::vector<TextureImage>& textures, int page_size, AtlasMode mode,
                 int gutter_ratio = kDefaultGutterRatio);

// Reference: `mips` from buildMipChain, only the first max_levels used.
glm::vec4 sampleTexture(const std::vector<TextureImage>& mips, const Sampler& s, glm::vec2 uv,
                        float lod, int max_levels = 1 << 30);
// Atlas: texture `texture` of the atlas, with its kept levels; same result as sampleTexture with
// max_levels = placement.levels.
glm::vec4 sampleAtlas(const Atlas& atlas, int texture, const Sampler& s, glm::vec2 uv, float lod);

// lod = log2(max(|(dudx, dvdx) * size|, |(dudy, dvdy) * size|)), clamped to [0, levels - 1].
float lodFromDerivatives(float dudx, float dvdx, float dudy, float dvdy, glm::ivec2 size,
                         int levels);

}  // namespace strata
