// Image tests of texturing: every OpenCL method samples the texture atlas in its
// resolve; the Embree reference samples the original, un-packed textures on the CPU. They must
// agree on textured scenes for every wrap mode and filter, every atlas mode must give the same
// image, and no texel of an atlas neighbour may ever bleed into a sample.
#include <algorithm>
#include <filesystem>

#include "engine/reference/embree_reference.h"
#include "engine/frontend/texture_shading.h"
#include "preprocess/mesh_loader.h"
#include "test_support.h"

namespace strata {
namespace {

struct TexturedCase {
  std::string scene;    // file or builtin spec
  std::string texture;  // --texture for meshes without a material file
  std::string label;
};
void PrintTo(const TexturedCase& c, std::ostream* os) { *os << c.label; }

std::string assimp(const std::string& rel) {
  return std::string(STRATA_ASSIMP_MODELS_DIR) + "/" + rel;
}

std::vector<TexturedCase> cases() {
  return {{"builtin:textured:16", "", "textured16"},
          {test::modelPath("spot.obj"), test::modelPath("spot_texture.png"), "spot"},
          {assimp("glTF2/BoxTextured-glTF/BoxTextured.gltf"), "", "BoxTextured"},
          {assimp("glTF/CesiumMilkTruck/CesiumMilkTruck.gltf"), "", "CesiumMilkTruck"}};
}

Scene loadTextured(const TexturedCase& c) {
  Scene scene = loadScene(c.scene);
  if (!c.texture.empty()) applyTexture(scene, c.texture);
  return scene;
}

const float kViews[][2] = {{30, 20}, {150, -35}, {260, 55}, {0, 80}};

class TexturedImages : public ::testing::TestWithParam<TexturedCase> {};

TEST_P(TexturedImages, EveryMethodMatchesEmbree) {
  const TexturedCase& c = GetParam();
  const Scene scene = loadTextured(c);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  ASSERT_TRUE(g.textured()) << c.label << " has no textured material";
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto embree_opaque = makeEmbreeRenderer(EmbreeMode::Opaque);
  const Method methods[] = {Method::Ppll, Method::Abuffer, Method::Mdts,
                            Method::Dp,   Method::Ddp,     Method::Cells};
  std::vector<std::unique_ptr<MethodRenderer>> renderers;
  for (Method m : methods) renderers.push_back(makeRenderer(m));
  auto opaque = makeRenderer(Method::Opaque);
  for (const auto& v : kViews) {
    FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    s.k = 64;
    s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache";
    const std::string view = std::to_string(int(v[0])) + "_" + std::to_string(int(v[1]));
    const RenderResult ref = embree->render(g, s);
    for (size_t i = 0; i < renderers.size(); ++i) {
      const std::string name = methodName(methods[i]);
      SCOPED_TRACE(c.label + " " + name + " view " + view);
      const RenderResult a = renderers[i]->render(g, s);
      EXPECT_EQ(a.stats.fragments_lost, 0u);
      EXPECT_EQ(a.stats.atlas, "packed");
      EXPECT_GT(a.stats.atlas_pages, 0u);
      test::expectImagesMatch(a.image, ref.image, "textured-" + c.label + "-" + name + "-" + view);
    }
    SCOPED_TRACE(c.label + " opaque view " + view);
    test::expectImagesMatch(opaque->render(g, s).image, embree_opaque->render(g, s).image,
                            "textured-" + c.label + "-opaque-" + view);
  }
}

// Translucency (cells and embree only): the texel colours each interface's reflection.
TEST_P(TexturedImages, CellsTranslucencyMatchesEmbree) {
  const TexturedCase& c = GetParam();
  const Scene scene = loadTextured(c);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto cells = makeRenderer(Method::Cells);
  for (const auto& v : {kViews[0], kViews[2]}) {
    FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    s.effect = Effect::Translucency;
    s.sigma = 2.0f / scene.boundingSphere().radius;
    s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache";
    const std::string view = std::to_string(int(v[0])) + "_" + std::to_string(int(v[1]));
    SCOPED_TRACE(c.label + " view " + view);
    test::expectImagesMatch(cells->render(g, s).image, embree->render(g, s).image,
                            "textured-translucency-" + c.label + "-" + view);
  }
}

INSTANTIATE_TEST_SUITE_P(Scenes, TexturedImages, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return info.param.label; });

// The texture really is in the picture: the same scene without its textures differs a lot, so
// the comparisons above could not pass with texturing switched off.
TEST(TexturedImagesSanity, TexturesChangeTheImage) {
  const Scene scene = loadScene("builtin:textured:16");
  Scene plain = scene;
  for (Material& m : plain.materials) m.texture = -1;
  const FrameSettings s = test::settingsFor(scene, 256, 30, 20);
  auto ppll = makeRenderer(Method::Ppll);
  const Image a = ppll->render(WorldGeometry::fromScene(scene), s).image;
  const Image b = ppll->render(WorldGeometry::fromScene(plain), s).image;
  EXPECT_LT(compareImages(a, b).within_2, 0.9);
}

// Packing never changes the image: off (a page and a launch per texture), uniform and packed
// sample the same texels, so their images are identical; off draws one launch per texture.
TEST(TextureAtlas, ModesGiveIdenticalImagesAndOffLaunchesPerTexture) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:textured:16");
  FrameSettings s = test::settingsFor(scene, 256, 30, 20);
  auto ppll = makeRenderer(Method::Ppll);
  s.atlas = AtlasChoice::Packed;
  const RenderResult packed = ppll->render(g, s);
  s.atlas = AtlasChoice::Uniform;
  const RenderResult uniform = ppll->render(g, s);
  s.atlas = AtlasChoice::Off;
  const RenderResult off = ppll->render(g, s);
  EXPECT_EQ(compareImages(packed.image, uniform.image).max_abs, 0);
  EXPECT_EQ(compareImages(packed.image, off.image).max_abs, 0);
  EXPECT_EQ(packed.stats.atlas, "packed");
  EXPECT_EQ(off.stats.atlas, "off");
  // Every distinct (texture, wrap modes) is one page without an atlas; the atlas holds them
  // on fewer pages, and more densely when packed.
  EXPECT_EQ(off.stats.atlas_pages, off.stats.atlas_placements);
  // The scene samples one texture with two wrap modes: it is placed twice (each copy's gutter
  // holds its own wrap rule's texels).
  EXPECT_EQ(packed.stats.atlas_placements, scene.textures.size() + 1);
  EXPECT_LT(packed.stats.atlas_pages, off.stats.atlas_pages);
  EXPECT_GT(packed.stats.atlas_occupancy, uniform.stats.atlas_occupancy);
  // One front-end launch pair for all textured materials with the atlas; one per texture
  // without (static batching merges each material's triangles).
  EXPECT_GE(off.stats.launches, packed.stats.launches + off.stats.atlas_entries - 1);
}

// Contrasting neighbours: many small solid-colour textures packed side by side, sampled with
// every wrap mode and filter, minified at a grazing angle (coarse mip levels) and with texture
// coordinates far outside [0, 1]. A solid texture samples to its own colour at every level, so
// any texel of a neighbour would show as a wrong colour against the reference. Every pixel must
// match within 1/255 apart from a handful on silhouettes.
TEST(TextureAtlas, NoNeighbourTexelEverBleedsIn) {
  Scene scene;
  scene.source = "test:solid-atlas";
  const int kTextures = 24;
  for (int i = 0; i < kTextures; ++i) {
    auto im = std::make_shared<TextureImage>();
    // Mixed sizes, 8 to 640 texels a side, packed tightly by stb_rect_pack; the larger ones keep
    // coarse mip levels (and wider gutters), which minification far away samples.
    im->width = 8 + 97 * (i % 6) + 5 * i;
    im->height = 8 + 131 * ((i * 7) % 5) + i;
    const glm::vec4 colour((i * 53 % 256) / 255.0f, (i * 101 % 256) / 255.0f,
                           (255 - i * 37 % 256) / 255.0f, 1.0f);
    im->texels.assign(size_t(im->width) * size_t(im->height), colour);
    scene.textures.push_back({"solid" + std::to_string(i), im});
    Material m;
    m.name = "solid" + std::to_string(i);
    m.color = glm::vec4(1.0f);
    m.opacity = 1.0f;
    m.texture = i;
    m.sampler.wrap_s = Wrap(i % 3);
    m.sampler.wrap_t = Wrap((i / 3) % 3);
    m.sampler.filter = Filter((i / 9) % 3 == 0 ? 2 : (i % 3));
    scene.materials.push_back(m);
    // Long strips side by side (never overlapping: coplanar overlaps would make the nearest hit
    // a coin toss), receding from the camera: UVs from -7 to 9 across each.
    Mesh quad;
    quad.name = m.name;
    const float x0 = float(i) * 1.1f - 13.0f, z0 = 0.0f;
    quad.positions = {{x0, 0.0f, z0},
                      {x0 + 1.0f, 0.0f, z0},
                      {x0 + 1.0f, 0.0f, z0 + 40.0f},
                      {x0, 0.0f, z0 + 40.0f}};
    quad.texcoords = {{-7.0f, -7.0f}, {9.0f, -7.0f}, {9.0f, 9.0f}, {-7.0f, 9.0f}};
    quad.indices = {0, 1, 2, 0, 2, 3};
    quad.material = uint32_t(i);
    scene.meshes.push_back(quad);
    scene.instances.push_back({uint32_t(i), glm::mat4(1.0f), uint32_t(i), m.name});
  }
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  int with_mips = 0;
  for (const SceneTexture& t : scene.textures)
    with_mips += keptMipLevels({t.image->width, t.image->height}) > 1;
  ASSERT_GE(with_mips, 6);
  FrameSettings s;
  s.width = s.height = 256;
  OrbitView v;
  v.azimuth_deg = 180.0f;
  v.elevation_deg = 6.0f;  // grazing: deep minification far away
  v.distance_radii = 1.02f;
  s.camera = Camera::orbit(scene.boundingSphere(), v);
  auto opaque = makeRenderer(Method::Opaque);
  auto embree = makeEmbreeRenderer(EmbreeMode::Opaque);
  const Image ref = embree->render(g, s).image;
  // The colours a pixel may have: a strip's own shaded colour (all strips share one normal, so
  // one diffuse factor) or the background.
  const glm::vec4 shade = shadeTriangle(g, 0, s.camera.lightDirection()) / g.material_colors[0];
  std::vector<glm::vec3> allowed = {s.background.color, s.background.color2};
  for (const SceneTexture& t : scene.textures)
    allowed.push_back(glm::vec3(t.image->texels[0]) * glm::vec3(shade));
  for (AtlasChoice mode : {AtlasChoice::Packed, AtlasChoice::Uniform}) {
    s.atlas = mode;
    const RenderResult a = opaque->render(g, s);
    SCOPED_TRACE(atlasChoiceName(mode));
    uint64_t foreign = 0, textured = 0;
    for (int y = 0; y < a.image.height; ++y)
      for (int x = 0; x < a.image.width; ++x) {
        const uint8_t* p = a.image.pixel(x, y);
        int best = 255;
        for (size_t k = 0; k < allowed.size(); ++k) {
          int worst = 0;
          for (int ch = 0; ch < 3; ++ch)
            worst = std::max(worst, std::abs(int(p[ch]) - int(st_to_unorm8(allowed[k][ch]))));
          best = std::min(best, worst);
          if (worst <= 1 && k >= 2) ++textured;
        }
        if (best > 1) ++foreign;
      }
    EXPECT_EQ(foreign, 0u) << "pixels whose colour is no texture's own (a neighbour bled in)";
    EXPECT_GT(textured, uint64_t(a.image.width) * a.image.height / 3);
    EXPECT_GT(a.stats.atlas_placements, 0u);
    if (std::getenv("STRATA_TEST_KEEP_IMAGES"))
      writeImage(a.image, std::string(STRATA_TEST_OUTPUT_DIR) + "/solid-atlas.png");
    test::expectImagesMatch(a.image, ref, std::string("solid-atlas-") + atlasChoiceName(mode),
                            0.999);
  }
}

// A renderer keeps its atlas while the textures stay the same and rebuilds it when they change:
// scenes rendered in turn by one renderer give exactly the images fresh renderers give.
TEST(TextureAtlas, RendererReusesOrRebuildsItsAtlas) {
  const Scene a = loadScene("builtin:textured:16"), b = loadScene("builtin:textured:3"),
              plain = loadScene("builtin:demo");
  const WorldGeometry ga = WorldGeometry::fromScene(a), gb = WorldGeometry::fromScene(b),
                      gp = WorldGeometry::fromScene(plain);
  for (Method m : {Method::Ppll, Method::Cells}) {
    SCOPED_TRACE(methodName(m));
    FrameSettings s = test::settingsFor(a, 128, 30, 20);
    s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache";
    auto shared = makeRenderer(m);
    const Image a1 = shared->render(ga, s).image;
    shared->render(gp, s);
    const Image b1 = shared->render(gb, s).image;
    s.atlas = AtlasChoice::Uniform;
    const Image a2 = shared->render(ga, s).image;
    s.atlas = AtlasChoice::Packed;
    EXPECT_EQ(compareImages(b1, makeRenderer(m)->render(gb, s).image).max_abs, 0);
    const Image fresh = makeRenderer(m)->render(ga, s).image;
    EXPECT_EQ(compareImages(a1, fresh).max_abs, 0);
    EXPECT_EQ(compareImages(a2, fresh).max_abs, 0);
  }
}

// A texture replaced by a reloaded one (the old image freed, a new one of other texels made,
// perhaps at the same address) must reach a reused renderer: its image equals a fresh one's.
TEST(TextureAtlas, ReusedRendererSeesAReloadedTexture) {
  const auto solid = [](const glm::vec4& c) {
    auto im = std::make_shared<TextureImage>();
    im->width = im->height = 16;
    im->texels.assign(256, c);
    return std::shared_ptr<const TextureImage>(std::move(im));
  };
  Scene scene = loadScene("builtin:textured:4");
  FrameSettings s = test::settingsFor(scene, 96, 30, 20);
  for (Method m : {Method::Opaque, Method::Cells}) {
    SCOPED_TRACE(methodName(m));
    const std::unique_ptr<MethodRenderer> reused = makeRenderer(m);
    for (const glm::vec4& c : {glm::vec4(1, 0, 0, 1), glm::vec4(0, 0, 1, 1)}) {
      for (SceneTexture& t : scene.textures) t.image = solid(c);  // the old images are freed
      WorldGeometry g = WorldGeometry::fromScene(scene);
      const Image again = reused->render(g, s).image;
      const Image fresh = makeRenderer(m)->render(g, s).image;
      EXPECT_EQ(compareImages(again, fresh).max_abs, 0);
    }
  }
}

// A texture as wide as the loader allows still gets a page (its gutter makes the page wider than
// the texture), and samples as the reference does.
TEST(TextureAtlas, WidestTextureFitsAPage) {
  Scene scene;
  scene.source = "test:widest";
  auto im = std::make_shared<TextureImage>();
  im->width = kMaxTextureSize;
  im->height = 64;
  im->texels.resize(size_t(im->width) * size_t(im->height));
  for (int y = 0; y < im->height; ++y)
    for (int x = 0; x < im->width; ++x)
      im->texels[size_t(y) * size_t(im->width) + size_t(x)] =
          glm::vec4(float((x / 256) & 1), float((y / 8) & 1), float(x) / float(im->width), 1.0f);
  scene.textures.push_back({"widest", im});
  Material m;
  m.color = glm::vec4(1.0f);
  m.opacity = 1.0f;
  m.texture = 0;
  m.sampler.filter = Filter::Bilinear;
  scene.materials.push_back(m);
  Mesh quad;
  quad.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
  quad.texcoords = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  quad.indices = {0, 1, 2, 0, 2, 3};
  scene.meshes.push_back(quad);
  scene.instances.push_back({0, glm::mat4(1.0f), 0, "quad"});
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s = test::settingsFor(scene, 256, 0, 0);
  for (AtlasChoice mode : {AtlasChoice::Packed, AtlasChoice::Uniform, AtlasChoice::Off}) {
    s.atlas = mode;
    SCOPED_TRACE(atlasChoiceName(mode));
    const RenderResult a = makeRenderer(Method::Opaque)->render(g, s);
    EXPECT_EQ(a.stats.atlas_pages, 1u);
    test::expectImagesMatch(a.image, makeEmbreeRenderer(EmbreeMode::Opaque)->render(g, s).image,
                            std::string("widest-") + atlasChoiceName(mode));
  }
}

}  // namespace
}  // namespace strata
