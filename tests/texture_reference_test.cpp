// Textured materials on the reference side: the builtin:textured:N scene, the reference
// texel of a fragment (referenceTexel) against cases worked out by hand, and the Embree reference
// applying it (flat-shaded colour times texel, composited with the texel's alpha), with untextured
// scenes unchanged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "engine/frontend/texture_shading.h"
#include "engine/frontend/view_constants.h"
#include "engine/reference/embree_reference.h"
#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/scene/world_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

// ---- builtin:textured:N -------------------------------------------------------------------------

void expectSceneError(const std::string& spec, const std::string& fragment) {
  try {
    makeBuiltinScene(spec);
    ADD_FAILURE() << spec << " was accepted";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(spec), std::string::npos) << what;
    EXPECT_NE(what.find(fragment), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
}

TEST(TexturedScene, BadMaterialCountsAreRejected) {
  expectSceneError("builtin:textured", "from 1 to 4096");
  expectSceneError("builtin:textured:", "from 1 to 4096");
  expectSceneError("builtin:textured:0", "from 1 to 4096");
  expectSceneError("builtin:textured:-3", "from 1 to 4096");
  expectSceneError("builtin:textured:4097", "from 1 to 4096");
  expectSceneError("builtin:textured:many", "is not a whole number");
  expectSceneError("builtin:textured:16x", "is not a whole number");
  test::expectErrorContaining([] { makeBuiltinScene("builtin:texturd:4"); }, "builtin:textured:N");
}

TEST(TexturedScene, SixteenMaterialsCoverSizesWrapsFiltersAndSharing) {
  const Scene s = makeBuiltinScene("builtin:textured:16");
  EXPECT_EQ(s.source, "builtin:textured:16");
  ASSERT_EQ(s.textures.size(), 16u);
  // 16 materials with a texture of their own, one more sampling texture 1 with other wrap
  // modes, one untextured.
  ASSERT_EQ(s.materials.size(), 18u);
  std::set<std::pair<int, int>> sizes;
  bool non_square = false, npot = false, some_alpha = false;
  int with_mips = 0;
  for (const SceneTexture& t : s.textures) {
    ASSERT_TRUE(t.image);
    EXPECT_NO_THROW(validateTexture(*t.image, t.name.c_str()));
    const int w = t.image->width, h = t.image->height;
    sizes.insert({w, h});
    non_square |= w != h;
    npot |= (w & (w - 1)) != 0 || (h & (h - 1)) != 0;
    EXPECT_LE(std::max(w, h), 512) << t.name;
    EXPECT_GE(std::min(w, h), 8) << t.name;
    with_mips += keptMipLevels({w, h}) > 1;
    for (const glm::vec4& c : t.image->texels) some_alpha |= c.a < 1.0f;
  }
  EXPECT_EQ(sizes.size(), 16u) << "every texture a different size";
  EXPECT_TRUE(non_square);
  EXPECT_TRUE(npot);
  EXPECT_TRUE(some_alpha);
  EXPECT_GE(with_mips, 3) << "minified textures need levels > 0 in the atlas";
  EXPECT_EQ(keptMipLevels({s.textures[0].image->width, s.textures[0].image->height}), 3);

  // Every wrap mode on each axis, mixed pairs, every filter.
  std::set<Wrap> wrap_s, wrap_t;
  std::set<Filter> filters;
  int mixed = 0;
  std::vector<std::vector<Sampler>> samplers_of(s.textures.size());
  for (const Material& m : s.materials) {
    if (m.texture < 0) continue;
    ASSERT_LT(size_t(m.texture), s.textures.size());
    wrap_s.insert(m.sampler.wrap_s);
    wrap_t.insert(m.sampler.wrap_t);
    filters.insert(m.sampler.filter);
    mixed += m.sampler.wrap_s != m.sampler.wrap_t;
    samplers_of[size_t(m.texture)].push_back(m.sampler);
  }
  EXPECT_EQ(wrap_s.size(), 3u);
  EXPECT_EQ(wrap_t.size(), 3u);
  EXPECT_EQ(filters.size(), 3u);
  EXPECT_GE(mixed, 4);
  // Exactly one texture is sampled by two materials, with different wrap modes.
  int shared = 0;
  for (const auto& v : samplers_of) {
    ASSERT_GE(v.size(), 1u) << "every texture is used";
    if (v.size() == 2) {
      ++shared;
      EXPECT_TRUE(v[0].wrap_s != v[1].wrap_s || v[0].wrap_t != v[1].wrap_t);
    }
    EXPECT_LE(v.size(), 2u);
  }
  EXPECT_EQ(shared, 1);

  // Texture coordinates well outside [0, 1]; every material on some mesh.
  float lo = 0.0f, hi = 0.0f;
  std::set<uint32_t> used;
  for (const Mesh& m : s.meshes) {
    used.insert(m.material);
    if (s.materials[m.material].texture >= 0) {
      ASSERT_EQ(m.texcoords.size(), m.positions.size()) << m.name;
    }
    for (const glm::vec2& uv : m.texcoords) {
      lo = std::min({lo, uv.x, uv.y});
      hi = std::max({hi, uv.x, uv.y});
    }
  }
  EXPECT_LE(lo, -3.0f);
  EXPECT_GE(hi, 4.0f);
  EXPECT_EQ(used.size(), s.materials.size());

  const WorldGeometry g = WorldGeometry::fromScene(s);
  EXPECT_TRUE(g.textured());
  EXPECT_EQ(g.textures.size(), 16u);
  EXPECT_EQ(g.triangle_uv.size(), size_t(g.triangleCount()) * 3);
  ASSERT_TRUE(s.default_view.has_value());
}

TEST(TexturedScene, DeterministicSmallAndLargeCounts) {
  const Scene a = makeBuiltinScene("builtin:textured:64");
  const Scene b = makeBuiltinScene("builtin:textured:64");
  ASSERT_EQ(a.textures.size(), 64u);
  EXPECT_LT(a.triangleCount(), 50000u);
  for (size_t i = 0; i < a.textures.size(); ++i)
    ASSERT_EQ(a.textures[i].image->texels, b.textures[i].image->texels) << i;
  EXPECT_EQ(a.triangleCount(), b.triangleCount());

  const Scene one = makeBuiltinScene("builtin:textured:1");
  ASSERT_EQ(one.textures.size(), 1u);
  ASSERT_EQ(one.materials.size(), 3u);
  EXPECT_EQ(one.materials[1].texture, 0);  // the shared sampler falls back to texture 0
  EXPECT_TRUE(WorldGeometry::fromScene(one).textured());

  const Scene big = makeBuiltinScene("builtin:textured:4096");
  EXPECT_EQ(big.textures.size(), 4096u);
  EXPECT_EQ(big.materials.size(), 4098u);
  EXPECT_LT(big.triangleCount(), 50000u);
}

// ---- Hand-made textured quads -------------------------------------------------------------------

constexpr int kSize = 64;

// A 4x4 texture whose texel (i, j) (column i, row j from the top) is (0.1 + 0.2 i, 0.1 + 0.2 j,
// 0.5, alpha), so a sampled colour names its texel.
TextureImage texture4x4(float alpha = 1.0f) {
  TextureImage t;
  t.width = t.height = 4;
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i)
      t.texels.emplace_back(0.1f + 0.2f * i, 0.1f + 0.2f * j, 0.5f, alpha);
  return t;
}

// One textured quad filling the view of orthoSettings(): world [-1, 1]^2 at z = 0, facing the
// camera, u from uv_min.x (left) to uv_max.x (right), v from uv_min.y (top) to uv_max.y.
Scene quadScene(const TextureImage& image, Sampler sampler, glm::vec2 uv_min, glm::vec2 uv_max,
                float opacity = 1.0f, glm::vec3 color = {0.9f, 0.6f, 0.3f}) {
  Scene s;
  s.source = "test quad";
  Mesh m = makeTexturedQuad({1.0f, 1.0f}, uv_min, uv_max);
  m.material = 0;
  s.meshes.push_back(m);
  s.textures.push_back({"test texture", std::make_shared<const TextureImage>(image)});
  Material mat;
  mat.color = glm::vec4(color, 1.0f);
  mat.opacity = opacity;
  mat.texture = 0;
  mat.sampler = sampler;
  s.materials.push_back(mat);
  s.instances.push_back(Instance{});
  return s;
}

// Looks down -z from z = 5 at a 2 x 2 view: pixel centre (x, y) is world
// ((x + 0.5) / 32 - 1, 1 - (y + 0.5) / 32), so u = u0 + (u1 - u0) (x + 0.5) / 64 and likewise v.
FrameSettings orthoSettings() { return test::orthoTopDown(kSize); }

// The texel referenceTexel gives at pixel (x, y), the same from both triangles of the quad.
glm::vec4 texelAt(const WorldGeometry& g, const ReferenceTextures& rt, const StViewConstants& v,
                  int x, int y) {
  const glm::vec4 a = referenceTexel(g, rt, v, 0, x, y), b = referenceTexel(g, rt, v, 1, x, y);
  EXPECT_EQ(a, b) << "pixel " << x << "," << y;
  return a;
}

glm::ivec2 texelIndex(const glm::vec4& c) {
  return {int(std::lround((c.r - 0.1f) / 0.2f)), int(std::lround((c.g - 0.1f) / 0.2f))};
}

// u = -1 + 3 (x + 0.5) / 64 over 4 texels: floor(4u) at the pixel columns below is
// x = 2: -4 (4u = -3.53), x = 10: -3 (-2.03), x = 30: 1 (1.72), x = 50: 5 (5.47), x = 60: 7 (7.34).
// Repeat: i mod 4; MirroredRepeat: m = i mod 8, m < 4 ? m : 7 - m; Clamp: clamp(i, 0, 3).
const int kPixels[5] = {2, 10, 30, 50, 60};
const int kRepeat[5] = {0, 1, 1, 1, 3};
const int kMirrored[5] = {3, 2, 1, 2, 0};
const int kClamp[5] = {0, 0, 1, 3, 3};

const int* expectedIndices(Wrap w) {
  return w == Wrap::Repeat ? kRepeat : w == Wrap::MirroredRepeat ? kMirrored : kClamp;
}

TEST(ReferenceTexel, NearestWrapsPerAxisAsWorkedOutByHand) {
  const FrameSettings settings = orthoSettings();
  const StViewConstants view = makeViewConstants(settings);
  const Wrap wraps[3] = {Wrap::Repeat, Wrap::MirroredRepeat, Wrap::Clamp};
  for (Wrap ws : wraps)
    for (Wrap wt : wraps) {
      const Scene s = quadScene(texture4x4(), {ws, wt, Filter::Nearest}, {-1, -1}, {2, 2});
      const WorldGeometry g = WorldGeometry::fromScene(s);
      ASSERT_TRUE(g.textured());
      const ReferenceTextures rt = ReferenceTextures::build(g);
      for (int a = 0; a < 5; ++a)
        for (int b = 0; b < 5; ++b) {
          const glm::vec4 c = texelAt(g, rt, view, kPixels[a], kPixels[b]);
          EXPECT_EQ(texelIndex(c), glm::ivec2(expectedIndices(ws)[a], expectedIndices(wt)[b]))
              << "wrap " << int(ws) << "," << int(wt) << " pixel " << kPixels[a] << ","
              << kPixels[b];
          EXPECT_EQ(c.b, 0.5f);
          EXPECT_EQ(c.a, 1.0f);
        }
    }
}

TEST(ReferenceTexel, BilinearBlendsTheFourNearestTexels) {
  const FrameSettings settings = orthoSettings();
  const StViewConstants view = makeViewConstants(settings);
  const Scene s =
      quadScene(texture4x4(), {Wrap::Repeat, Wrap::Repeat, Filter::Bilinear}, {0, 0}, {1, 1});
  const WorldGeometry g = WorldGeometry::fromScene(s);
  const ReferenceTextures rt = ReferenceTextures::build(g);
  // Pixel 20: u = 20.5 / 64, 4u - 0.5 = 0.78125: texels 0 and 1, weight 0.78125 on texel 1, so
  // red = 0.1 + 0.2 * 0.78125 = 0.25625. Row 40: 4v - 0.5 = 2.03125: rows 2 and 3.
  const glm::vec4 c = texelAt(g, rt, view, 20, 40);
  EXPECT_NEAR(c.r, 0.25625f, 1e-5f);
  EXPECT_NEAR(c.g, 0.1f + 0.2f * 2.03125f, 1e-5f);
  // Pixel 2: 4u - 0.5 = -0.34375: texel -1 wraps to 3, weight 0.65625 on texel 0.
  const glm::vec4 d = texelAt(g, rt, view, 2, 40);
  EXPECT_NEAR(d.r, 0.34375f * 0.7f + 0.65625f * 0.1f, 1e-5f);
}

// A 256x256 checkerboard of single black and white texels: at level 0 every texel is 0 or 1, at
// level 1 (the 2x2 box filter) every texel is 0.5. The atlas keeps 2 levels of a 256x256 texture.
TextureImage finestChecker() {
  TextureImage t;
  t.width = t.height = 256;
  for (int y = 0; y < 256; ++y)
    for (int x = 0; x < 256; ++x) {
      const float v = float((x + y) & 1);
      t.texels.emplace_back(v, v, v, 1.0f);
    }
  return t;
}

TEST(ReferenceTexel, MagnifiedUsesLevelZeroAndMinifiedALevelAboveZero) {
  const FrameSettings settings = orthoSettings();
  const StViewConstants view = makeViewConstants(settings);
  ASSERT_EQ(keptMipLevels({256, 256}), 2);

  // Magnified: the 4x4 texture over u -1..2 is 0.1875 texels per pixel: lod 0.
  {
    const Scene s = quadScene(texture4x4(), {}, {-1, -1}, {2, 2});
    const WorldGeometry g = WorldGeometry::fromScene(s);
    const StTexTriangle tri = makeTexTriangle(g, 0, 0, view);
    float uv[2], duv[4];
    st_texcoords_at_pixel(&tri, 20, 12, uv, duv);
    EXPECT_NEAR(uv[0], -1.0f + 3.0f * 20.5f / 64.0f, 1e-5f);
    EXPECT_NEAR(uv[1], -1.0f + 3.0f * 12.5f / 64.0f, 1e-5f);
    EXPECT_NEAR(duv[0], 3.0f / 64.0f, 1e-5f);
    EXPECT_NEAR(duv[1], 0.0f, 1e-5f);
    EXPECT_NEAR(duv[2], 0.0f, 1e-5f);
    EXPECT_NEAR(duv[3], 3.0f / 64.0f, 1e-5f);
    EXPECT_EQ(lodFromDerivatives(duv[0], duv[1], duv[2], duv[3], {4, 4}, 8), 0.0f);
  }
  // One texel covers two pixels (u 0..0.125 of 256 texels): level 0, only black and white.
  {
    const Scene s = quadScene(finestChecker(), {Wrap::Repeat, Wrap::Repeat, Filter::Nearest},
                              {0, 0}, {0.125f, 0.125f});
    const WorldGeometry g = WorldGeometry::fromScene(s);
    const ReferenceTextures rt = ReferenceTextures::build(g);
    ASSERT_EQ(rt.mips[0].size(), 2u);
    for (int y = 0; y < kSize; y += 7)
      for (int x = 0; x < kSize; x += 5) {
        const glm::vec4 c = texelAt(g, rt, view, x, y);
        // texel (x / 2, y / 2): white when their sum is odd
        EXPECT_EQ(c.r, float(((x / 2) + (y / 2)) & 1)) << x << "," << y;
      }
  }
  // Minified: u 0..2 of 256 texels is 8 texels per pixel (lod 3, clamped to the kept level 1):
  // every sample is the box-filtered grey, for Nearest, Bilinear and Trilinear.
  for (Filter f : {Filter::Nearest, Filter::Bilinear, Filter::Trilinear}) {
    const Scene s = quadScene(finestChecker(), {Wrap::Repeat, Wrap::Repeat, f}, {0, 0}, {2, 2});
    const WorldGeometry g = WorldGeometry::fromScene(s);
    const StTexTriangle tri = makeTexTriangle(g, 0, 0, view);
    float uv[2], duv[4];
    st_texcoords_at_pixel(&tri, 20, 12, uv, duv);
    EXPECT_NEAR(lodFromDerivatives(duv[0], duv[1], duv[2], duv[3], {256, 256}, 9), 3.0f, 1e-3f);
    const ReferenceTextures rt = ReferenceTextures::build(g);
    for (int y = 1; y < kSize; y += 9)
      for (int x = 3; x < kSize; x += 11) {
        const glm::vec4 c = texelAt(g, rt, view, x, y);
        EXPECT_NEAR(c.r, 0.5f, 1e-6f) << "filter " << int(f) << " pixel " << x << "," << y;
      }
  }
}

TEST(ReferenceTexel, UntexturedTrianglesGetWhite) {
  WorldGeometry g = WorldGeometry::fromScene(quadScene(texture4x4(), {}, {0, 0}, {1, 1}));
  const ReferenceTextures rt = ReferenceTextures::build(g);
  const StViewConstants view = makeViewConstants(orthoSettings());
  g.material_texture[0] = -1;
  EXPECT_EQ(referenceTexel(g, rt, view, 0, 10, 10), glm::vec4(1.0f));
}

// ---- The Embree reference applies the texel -----------------------------------------------------

RenderResult renderEmbree(const WorldGeometry& g, const FrameSettings& s,
                          EmbreeMode mode = EmbreeMode::Transparency) {
  return makeEmbreeRenderer(mode)->render(g, s);
}

// The pixel of one fragment of colour s (flat shade times texel) over the background, in the
// renderer's own float steps ("under" compositing).
glm::u8vec3 over(const glm::vec4& s, const glm::vec3& bg) {
  glm::u8vec3 out;
  const float ta = 1.0f * s.a, t = 1.0f - s.a;
  for (int c = 0; c < 3; ++c) out[c] = uint8_t(st_to_unorm8(ta * s[c] + t * bg[c]));
  return out;
}

glm::u8vec3 pixelOf(const Image& im, int x, int y) {
  const uint8_t* p = im.pixel(x, y);
  return {p[0], p[1], p[2]};
}

TEST(EmbreeTextured, TransparentQuadShowsShadeTimesTexel) {
  // Alpha 0.5 texels in a half-opaque material: fragment opacity 0.25.
  for (float alpha : {1.0f, 0.5f}) {
    const Scene scene =
        quadScene(texture4x4(alpha), {Wrap::MirroredRepeat, Wrap::Clamp, Filter::Nearest}, {-1, -1},
                  {2, 2}, 0.5f);
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    const FrameSettings s = orthoSettings();
    const RenderResult r = renderEmbree(g, s);
    EXPECT_EQ(r.stats.stage_ms.count("texture_build"), 1u);
    const glm::vec4 shade = shadeTriangle(g, 0, s.camera.lightDirection());
    ASSERT_EQ(shade, shadeTriangle(g, 1, s.camera.lightDirection()));
    const ReferenceTextures rt = ReferenceTextures::build(g);
    const StViewConstants view = makeViewConstants(s);
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const glm::vec4 t0 = referenceTexel(g, rt, view, 0, x, y);
        const glm::vec4 t1 = referenceTexel(g, rt, view, 1, x, y);
        const glm::u8vec3 got = pixelOf(r.image, x, y);
        const glm::u8vec3 e0 = over(shade * t0, s.background.color);
        const glm::u8vec3 e1 = over(shade * t1, s.background.color);
        ASSERT_TRUE(got == e0 || got == e1) << "pixel " << x << "," << y;
      }
    // Worked out by hand at pixel (50, 2): texel (mirrored 5 -> 2, clamped -4 -> 0).
    const glm::vec4 texel(0.5f, 0.1f, 0.5f, alpha);
    EXPECT_EQ(pixelOf(r.image, 50, 2), over(shade * texel, s.background.color));
    const double k = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
    const double a = 0.5 * alpha;
    EXPECT_NEAR(r.image.pixel(50, 2)[0], 255.0 * (a * k * 0.9 * 0.5 + (1 - a) * 0.1), 0.51);
    EXPECT_NEAR(r.image.pixel(50, 2)[1], 255.0 * (a * k * 0.6 * 0.1 + (1 - a) * 0.2), 0.51);
  }
}

TEST(EmbreeTextured, OpaqueAndTranslucencyUseTheTexelColour) {
  const Scene scene = quadScene(texture4x4(), {Wrap::Repeat, Wrap::Repeat, Filter::Nearest},
                                {-1, -1}, {2, 2}, 0.5f);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s = orthoSettings();
  const glm::vec4 shade = shadeTriangle(g, 0, s.camera.lightDirection());
  // Pixel (60, 30): texel (3, 1).
  const glm::vec4 texel(0.7f, 0.3f, 0.5f, 1.0f);
  const RenderResult opaque = renderEmbree(g, s, EmbreeMode::Opaque);
  for (int c = 0; c < 3; ++c)
    EXPECT_EQ(opaque.image.pixel(60, 30)[c], st_to_unorm8(shade[c] * texel[c])) << c;

  s.effect = Effect::Translucency;
  s.sigma = 0.0f;
  const RenderResult tl = renderEmbree(g, s);
  const float r = st_schlick_reflectance(1.0f);  // straight on
  for (int c = 0; c < 3; ++c)
    EXPECT_EQ(tl.image.pixel(60, 30)[c],
              st_to_unorm8(r * (shade[c] * texel[c]) + (1.0f - r) * s.background.color[c]))
        << c;
}

TEST(EmbreeTextured, TexturedFragmentInFrontOfAnUntexturedOne) {
  // A textured quad at z = 0.5 over an untextured one at z = 0: each fragment gets its own
  // colour (texel only on the textured one).
  Scene scene =
      quadScene(texture4x4(), {Wrap::Repeat, Wrap::Repeat, Filter::Nearest}, {0, 0}, {1, 1}, 0.6f);
  scene.instances[0].transform = glm::mat4(1.0f);
  scene.instances[0].transform[3] = glm::vec4(0.0f, 0.0f, 0.5f, 1.0f);
  Mesh back = makeTexturedQuad({1.0f, 1.0f}, {0, 0}, {1, 1});
  back.material = 1;
  scene.meshes.push_back(back);
  Material plain;
  plain.color = glm::vec4(0.2f, 0.4f, 0.8f, 1.0f);
  plain.opacity = 0.7f;
  scene.materials.push_back(plain);
  Instance inst;
  inst.mesh = 1;
  inst.object_id = 1;
  scene.instances.push_back(inst);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  ASSERT_TRUE(g.textured());
  ASSERT_EQ(g.triangleTexture(2), -1);
  const FrameSettings s = orthoSettings();
  const RenderResult r = renderEmbree(g, s);
  const glm::vec3 light = s.camera.lightDirection();
  const glm::vec4 front = shadeTriangle(g, 0, light), behind = shadeTriangle(g, 2, light);
  // Pixel (40, 10): u = 40.5 / 64 -> texel 2, v = 10.5 / 64 -> texel 0.
  const glm::vec4 f = front * glm::vec4(0.5f, 0.1f, 0.5f, 1.0f);
  float T = 1.0f, rgb[3] = {0, 0, 0};
  for (const glm::vec4& c : {f, behind}) {
    const float ta = T * c.a;
    for (int k = 0; k < 3; ++k) rgb[k] += ta * c[k];
    T *= 1.0f - c.a;
  }
  for (int c = 0; c < 3; ++c)
    EXPECT_EQ(r.image.pixel(40, 10)[c], st_to_unorm8(rgb[c] + T * s.background.color[c])) << c;
  EXPECT_EQ(r.stats.max_depth_complexity, 2u);
}

TEST(EmbreeTextured, UntexturedScenesAreUnchanged) {
  // By hand: an untextured quad of opacity 0.5 over the solid background.
  Scene scene = quadScene(texture4x4(), {}, {0, 0}, {1, 1}, 0.5f);
  scene.materials[0].texture = -1;
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  ASSERT_FALSE(g.textured());
  const FrameSettings s = orthoSettings();
  const RenderResult r = renderEmbree(g, s);
  EXPECT_EQ(r.stats.stage_ms.count("texture_build"), 0u);
  const double k = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  EXPECT_NEAR(r.image.pixel(20, 20)[0], 255.0 * (0.5 * k * 0.9 + 0.5 * 0.1), 0.51);
  EXPECT_NEAR(r.image.pixel(20, 20)[2], 255.0 * (0.5 * k * 0.3 + 0.5 * 0.3), 0.51);

  // builtin:demo untextured, and with an all-white texture on every material (texture
  // coordinates all 0): the textured path multiplies by exactly 1, so the images are equal bit
  // for bit, in both modes and effects.
  Scene demo = makeBuiltinScene("builtin:demo");
  const WorldGeometry plain = WorldGeometry::fromScene(demo);
  ASSERT_FALSE(plain.textured());
  TextureImage white;
  white.width = white.height = 2;
  white.texels.assign(4, glm::vec4(1.0f));
  demo.textures.push_back({"white", std::make_shared<const TextureImage>(white)});
  for (Material& m : demo.materials) m.texture = 0;
  const WorldGeometry textured = WorldGeometry::fromScene(demo);
  ASSERT_TRUE(textured.textured());
  FrameSettings ds;
  ds.width = ds.height = 96;
  ds.camera = Camera::orbit(demo.boundingSphere(), OrbitView{});
  for (EmbreeMode mode : {EmbreeMode::Transparency, EmbreeMode::Opaque})
    for (Effect effect : {Effect::Transparency, Effect::Translucency}) {
      ds.effect = effect;
      const RenderResult a = renderEmbree(plain, ds, mode);
      const RenderResult b = renderEmbree(textured, ds, mode);
      EXPECT_EQ(a.image.rgba, b.image.rgba) << "mode " << int(mode) << " effect " << int(effect);
      EXPECT_EQ(a.stats.fragments, b.stats.fragments);
    }
}

// ---- builtin:textured:16 rendered ---------------------------------------------------------------

TEST(EmbreeTextured, TexturedSceneLayersMagnificationAndMinification) {
  const Scene scene = makeBuiltinScene("builtin:textured:16");
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s;
  s.width = s.height = 128;
  s.camera = Camera::orbit(scene.boundingSphere(), *scene.default_view);
  s.capture_depth_complexity = true;
  const RenderResult r = renderEmbree(g, s);
  EXPECT_GE(r.stats.max_depth_complexity, 5u);

  // Over every fragment of the default view: some magnified (lod 0 with more than a pixel per
  // texel), some minified past level 1 of a texture that keeps levels above 0.
  EmbreeRayPicker picker;
  std::vector<glm::ivec2> pixels;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) pixels.push_back({x, y});
  const auto hits = picker.pick(g, s, pixels, true);
  const StViewConstants view = makeViewConstants(s);
  int magnified = 0, minified = 0, outside = 0;
  for (size_t i = 0; i < pixels.size(); ++i)
    for (const EmbreeRayHit& h : hits[i]) {
      const int32_t tex = g.triangleTexture(h.triangle);
      if (tex < 0) continue;
      const glm::ivec2 size(g.textures[size_t(tex)]->width, g.textures[size_t(tex)]->height);
      const StTexTriangle tri = makeTexTriangle(g, h.triangle, uint32_t(tex), view);
      float uv[2], duv[4];
      st_texcoords_at_pixel(&tri, pixels[i].x, pixels[i].y, uv, duv);
      const float rho = std::max(std::hypot(duv[0] * size.x, duv[1] * size.y),
                                 std::hypot(duv[2] * size.x, duv[3] * size.y));
      magnified += rho < 1.0f;
      minified += keptMipLevels(size) > 1 && rho > 2.0f;
      outside += uv[0] < 0.0f || uv[0] > 1.0f || uv[1] < 0.0f || uv[1] > 1.0f;
    }
  EXPECT_GT(magnified, 100);
  EXPECT_GT(minified, 100);
  EXPECT_GT(outside, 1000);
}

}  // namespace
}  // namespace strata
