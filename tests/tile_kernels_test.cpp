// The two forms of the per-tile kernels (FrameSettings::tile_kernels): a work-group per tile, or
// a work-item alone per tile. Every OpenCL method on the shared front end gives the same images,
// counts, losses and per-pixel depth complexity with either, on meshes, textured and instanced
// scenes and frames whose size is not a whole number of tiles; picking finds the same fragments;
// the octree resolve agrees in every variant.
#include "engine/features/picking.h"
#include "engine/frontend/texture_shading.h"
#include "test_support.h"

namespace strata {
namespace {

struct TileCase {
  std::string scene, texture, label;
  int width = 256, height = 256;
};

std::vector<TileCase> tileCases() {
  return {
      {test::modelPath("horse.ply"), "", "horse"},
      {test::modelPath("spot.obj"), test::modelPath("spot_texture.png"), "spot-textured"},
      {"builtin:spheres:16", "", "spheres16"},
      {"builtin:crowd:6", "", "crowd-instanced"},
      {test::modelPath("teapot.obj"), "", "teapot-odd-size", 203, 157},
      {"builtin:demo", "", "demo"},
  };
}

FrameSettings settingsOf(const Scene& scene, const TileCase& c) {
  FrameSettings s = test::settingsFor(scene, c.width, 35.0f, 20.0f);
  s.width = c.width;
  s.height = c.height;
  s.capture_depth_complexity = true;
  return s;
}

// The frame in the group and the serial form: the same image to the bit (written on failure as
// NAME), fragments and deepest pixel. Returns (group, serial).
std::pair<RenderResult, RenderResult> renderBothForms(MethodRenderer& renderer,
                                                      const WorldGeometry& g, FrameSettings s,
                                                      const std::string& name) {
  s.tile_kernels = "group";
  RenderResult group = renderer.render(g, s);
  s.tile_kernels = "serial";
  RenderResult serial = renderer.render(g, s);
  EXPECT_EQ(group.stats.tile_kernels, "group");
  EXPECT_EQ(serial.stats.tile_kernels, "serial");
  EXPECT_EQ(compareImages(serial.image, group.image).max_abs, 0);
  test::expectImagesMatch(serial.image, group.image, name, 1.0);
  EXPECT_GT(serial.stats.fragments, 0u);
  EXPECT_EQ(serial.stats.fragments, group.stats.fragments);
  EXPECT_EQ(serial.stats.max_depth_complexity, group.stats.max_depth_complexity);
  return {std::move(group), std::move(serial)};
}

TEST(TileKernels, SerialAndGroupAgree) {
  struct MethodCase {
    Method method;
    std::string label;
    int k = 64;  // abuffer's budget: large enough to lose nothing (then the records are the same)
    bool global_slots = false;  // mdts's slots, bdp's buckets in global memory
    bool lossless = true;       // bdp and bdp2 lose colliding fragments by design
  };
  const std::vector<MethodCase> methods = {
      {Method::Opaque, "opaque"},
      {Method::Ppll, "ppll"},
      {Method::Abuffer, "abuffer"},
      {Method::Mdts, "mdts", 6},  // mdts keeps the nearest K in either form, losses included
      {Method::Mdts, "mdts-global", 64, true},
      {Method::Mdts32, "mdts32", 64},
      {Method::Mdts32, "mdts32-global", 3, true},
      {Method::Dp, "dp"},
      {Method::Ddp, "ddp"},
      {Method::Bdp, "bdp", 16, false, false},
      {Method::Bdp, "bdp-global", 16, true, false},
      {Method::Bdp2, "bdp2", 16, false, false},
  };
  for (const MethodCase& m : methods) {
    auto renderer = makeRenderer(m.method);
    for (const TileCase& c : tileCases()) {
      SCOPED_TRACE(m.label + " " + c.label);
      Scene scene = loadScene(c.scene);
      if (!c.texture.empty()) applyTexture(scene, c.texture);
      const WorldGeometry g = WorldGeometry::fromScene(scene);
      FrameSettings s = settingsOf(scene, c);
      s.k = m.k;
      s.mdts.global_slots = m.global_slots;
      s.bucket.global_buckets = m.global_slots;
      const auto [group, serial] =
          renderBothForms(*renderer, g, s, "tiles-serial-" + m.label + "-" + c.label);
      EXPECT_EQ(serial.stats.fragments_lost, group.stats.fragments_lost);
      EXPECT_EQ(serial.stats.geometry_passes, group.stats.geometry_passes);
      if (m.lossless && m.k >= 64) {
        EXPECT_EQ(serial.stats.fragments_lost, 0u);
      }
      EXPECT_EQ(serial.depth_complexity, group.depth_complexity);
      EXPECT_EQ(serial.depth_complexity.size(), size_t(c.width) * size_t(c.height));
    }
  }
}

// Past its budget the A-buffer keeps the first K fragments to arrive, and the two forms deliver
// them in different orders; what each loses is still counted the same.
TEST(TileKernels, AbufferCountsTheSameLossInEitherForm) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  FrameSettings s = test::settingsFor(scene, 256, 90.0f, 10.0f);
  s.k = 2;
  auto abuffer = makeRenderer(Method::Abuffer);
  s.tile_kernels = "group";
  const RenderResult group = abuffer->render(g, s);
  s.tile_kernels = "serial";
  const RenderResult serial = abuffer->render(g, s);
  EXPECT_GT(group.stats.fragments_lost, 0u);
  EXPECT_EQ(serial.stats.fragments_lost, group.stats.fragments_lost);
  EXPECT_EQ(serial.stats.fragments, group.stats.fragments);
  EXPECT_EQ(serial.stats.bytes_needed, group.stats.bytes_needed);
}

// The serial binner lists every tile's records in slot (world triangle) order, whatever the
// batching and the draw order: so abuffer, keeping the first K fragments a pixel meets, loses
// the same ones and renders the same image under every batching and sort.
TEST(TileKernels, SerialBinnerKeepsTheSlotOrder) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:spheres:16");
  FrameSettings s = test::settingsFor(scene, 192, 35.0f, 20.0f);
  s.k = 3;
  s.tile_kernels = "serial";
  auto abuffer = makeRenderer(Method::Abuffer);
  s.batch = Batch::Static;
  s.sort = DrawSort::None;
  const RenderResult first = abuffer->render(g, s);
  ASSERT_GT(first.stats.fragments_lost, 0u);
  struct Variant {
    Batch batch;
    DrawSort sort;
    const char* label;
  };
  for (const Variant& v : {Variant{Batch::None, DrawSort::Depth, "none-depth"},
                           Variant{Batch::Instanced, DrawSort::Key, "instanced-key"},
                           Variant{Batch::None, DrawSort::Gray, "none-gray"}}) {
    SCOPED_TRACE(v.label);
    s.batch = v.batch;
    s.sort = v.sort;
    const RenderResult other = abuffer->render(g, s);
    EXPECT_EQ(other.stats.fragments_lost, first.stats.fragments_lost);
    EXPECT_EQ(compareImages(other.image, first.image).max_abs, 0);
    test::expectImagesMatch(other.image, first.image,
                            std::string("tiles-serial-slot-order-") + v.label, 1.0);
  }
}

TEST(TileKernels, PickingFindsTheSameFragments) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  FrameSettings s = test::settingsFor(scene, 160, 30.0f, 20.0f);
  std::vector<glm::ivec2> pixels;
  for (int y = 3; y < s.height; y += 7)
    for (int x = 2; x < s.width; x += 5) pixels.push_back({x, y});
  IdPicker picker;
  s.tile_kernels = "group";
  const PickResult group = picker.pick(g, s, pixels, true);
  s.tile_kernels = "serial";
  const PickResult serial = picker.pick(g, s, pixels, true);
  ASSERT_EQ(serial.pixels.size(), group.pixels.size());
  size_t hits = 0, layers = 0;
  for (size_t i = 0; i < pixels.size(); ++i) {
    const PickedPixel &a = serial.pixels[i], &b = group.pixels[i];
    SCOPED_TRACE(testing::Message() << "pixel " << pixels[i].x << "," << pixels[i].y);
    ASSERT_EQ(a.status, b.status);
    if (a.status != PickStatus::Hit) continue;
    ++hits;
    EXPECT_EQ(a.front.triangle, b.front.triangle);
    EXPECT_EQ(a.front.depth, b.front.depth);
    ASSERT_EQ(a.layers.size(), b.layers.size());
    for (size_t l = 0; l < a.layers.size(); ++l) {
      EXPECT_EQ(a.layers[l].triangle, b.layers[l].triangle);
      EXPECT_EQ(a.layers[l].depth, b.layers[l].depth);
    }
    layers += a.layers.size();
  }
  EXPECT_GT(hits, 50u);
  EXPECT_GT(layers, 2 * hits);
}

// The octree resolve in either form: the same images, fragments and walks for every variant,
// with small k (many walks), the early out, translucency and frames of several batches (whose
// middle batches carry the accumulator through).
TEST(TileKernels, OctreeResolveFormsAgree) {
  struct OctreeCase {
    std::string scene, variant, label;
    uint32_t k = 32, leaf_tris = 2000;
    bool early_out = false, translucency = false;
    size_t batch = size_t(1) << 20;
  };
  const std::vector<OctreeCase> cases = {
      {"builtin:spheres:16", "kbuffer", "spheres-kbuffer"},
      {"builtin:spheres:16", "kbuffer", "spheres-k2", 2, 500},
      {"builtin:spheres:16", "blocks-histogram", "spheres-blocks-histogram"},
      {"builtin:spheres:16", "blocks", "spheres-blocks-early-out", 32, 2000, true},
      {"builtin:spheres:16", "dp", "spheres-dp"},
      {test::modelPath("horse.ply"), "kbuffer", "horse-translucent", 4, 3000, false, true},
      {"builtin:city:6", "kbuffer", "city-batches", 8, 1500, false, false, 4000},
  };
  auto octree = makeRenderer(Method::Octree);
  for (const OctreeCase& c : cases) {
    SCOPED_TRACE(c.label);
    const auto [scene, g] = test::sceneAndGeometry(c.scene);
    FrameSettings s = test::settingsFor(scene, 160, 35.0f, 20.0f);
    s.width = 203;  // not a whole number of tiles or blocks
    s.height = 157;
    s.octree.variant = c.variant;
    s.octree.k = c.k;
    s.octree.leaf_triangles = c.leaf_tris;
    s.octree.early_out = c.early_out;
    s.octree.batch_triangles = c.batch;
    s.effect = c.translucency ? Effect::Translucency : Effect::Transparency;
    s.capture_depth_complexity = true;
    const auto [group, serial] = renderBothForms(*octree, g, s, "tiles-serial-octree-" + c.label);
    EXPECT_EQ(serial.stats.tile_walks, group.stats.tile_walks);
    EXPECT_EQ(serial.stats.leaf_layers_max, group.stats.leaf_layers_max);
    EXPECT_EQ(serial.stats.bin_entry_reads, group.stats.bin_entry_reads);
    EXPECT_EQ(serial.stats.batches, group.stats.batches);
    if (c.batch < 10000) {
      EXPECT_GT(serial.stats.batches, 1u);
    }
    EXPECT_EQ(serial.depth_complexity, group.depth_complexity);
  }
}

TEST(TileKernels, UnknownFormIsRefused) {
  const WorldGeometry g = WorldGeometry::fromScene(loadScene("builtin:demo"));
  FrameSettings s;
  s.tile_kernels = "vectorised";
  for (Method m : {Method::Opaque, Method::Ppll, Method::Cells}) {
    SCOPED_TRACE(methodName(m));
    try {
      makeRenderer(m)->render(g, s);
      ADD_FAILURE() << "rendered with an unknown tile kernel form";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("vectorised"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace strata
