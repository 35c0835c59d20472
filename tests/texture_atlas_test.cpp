// Texture atlas, CPU half: packing, gutters, mip limits and the atlas sampler against the
// reference sampler of the un-packed textures. No device.
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "engine/features/texture_atlas.h"
#include "preprocess/scene/scene.h"

namespace strata {
namespace {

TextureImage randomTexture(int w, int h, std::mt19937& rng) {
  std::uniform_real_distribution<float> d(0.0f, 1.0f);
  TextureImage t{w, h, {}};
  t.texels.resize(size_t(w) * size_t(h));
  for (auto& v : t.texels) v = {d(rng), d(rng), d(rng), d(rng)};
  return t;
}

TextureImage solidTexture(int w, int h, glm::vec4 c) {
  return TextureImage{w, h, std::vector<glm::vec4>(size_t(w) * size_t(h), c)};
}

std::vector<glm::ivec2> mixedSizes() {
  return {{1, 1},    {2, 1},    {1, 7},     {3, 5},     {8, 8},     {13, 17},   {16, 16},
          {31, 9},   {32, 64},  {64, 64},   {67, 45},   {100, 3},   {128, 128}, {129, 131},
          {256, 64}, {64, 256}, {200, 150}, {255, 255}, {256, 256}, {5, 200},   {90, 90}};
}

const Wrap kWraps[] = {Wrap::Repeat, Wrap::MirroredRepeat, Wrap::Clamp};
const Filter kFilters[] = {Filter::Nearest, Filter::Bilinear, Filter::Trilinear};

float maxDiff(glm::vec4 a, glm::vec4 b) {
  glm::vec4 d = glm::abs(a - b);
  return std::max(std::max(d.x, d.y), std::max(d.z, d.w));
}

// Cells of one page never overlap, stay inside the page, and at every kept level the texture
// plus a one-texel ring lies inside its own cell's footprint there.
void expectSaneLayout(const AtlasLayout& L) {
  for (size_t i = 0; i < L.placements.size(); ++i) {
    const AtlasPlacement& a = L.placements[i];
    EXPECT_GE(a.cell_x, 0);
    EXPECT_GE(a.cell_y, 0);
    EXPECT_LE(a.cell_x + a.cell_w, L.page_size);
    EXPECT_LE(a.cell_y + a.cell_h, L.page_heights.at(size_t(a.page)));
    EXPECT_LE(L.page_heights.at(size_t(a.page)), L.page_size);
    for (int l = 0; l < a.levels; ++l) {
      int s = 1 << l;
      glm::ivec2 o = levelOrigin(a, l);
      int lx0 = (a.cell_x + s - 1) / s, ly0 = (a.cell_y + s - 1) / s;
      int lx1 = (a.cell_x + a.cell_w) / s, ly1 = (a.cell_y + a.cell_h) / s;
      EXPECT_GE(o.x - 1, lx0) << i << " level " << l;
      EXPECT_GE(o.y - 1, ly0) << i << " level " << l;
      EXPECT_LE(o.x + std::max(1, a.w >> l) + 1, lx1) << i << " level " << l;
      EXPECT_LE(o.y + std::max(1, a.h >> l) + 1, ly1) << i << " level " << l;
    }
    for (size_t j = i + 1; j < L.placements.size(); ++j) {
      const AtlasPlacement& b = L.placements[j];
      if (a.page != b.page) continue;
      bool apart = a.cell_x + a.cell_w <= b.cell_x || b.cell_x + b.cell_w <= a.cell_x ||
                   a.cell_y + a.cell_h <= b.cell_y || b.cell_y + b.cell_h <= a.cell_y;
      EXPECT_TRUE(apart) << "cells " << i << " and " << j << " overlap";
    }
  }
}

TEST(TextureAtlasMip, ChainHalvesDownToOneTexel) {
  std::mt19937 rng(1);
  auto chain = buildMipChain(randomTexture(13, 6, rng));
  ASSERT_EQ(chain.size(), 4u);  // 13x6, 6x3, 3x1, 1x1
  EXPECT_EQ(chain[1].width, 6);
  EXPECT_EQ(chain[1].height, 3);
  EXPECT_EQ(chain[2].width, 3);
  EXPECT_EQ(chain[2].height, 1);
  EXPECT_EQ(chain[3].width, 1);
  EXPECT_EQ(chain[3].height, 1);
  glm::vec4 avg =
      (chain[0].texels[0] + chain[0].texels[1] + chain[0].texels[13] + chain[0].texels[14]) * 0.25f;
  EXPECT_LT(maxDiff(chain[1].texels[0], avg), 1e-6f);
}

TEST(TextureAtlasSampling, AtlasEqualsReferenceForEveryWrapAndFilter) {
  std::mt19937 rng(6);
  std::vector<TextureImage> textures;
  for (glm::ivec2 s : mixedSizes()) textures.push_back(randomTexture(s.x, s.y, rng));
  std::vector<std::vector<TextureImage>> chains;
  for (const auto& t : textures) chains.push_back(buildMipChain(t));
  std::uniform_real_distribution<float> uvd(-7.5f, 8.5f), lodd(-1.0f, 9.0f);
  int checked = 0, multi_level = 0;
  for (AtlasMode mode : {AtlasMode::Packed, AtlasMode::Uniform})
    for (int ratio : {kDefaultGutterRatio, 4})
      for (Wrap ws : kWraps)
        for (Wrap wt : kWraps) {
          std::vector<Sampler> samplers(textures.size(), Sampler{ws, wt, Filter::Bilinear});
          Atlas atlas = buildAtlas(textures, samplers, 1024, mode, ratio);
          expectSaneLayout(atlas.layout);
          for (size_t i = 0; i < textures.size(); ++i) {
            const AtlasPlacement& p = atlas.layout.placements[i];
            if (p.levels > 1) ++multi_level;
            for (Filter f : kFilters) {
              Sampler s{ws, wt, f};
              for (int k = 0; k < 60; ++k) {
                glm::vec2 uv(uvd(rng), uvd(rng));
                if (k < 8) uv = glm::vec2(float(k % 3) - 1.0f, float(k / 3) - 1.0f) * 1.0f;
                if (k >= 8 && k < 16)  // exact texel edges of level 0
                  uv = glm::vec2(std::floor(uvd(rng) * float(p.w)) / float(p.w),
                                 std::floor(uvd(rng) * float(p.h)) / float(p.h));
                float lod = k % 5 == 0 ? std::floor(lodd(rng)) : lodd(rng);
                glm::vec4 ref = sampleTexture(chains[i], s, uv, lod, p.levels);
                glm::vec4 got = sampleAtlas(atlas, int(i), s, uv, lod);
                ASSERT_LT(maxDiff(ref, got), 1e-5f)
                    << "texture " << i << " (" << p.w << "x" << p.h << ", " << p.levels
                    << " levels) wrap " << int(ws) << "/" << int(wt) << " filter " << int(f)
                    << " uv " << uv.x << "," << uv.y << " lod " << lod;
                ++checked;
              }
            }
          }
        }
  EXPECT_GT(checked, 40000);
  EXPECT_GT(multi_level, 50);  // trilinear across kept levels is exercised
}

TEST(TextureAtlasSampling, ReferenceWrapsAsSpecified) {
  TextureImage t{3, 1, {{0, 0, 0, 1}, {1, 0, 0, 1}, {2, 0, 0, 1}}};
  auto chain = buildMipChain(t);
  auto at = [&](Wrap w, float u) {
    return sampleTexture(chain, Sampler{w, w, Filter::Nearest}, {u, 0.5f}, 0.0f).x;
  };
  EXPECT_EQ(at(Wrap::Repeat, -0.1f), 2.0f);
  EXPECT_EQ(at(Wrap::Repeat, 1.1f), 0.0f);
  EXPECT_EQ(at(Wrap::MirroredRepeat, -0.1f), 0.0f);
  EXPECT_EQ(at(Wrap::MirroredRepeat, 1.1f), 2.0f);
  EXPECT_EQ(at(Wrap::MirroredRepeat, 1.5f), 1.0f);
  EXPECT_EQ(at(Wrap::Clamp, -5.0f), 0.0f);
  EXPECT_EQ(at(Wrap::Clamp, 5.0f), 2.0f);
  // Bilinear at u = 0 under repeat blends the last and first texels equally.
  EXPECT_NEAR(sampleTexture(chain, Sampler{Wrap::Repeat, Wrap::Repeat, Filter::Bilinear},
                            {0.0f, 0.5f}, 0.0f)
                  .x,
              1.0f, 1e-6f);
}

TEST(TextureAtlasBleeding, ContrastingNeighboursNeverBleed) {
  // Solid textures in saturated, mutually different colours, packed tightly; the page background
  // is zero, which no texture uses.
  std::vector<TextureImage> textures;
  std::vector<glm::vec4> colours;
  std::vector<glm::ivec2> sizes = {{4, 4},     {8, 8},    {16, 16}, {32, 32},   {5, 3},   {1, 1},
                                   {64, 64},   {128, 32}, {7, 9},   {256, 256}, {33, 17}, {2, 2},
                                   {130, 130}, {16, 128}, {3, 64},  {512, 512}};
  for (size_t i = 0; i < sizes.size(); ++i) {
    glm::vec4 c(float(i % 2), float((i / 2) % 2), float((i / 4) % 2), 0.25f + 0.05f * float(i));
    colours.push_back(c);
    textures.push_back(solidTexture(sizes[i].x, sizes[i].y, c));
  }
  int samples = 0;
  for (AtlasMode mode : {AtlasMode::Packed, AtlasMode::Uniform})
    for (int ratio : {kDefaultGutterRatio, 2})
      for (Wrap w : kWraps) {
        std::vector<Sampler> samplers(textures.size(), Sampler{w, w, Filter::Bilinear});
        Atlas atlas =
            buildAtlas(textures, samplers, mode == AtlasMode::Packed ? 1024 : 2048, mode, ratio);
        expectSaneLayout(atlas.layout);
        for (size_t i = 0; i < textures.size(); ++i) {
          const AtlasPlacement& p = atlas.layout.placements[i];
          for (Filter f : kFilters)
            for (float lod = 0.0f; lod <= float(p.levels) + 0.5f; lod += 0.5f) {
              int lvl = std::min(int(lod), p.levels - 1);
              int nx = std::max(1, p.w >> lvl), ny = std::max(1, p.h >> lvl);
              int step_x = std::max(1, nx / 16), step_y = std::max(1, ny / 16);
              for (int ky = -1; ky <= ny + 1; ky += (ky < 1 || ky >= ny - 1) ? 1 : step_y)
                for (int kx = -1; kx <= nx + 1; kx += (kx < 1 || kx >= nx - 1) ? 1 : step_x)
                  for (float e : {0.0f, 0.5f, -1e-4f, 1e-4f}) {
                    glm::vec2 uv((float(kx) + e) / float(nx), (float(ky) + e) / float(ny));
                    glm::vec4 got = sampleAtlas(atlas, int(i), Sampler{w, w, f}, uv, lod);
                    ASSERT_LT(maxDiff(got, colours[i]), 1e-5f)
                        << "texture " << i << " wrap " << int(w) << " filter " << int(f) << " lod "
                        << lod << " uv " << uv.x << "," << uv.y;
                    ++samples;
                  }
            }
        }
      }
  EXPECT_GT(samples, 100000);
}

TEST(TextureAtlasPacking, PackedOccupancyAtLeast85PercentUniformLower) {
  std::mt19937 rng(85);
  const int side[] = {16, 24, 32, 48, 64, 96, 128, 160, 192, 256};
  std::uniform_int_distribution<int> pick(0, 9);
  std::vector<glm::ivec2> sizes;
  for (int i = 0; i < 64; ++i) sizes.push_back({side[pick(rng)], side[pick(rng)]});
  sizes.push_back({1, 1});
  sizes.push_back({200, 37});
  sizes.push_back({77, 131});
  AtlasLayout packed = packAtlas(sizes, 1024, AtlasMode::Packed);
  AtlasLayout uniform = packAtlas(sizes, 1024, AtlasMode::Uniform);
  expectSaneLayout(packed);
  expectSaneLayout(uniform);
  std::printf(
      "[ occupancy ] %zu textures on 1024^2 pages: packed %d pages %.1f%% (%.1f%% with "
      "gutters), uniform %d pages %.1f%% (%.1f%% with gutters)\n",
      sizes.size(), packed.pages, 100 * packed.occupancy, 100 * packed.occupancy_with_gutters,
      uniform.pages, 100 * uniform.occupancy, 100 * uniform.occupancy_with_gutters);
  EXPECT_GE(packed.occupancy, 0.85);
  EXPECT_LT(uniform.occupancy, packed.occupancy);
  EXPECT_LE(packed.pages, uniform.pages);
  // On small pages the set spills over several, each filled densely.
  AtlasLayout small = packAtlas(sizes, 512, AtlasMode::Packed);
  expectSaneLayout(small);
  std::printf("[ occupancy ] same set on 512^2 pages: packed %d pages %.1f%%\n", small.pages,
              100 * small.occupancy);
  EXPECT_GE(small.pages, 3);
  EXPECT_GE(small.occupancy, 0.85);
  // One big page holds everything at the same density.
  AtlasLayout big = packAtlas(sizes, 4096, AtlasMode::Packed);
  EXPECT_EQ(big.pages, 1);
}

TEST(TextureAtlasPacking, SeveralPagesWhenOneIsFull) {
  std::vector<glm::ivec2> sizes(10, glm::ivec2(100, 100));  // 102^2 cells, 4 per 256 page
  for (AtlasMode mode : {AtlasMode::Packed, AtlasMode::Uniform}) {
    AtlasLayout L = packAtlas(sizes, 256, mode);
    EXPECT_EQ(L.pages, 3) << int(mode);
    expectSaneLayout(L);
    std::vector<int> per_page(size_t(L.pages), 0);
    for (const auto& p : L.placements) ++per_page[size_t(p.page)];
    for (int n : per_page) EXPECT_LE(n, 4);
  }
  // The built pages carry every texture, sampled correctly on later pages too.
  std::mt19937 rng(3);
  std::vector<TextureImage> textures;
  for (int i = 0; i < 10; ++i) textures.push_back(randomTexture(100, 100, rng));
  Atlas atlas = buildAtlas(textures, 256, AtlasMode::Packed);
  ASSERT_EQ(atlas.pages.size(), 3u);
  for (size_t i = 0; i < textures.size(); ++i) {
    auto chain = buildMipChain(textures[i]);
    Sampler s{Wrap::Repeat, Wrap::Repeat, Filter::Trilinear};
    glm::vec2 uv(0.37f + float(i), -2.71f);
    EXPECT_LT(maxDiff(sampleTexture(chain, s, uv, 0.3f, atlas.layout.placements[i].levels),
                      sampleAtlas(atlas, int(i), s, uv, 0.3f)),
              1e-5f);
  }
}

TEST(TextureAtlasPacking, MipLevelsKeptAndGutterRule) {
  EXPECT_EQ(keptMipLevels({1, 1}), 1);
  EXPECT_EQ(keptMipLevels({255, 1000}), 1);
  EXPECT_EQ(keptMipLevels({256, 256}), 2);
  EXPECT_EQ(keptMipLevels({1024, 512}), 3);
  EXPECT_EQ(keptMipLevels({256, 64}, 4), 4);
  EXPECT_EQ(gutterTexels(1), 1);
  EXPECT_EQ(gutterTexels(2), 4);
  EXPECT_EQ(gutterTexels(4), 16);
}

TEST(TextureAtlasErrors, AbsurdSizesThrowOneLineErrors) {
  auto expectError = [](auto&& f, const char* what) {
    try {
      f();
      ADD_FAILURE() << what << ": no error";
    } catch (const Error& e) {
      std::string m = e.what();
      EXPECT_FALSE(m.empty()) << what;
      EXPECT_EQ(m.find('\n'), std::string::npos) << what << ": " << m;
    } catch (...) {
      ADD_FAILURE() << what << ": not a strata::Error";
    }
  };
  expectError([] { packAtlas({{0, 0}}, 512, AtlasMode::Packed); }, "0x0");
  expectError([] { packAtlas({{16, -3}}, 512, AtlasMode::Packed); }, "negative");
  expectError([] { packAtlas({{600, 16}}, 512, AtlasMode::Packed); }, "wider than a page");
  expectError([] { packAtlas({{511, 16}}, 512, AtlasMode::Uniform); }, "gutter does not fit");
  expectError([] { packAtlas({{20000, 16}}, 16384, AtlasMode::Packed); }, "> 16384");
  expectError([] { packAtlas({{16, 16}}, 0, AtlasMode::Packed); }, "page 0");
  expectError([] { packAtlas({{16, 16}}, 20000, AtlasMode::Packed); }, "page > 16896");
  expectError([] { buildAtlas({TextureImage{4, 4, {}}}, 64, AtlasMode::Packed); }, "texel count");
  expectError(
      [] {
        buildAtlas({TextureImage{-1, 4, {}}}, 64, AtlasMode::Packed);
      },
      "negative image");
  expectError([] { buildMipChain(TextureImage{0, 0, {}}); }, "empty mip chain");
  expectError([] { buildMipChain(TextureImage{20000, 1, {}}); }, "huge image");
}

TEST(TextureAtlasLod, FromDerivatives) {
  // One texel per pixel -> 0; four -> 2; clamped to the kept levels and to 0 below.
  EXPECT_NEAR(lodFromDerivatives(1.0f / 64, 0, 0, 1.0f / 64, {64, 64}, 7), 0.0f, 1e-6f);
  EXPECT_NEAR(lodFromDerivatives(4.0f / 64, 0, 0, 1.0f / 64, {64, 64}, 7), 2.0f, 1e-5f);
  EXPECT_NEAR(lodFromDerivatives(0, 3.0f / 32, 0, 0, {64, 32}, 7), std::log2(3.0f), 1e-5f);
  EXPECT_NEAR(lodFromDerivatives(1.0f, 0, 0, 1.0f, {256, 256}, 2), 1.0f, 1e-6f);
  EXPECT_EQ(lodFromDerivatives(1e-6f, 0, 0, 1e-6f, {64, 64}, 7), 0.0f);
  EXPECT_EQ(lodFromDerivatives(0, 0, 0, 0, {64, 64}, 7), 0.0f);
}

}  // namespace
}  // namespace strata
