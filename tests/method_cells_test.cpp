// The convex-cells method (`cells`) against the Embree reference: transparency and translucency
// on every shared model, the depth-test scenes and the demo from 8 views at 512x512; its memory
// promise (fragment memory independent of depth); every triangle read once; bad input.
#include <filesystem>

#include <glm/gtc/matrix_transform.hpp>

#include "engine/cells/cell_order.h"
#include "engine/frontend/texture_shading.h"
#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "preprocess/mesh_loader.h"
#include "test_support.h"

namespace strata {
namespace {

std::string cacheDir() { return std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache"; }

using Case = test::SceneCase;

std::vector<Case> cases() { return test::sharedSceneCases({16, 96}); }

// Eight views all round, above and below.
const float kViews[8][2] = {{0, 15},   {45, -30},  {90, 45}, {135, -10},
                            {180, 70}, {225, -60}, {270, 5}, {315, 30}};

FrameSettings settingsFor(const Scene& scene, int size, float az, float el) {
  FrameSettings s = test::settingsFor(scene, size, az, el);
  if (scene.default_projection) {
    // The depth-test scenes keep their orthographic projection, turned by the view.
    OrbitView v = scene.default_view.value_or(OrbitView{});
    v.azimuth_deg = az;
    v.elevation_deg = el;
    v.ortho_height.reset();
    s.camera = Camera::orbit(scene.boundingSphere(), v, *scene.default_projection);
  }
  s.cell_cache_dir = cacheDir();
  return s;
}

class CellsImages : public test::SceneImageTest<Case> {};

TEST_P(CellsImages, TransparencyMatchesEmbreeFromEightViews) {
  const Case& c = GetParam();
  auto cells = makeRenderer(Method::Cells);
  for (const auto& v : kViews) {
    const FrameSettings s = settingsFor(scene, 512, v[0], v[1]);
    const RenderResult ref = embree->render(g, s);
    const RenderResult a = cells->render(g, s);
    SCOPED_TRACE(c.label + " view " + std::to_string(int(v[0])) + "," + std::to_string(int(v[1])));
    EXPECT_EQ(a.stats.triangles_read, a.stats.triangles);  // every triangle read once
    EXPECT_EQ(a.stats.fragments_lost, 0u);
    EXPECT_GT(a.stats.fragments, 0u);
    EXPECT_GT(a.stats.cells, 0u);
    test::expectImagesMatch(
        a.image, ref.image,
        "cells-" + c.label + "-" + std::to_string(int(v[0])) + "_" + std::to_string(int(v[1])));
  }
}

TEST_P(CellsImages, TranslucencyMatchesEmbree) {
  const Case& c = GetParam();
  auto cells = makeRenderer(Method::Cells);
  for (int i = 0; i < 8; ++i) {
    FrameSettings s = settingsFor(scene, 512, kViews[i][0], kViews[i][1]);
    s.effect = Effect::Translucency;
    s.sigma = 2.0f / scene.boundingSphere().radius;
    const RenderResult ref = embree->render(g, s);
    const RenderResult a = cells->render(g, s);
    SCOPED_TRACE(c.label + " view " + std::to_string(i));
    test::expectImagesMatch(a.image, ref.image,
                            "cells-translucency-" + c.label + "-" + std::to_string(i));
  }
}

INSTANTIATE_TEST_SUITE_P(Models, CellsImages, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           std::string n = i.param.label;
                           for (char& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

// The paper's point: fragment memory does not grow with depth. At 1024x1024 the layers and the
// accumulator fit in 16 MB, and every working buffer is the same for 16 and 96 layers but for the
// projected scene vertices (screen, per vertex) and, where the device finds the
// order's masks and pairs (`order_masks` device), their buffers, which grow with the cells on
// screen.
TEST(Cells, MemoryIndependentOfDepth) {
  for (const char* masks : {"host", "device"}) {
    SCOPED_TRACE(std::string("order masks on the ") + masks);
    auto cells = makeRenderer(Method::Cells);
    FrameStats st[2];
    uint64_t vertex_bytes[2];
    const int layers[2] = {16, 96};
    for (int i = 0; i < 2; ++i) {
      const auto [scene, g] =
          test::sceneAndGeometry("builtin:spheres:" + std::to_string(layers[i]));
      FrameSettings s;
      s.width = s.height = 1024;
      s.camera =
          Camera::orbit(scene.boundingSphere(), *scene.default_view, *scene.default_projection);
      s.cell_cache_dir = cacheDir();
      s.cells.order_masks = masks;
      s.cells.batch_triangles = size_t(1) << 20;  // both scenes in several batches of this size
      st[i] = cells->render(g, s).stats;
      vertex_bytes[i] = g.positions.size() * sizeof(StScreenVertex) + st[i].order_device_bytes;
      EXPECT_EQ(st[i].max_depth_complexity, uint64_t(layers[i]));
      EXPECT_LE(st[i].fragment_bytes, 16u * 1000u * 1000u);
      EXPECT_EQ(st[i].triangles_read, st[i].triangles);
      EXPECT_EQ(st[i].fragments_lost, 0u);
      EXPECT_EQ(st[i].order_masks, masks);
    }
    EXPECT_EQ(st[0].fragment_bytes, st[1].fragment_bytes);
    EXPECT_EQ(st[0].device_bytes - vertex_bytes[0], st[1].device_bytes - vertex_bytes[1]);
    EXPECT_GT(st[1].batches, st[0].batches);  // the deeper scene streams more batches through
  }
}

// A renderer that drew a large scene and then a small one holds the small one's working set, as
// a fresh renderer would (a benchmark reports each scene's device memory from one renderer).
TEST(Cells, ASmallSceneAfterALargeOneHoldsItsOwnWorkingSet) {
  auto render = [](MethodRenderer& r, const std::string& spec) {
    const auto [scene, g] = test::sceneAndGeometry(spec);
    FrameSettings s = test::settingsFor(scene, 256, 30.0f, 20.0f);
    s.cell_cache_dir = cacheDir();
    return r.render(g, s).stats;
  };
  const std::string small = test::modelPath("teapot.obj");
  auto fresh = makeRenderer(Method::Cells);
  const FrameStats alone = render(*fresh, small);
  auto reused = makeRenderer(Method::Cells);
  const FrameStats large = render(*reused, "builtin:spheres:16");
  const FrameStats after = render(*reused, small);
  EXPECT_GT(large.device_bytes, 4 * alone.device_bytes);
  EXPECT_EQ(after.device_bytes, alone.device_bytes);
  EXPECT_EQ(after.fragments, alone.fragments);
}

// Every covered pixel centre of every triangle is one fragment, so the fragments the cells
// composite and the octree resolve count, and the deepest pixel, equal ppll's (the same setup and
// raster rules): on views that fill the image, and on views where the model covers a few tiles
// and most work-groups skip theirs. Frames of one batch and of many (500-triangle batches).
TEST(Cells, FragmentCountsOfCellsAndOctreeEqualPpll) {
  auto cells = makeRenderer(Method::Cells);
  auto octree = makeRenderer(Method::Octree);
  auto ppll = makeRenderer(Method::Ppll);
  for (const char* model : {"horse.ply", "teapot.obj"}) {
    const auto [scene, g] = test::sceneAndGeometry(test::modelPath(model));
    for (const float distance : {0.0f, 3.0f, 25.0f}) {
      for (const size_t batch : {size_t(1) << 20, size_t(500)}) {
        FrameSettings s = test::settingsFor(scene, 512, 60.0f, 20.0f);
        if (distance > 0.0f) s.camera = test::orbitCamera(scene, 60.0f, 20.0f, distance);
        s.cell_cache_dir = cacheDir();
        s.cells.batch_triangles = batch;
        s.octree.batch_triangles = batch;
        s.octree.leaf_triangles = 256;  // leaves small enough for many batches
        const FrameStats a = cells->render(g, s).stats;
        const FrameStats o = octree->render(g, s).stats;
        const FrameStats b = ppll->render(g, s).stats;
        SCOPED_TRACE(std::string(model) + " distance " + std::to_string(distance) + " batch " +
                     std::to_string(batch));
        EXPECT_EQ(a.fragments, b.fragments);
        EXPECT_EQ(a.max_depth_complexity, b.max_depth_complexity);
        EXPECT_EQ(o.fragments, b.fragments);
        EXPECT_EQ(o.max_depth_complexity, b.max_depth_complexity);
        EXPECT_GT(a.fragments, 0u);
        if (batch < 4000) {
          EXPECT_GT(a.batches, 1u);
          EXPECT_GT(o.batches, 1u);
        }
      }
    }
  }
}

// A frame of many batches carries each pixel's result from batch to batch, and a batch leaves
// the pixels it does not reach as the earlier ones left them: the image equals the one-batch
// frame's to the accumulator's rounding (1/255), on views that fill the image and where the
// model covers a few tiles, for cells and the octree, with transparency and translucency.
TEST(Cells, FramesOfManyBatchesEqualFramesOfOne) {
  auto cells = makeRenderer(Method::Cells);
  auto octree = makeRenderer(Method::Octree);
  for (const char* model : {"horse.ply", "teapot.obj"}) {
    const auto [scene, g] = test::sceneAndGeometry(test::modelPath(model));
    for (const Effect effect : {Effect::Transparency, Effect::Translucency}) {
      for (const float distance : {0.0f, 6.0f}) {
        FrameSettings s = test::settingsFor(scene, 256, 30.0f, 20.0f);
        if (distance > 0.0f) s.camera = test::orbitCamera(scene, 30.0f, 20.0f, distance);
        s.effect = effect;
        s.sigma = 2.0f / scene.boundingSphere().radius;
        s.cell_cache_dir = cacheDir();
        s.octree.leaf_triangles = 256;  // leaves small enough for many batches
        for (MethodRenderer* r : {cells.get(), octree.get()}) {
          const bool is_cells = r == cells.get();
          SCOPED_TRACE(std::string(model) + (is_cells ? " cells" : " octree") +
                       (effect == Effect::Translucency ? " translucency" : " transparency") +
                       " distance " + std::to_string(distance));
          s.cells.batch_triangles = s.octree.batch_triangles = size_t(1) << 20;
          const RenderResult one = r->render(g, s);
          s.cells.batch_triangles = s.octree.batch_triangles = 300;
          const RenderResult many = r->render(g, s);
          EXPECT_EQ(one.stats.batches, 1u);
          EXPECT_GT(many.stats.batches, 3u);
          EXPECT_EQ(many.stats.fragments, one.stats.fragments);
          EXPECT_EQ(many.stats.max_depth_complexity, one.stats.max_depth_complexity);
          EXPECT_LE(compareImages(many.image, one.image).max_abs, 1);
          test::expectImagesMatch(many.image, one.image,
                                  std::string("batches-") + (is_cells ? "cells-" : "octree-") +
                                      std::filesystem::path(model).stem().string(),
                                  1.0);
        }
      }
    }
  }
}

// Under a memory budget the batches are sized to fit it: the frame stays within the budget
// (device memory and the scene) and is the unbudgeted frame, in many batches; a budget too small
// for the largest group is refused naming the budget.
TEST(Cells, MemoryBudgetSizesTheBatches) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  auto cells = makeRenderer(Method::Cells);
  const uint64_t scene_bytes = g.positions.size() * 12 + g.indices.size() * 4 +
                               g.triangle_material.size() * 4 + g.material_colors.size() * 16;
  for (const Effect effect : {Effect::Transparency, Effect::Translucency}) {
    FrameSettings s = test::settingsFor(scene, 256, 30.0f, 20.0f);
    s.effect = effect;
    s.sigma = 2.0f / scene.boundingSphere().radius;
    s.cell_cache_dir = cacheDir();
    const RenderResult free = cells->render(g, s);
    EXPECT_EQ(free.stats.batches, 1u);
    const uint64_t need = free.stats.device_bytes + scene_bytes;
    for (const uint64_t budget : {need * 3 / 4, need / 2}) {
      s.memory_budget = budget;
      const RenderResult within = cells->render(g, s);
      SCOPED_TRACE("budget " + std::to_string(budget) + " of " + std::to_string(need));
      EXPECT_GT(within.stats.batches, 1u);
      EXPECT_LE(within.stats.device_bytes + scene_bytes, budget);
      EXPECT_EQ(within.stats.fragments, free.stats.fragments);
      EXPECT_LE(compareImages(within.image, free.image).max_abs, 1);
    }
    s.memory_budget = 1 << 20;
    try {
      cells->render(g, s);
      ADD_FAILURE() << "a 1 MB budget was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("memory budget of 1.0 MB is too small"),
                std::string::npos)
          << e.what();
    }
  }
}

// The two composite kernels (a work-group per block of tiles, for GPUs; a work-item per block,
// for CPUs), each with its form of the ordered binner (serial runs, or atomic appends sorted per
// tile), composite the same fragments in the same order: byte-identical images and the same
// counts, over one batch and many, both layer rules, translucency, texturing, the stacked
// spheres (whole passes, no segments), a view where most blocks have nothing to draw, and a
// frame so small that tile lists run to thousands of entries (longer than one local sort).
TEST(Cells, SerialAndGroupCompositesAgree) {
  struct Variant {
    std::string scene, texture, label;
    Effect effect = Effect::Transparency;
    size_t batch = size_t(1) << 20;
    std::string decompose = "strict";
    float distance = 0.0f;
    int size = 320;
  };
  const std::vector<Variant> variants = {
      {test::modelPath("horse.ply"), "", "horse"},
      {test::modelPath("horse.ply"), "", "horse-translucency", Effect::Translucency},
      {test::modelPath("horse.ply"), "", "horse-far", Effect::Transparency, size_t(1) << 20,
       "strict", 25.0f},
      {test::modelPath("teapot.obj"), "", "teapot-batches", Effect::Translucency, 500},
      {test::modelPath("teapot.obj"), "", "teapot-paper", Effect::Transparency, size_t(1) << 20,
       "paper"},
      {test::modelPath("spot.obj"), test::modelPath("spot_texture.png"), "spot-textured"},
      {"builtin:spheres:16", "", "spheres16"},
      {"builtin:demo", "", "demo-merged"},  // one group of merged cells: the k-buffer path
      {test::modelPath("horse.ply"), "", "horse-long-tile-lists", Effect::Transparency,
       size_t(1) << 20, "strict", 0.0f, 24},
  };
  auto cells = makeRenderer(Method::Cells);
  for (const Variant& v : variants) {
    SCOPED_TRACE(v.label);
    Scene scene = loadScene(v.scene);
    if (!v.texture.empty()) applyTexture(scene, v.texture);
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    FrameSettings s = settingsFor(scene, v.size, 40.0f, 25.0f);
    if (v.distance > 0.0f) s.camera = test::orbitCamera(scene, 40.0f, 25.0f, v.distance);
    s.effect = v.effect;
    s.sigma = 2.0f / scene.boundingSphere().radius;
    s.cells.batch_triangles = v.batch;
    s.decompose = v.decompose;
    s.cells.composite = "group";
    const RenderResult group = cells->render(g, s);
    s.cells.composite = "serial";
    const RenderResult serial = cells->render(g, s);
    EXPECT_EQ(compareImages(serial.image, group.image).max_abs, 0);
    test::expectImagesMatch(serial.image, group.image, "cells-serial-" + v.label, 1.0);
    EXPECT_EQ(serial.stats.fragments, group.stats.fragments);
    EXPECT_GT(serial.stats.fragments, 0u);
    EXPECT_EQ(serial.stats.max_depth_complexity, group.stats.max_depth_complexity);
    EXPECT_EQ(serial.stats.fragments_lost, group.stats.fragments_lost);
    EXPECT_EQ(serial.stats.batches, group.stats.batches);
    if (v.batch < 1000) {
      EXPECT_GT(serial.stats.batches, 1u);
    }
    EXPECT_EQ(group.stats.cells_composite, "group");
    EXPECT_EQ(serial.stats.cells_composite, "serial");
    EXPECT_EQ(serial.stats.cell_tile_segments, 0u);  // the serial composite needs none
    // Back to the group kernel on the same renderer: the order is cut into segments again.
    s.cells.composite = "group";
    const RenderResult again = cells->render(g, s);
    EXPECT_EQ(compareImages(again.image, group.image).max_abs, 0);
    EXPECT_EQ(again.stats.cell_tile_segments, group.stats.cell_tile_segments);
    // The group kernel without tile segments: every pass a segment of its own.
    s.cells.tile_segments = "off";
    const RenderResult unsegmented = cells->render(g, s);
    EXPECT_EQ(compareImages(unsegmented.image, group.image).max_abs, 0);
    test::expectImagesMatch(unsegmented.image, group.image, "cells-unsegmented-" + v.label, 1.0);
    EXPECT_EQ(unsegmented.stats.cell_tile_segments, 0u);
    EXPECT_EQ(unsegmented.stats.cells_composite, "group");
    EXPECT_EQ(unsegmented.stats.fragments, group.stats.fragments);
    s.cells.tile_segments = "auto";
  }
  FrameSettings s;
  s.cells.composite = "fastest";
  EXPECT_THROW(cells->render(WorldGeometry::fromScene(loadScene("builtin:demo")), s), Error);
}

// Inputs that are not clean manifolds still render exactly: triangle soup (every corner its own
// vertex), duplicated faces, a non-manifold fan, zero-area faces, flipped windings.
TEST(Cells, MessyInputRendersExactly) {
  Scene scene;
  scene.source = "messy";
  Mesh torus = makeTorus(1.0f, 0.35f, 48, 24);
  Mesh soup;
  for (size_t t = 0; t < torus.triangleCount(); ++t) {
    for (int k = 0; k < 3; ++k) {
      soup.positions.push_back(torus.positions[torus.indices[3 * t + (t % 7 == 0 ? 2 - k : k)]]);
      soup.indices.push_back(uint32_t(soup.positions.size() - 1));
    }
    if (t % 11 == 0)  // duplicate face
      for (int k = 0; k < 3; ++k) soup.indices.push_back(soup.indices[soup.indices.size() - 3]);
  }
  // Non-manifold fan: five triangles on one edge, and a zero-area sliver.
  const uint32_t base = uint32_t(soup.positions.size());
  soup.positions.push_back({0, -1, 0});
  soup.positions.push_back({0, 1, 0});
  for (int i = 0; i < 5; ++i) {
    const float a = 1.2566f * float(i);
    soup.positions.push_back({1.5f * std::cos(a), 0.2f, 1.5f * std::sin(a)});
    soup.indices.insert(soup.indices.end(), {base, base + 1, base + 2 + uint32_t(i)});
  }
  soup.indices.insert(soup.indices.end(), {base, base, base + 1});
  scene.meshes.push_back(soup);
  scene.materials.push_back(Material{});
  scene.instances.push_back(Instance{});
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  auto cells = makeRenderer(Method::Cells);
  for (int i = 0; i < 8; i += 2) {
    const FrameSettings s = settingsFor(scene, 256, kViews[i][0], kViews[i][1]);
    test::expectMatchesEmbree(cells->render(g, s).image, g, s, "cells-messy-" + std::to_string(i));
  }
}

// Faces repeated many times: one quad through a torus 40 times (the copies merged with the torus
// cells it crosses), another beside it 40 times (the copies drawn one after another), each in
// three meshes of their own colour and opacity and instanced twice. Equal depths composite in
// triangle order, as in ppll (the same image, bit for bit) and the reference (within its
// tolerance), in transparency and translucency, and the copies take no part in the pairs.
TEST(Cells, CoincidentCopiesRenderExactly) {
  Scene scene;
  scene.source = "copies";
  scene.meshes.push_back(makeTorus(1.0f, 0.35f, 32, 16));
  scene.materials.push_back(Material{});
  const glm::vec4 colours[3] = {
      {1, 0.2f, 0.1f, 0.3f}, {0.1f, 1, 0.2f, 0.5f}, {0.2f, 0.3f, 1, 0.2f}};
  for (int m = 0; m < 3; ++m) {
    Mesh quads;
    quads.positions = {{-1.2f, -0.1f, -1.2f}, {1.2f, 0.1f, -1.2f}, {1.2f, 0.1f, 1.2f},
                       {-1.2f, -0.1f, 1.2f},  {1.8f, -0.5f, 0.0f}, {2.8f, -0.5f, 0.2f},
                       {2.6f, 0.6f, 0.1f},    {1.9f, 0.5f, -0.1f}};
    for (int k = 0; k < 40; ++k)
      quads.indices.insert(quads.indices.end(), {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7});
    quads.material = uint32_t(scene.materials.size());
    Material mat;
    mat.color = colours[m];
    mat.opacity = colours[m].w;
    scene.materials.push_back(mat);
    scene.meshes.push_back(quads);
  }
  for (uint32_t i = 0; i < 4; ++i) {
    Instance in;
    in.mesh = i;
    scene.instances.push_back(in);
    in.transform = glm::translate(glm::mat4(1.0f), glm::vec3(0.3f, 2.0f, 0.2f));
    scene.instances.push_back(in);
  }
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const CellScene cs = CellScene::build(g, DecomposeOptions{}, cacheDir());
  EXPECT_EQ(cs.copy_cells, 3u * 2u * 2u * 39u * 2u);
  for (uint32_t c = 0; c < cs.cellCount(); ++c)
    if (cs.isCopy(c)) {
      EXPECT_EQ(cs.neighbour_first[c], cs.neighbour_first[c + 1]);
    }
  auto ppll = makeRenderer(Method::Ppll);
  auto cells = makeRenderer(Method::Cells);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (Effect effect : {Effect::Transparency, Effect::Translucency}) {
    for (int i = 0; i < 8; i += 2) {
      FrameSettings s = settingsFor(scene, 192, kViews[i][0], kViews[i][1]);
      s.effect = effect;
      const std::string name = std::string("cells-copies-") +
                               (effect == Effect::Transparency ? "t" : "l") + std::to_string(i);
      const RenderResult a = cells->render(g, s);
      EXPECT_EQ(a.stats.fragments_lost, 0u);
      test::expectImagesMatch(a.image, embree->render(g, s).image, name);
      if (effect == Effect::Transparency) {
        const RenderResult b = ppll->render(g, s);
        EXPECT_EQ(a.stats.fragments, b.stats.fragments);
        test::expectImagesMatch(a.image, b.image, name + "-ppll", 1.0);
        EXPECT_EQ(compareImages(a.image, b.image).max_abs, 0) << name;
      }
    }
  }
  // Close up, the second instance's copies off screen and the first's partly on it.
  FrameSettings s = settingsFor(scene, 192, 0.0f, 0.0f);
  s.camera = Camera::lookAt({0.0f, -0.6f, 2.5f}, {1.2f, -0.6f, 0.0f});
  const RenderResult a = cells->render(g, s);
  test::expectImagesMatch(a.image, embree->render(g, s).image, "cells-copies-close");
  EXPECT_EQ(compareImages(a.image, ppll->render(g, s).image).max_abs, 0);
}

// 3,000 slivers across a box, each box overlapping most others: more pairs than the bound, so
// the mesh is drawn as one merged group without pairs, as exact as ppll (the same image) and
// within the reference's tolerance, and says so in the statistics.
TEST(Cells, MeshPastThePairBoundIsOneMergedGroup) {
  Scene scene;
  scene.source = "slivers";
  Mesh m;
  test::SignedUniform next(5);
  for (uint32_t t = 0; t < 3000; ++t) {
    const glm::vec3 a(-1.0f, next(), next()), b(1.0f, next(), next());
    m.positions.insert(m.positions.end(), {a, b, b + glm::vec3(0.0f, 0.04f, 0.02f)});
    m.indices.insert(m.indices.end(), {3 * t, 3 * t + 1, 3 * t + 2});
  }
  scene.meshes.push_back(m);
  Material mat;
  mat.opacity = 0.4f;
  scene.materials.push_back(mat);
  scene.instances.push_back(Instance{});
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const CellScene cs = CellScene::build(g, DecomposeOptions{}, cacheDir());
  EXPECT_EQ(cs.unpaired_parts, 1u);
  EXPECT_TRUE(cs.neighbours.empty());
  auto cells = makeRenderer(Method::Cells);
  auto ppll = makeRenderer(Method::Ppll);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (int i = 0; i < 8; i += 3) {
    const FrameSettings s = settingsFor(scene, 160, kViews[i][0], kViews[i][1]);
    const RenderResult a = cells->render(g, s);
    EXPECT_EQ(a.stats.cell_unpaired_parts, 1u);
    EXPECT_EQ(a.stats.merged_groups, 1u);
    EXPECT_EQ(a.stats.fragments_lost, 0u);
    const RenderResult b = ppll->render(g, s);
    EXPECT_EQ(a.stats.fragments, b.stats.fragments);
    EXPECT_EQ(compareImages(a.image, b.image).max_abs, 0);
    test::expectImagesMatch(a.image, embree->render(g, s).image,
                            "cells-unpaired-" + std::to_string(i), 0.99);
  }
}

// A multi-part glTF (many meshes and instances, interpenetrating parts, depth 34) and a glTF
// of one box with bad normals: the order between parts and inside them still holds.
TEST(Cells, GltfAssembliesRenderExactly) {
  const std::string dir = std::string(STRATA_ASSIMP_MODELS_DIR) + "/glTF2/";
  for (const char* file : {"2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
                           "BoxBadNormals-glTF-Binary/BoxBadNormals.glb"}) {
    const std::string path = dir + file;
    ASSERT_TRUE(std::filesystem::exists(path)) << path << ": assimp-testmodels not installed";
    const auto [scene, g] = test::sceneAndGeometry(path);
    auto cells = makeRenderer(Method::Cells);
    for (int i = 0; i < 8; i += 3) {
      const FrameSettings s = settingsFor(scene, 384, kViews[i][0], kViews[i][1]);
      const RenderResult a = cells->render(g, s);
      EXPECT_EQ(a.stats.fragments_lost, 0u);
      test::expectMatchesEmbree(a.image, g, s,
                                std::string("cells-gltf-") + std::to_string(i) + "-" +
                                    std::filesystem::path(file).stem().string());
    }
  }
}

// The paper's local decomposition test admits non-convex cells: it gives fewer cells and, with
// two layers per cell, visible errors that the strict test does not have.
TEST(Cells, PaperDecompositionIsReportedNotHidden) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto cells = makeRenderer(Method::Cells);
  FrameSettings s = settingsFor(scene, 256, 30, 20);
  const RenderResult ref = embree->render(g, s);
  const RenderResult strict = cells->render(g, s);
  s.decompose = "paper";
  const RenderResult paper = cells->render(g, s);
  EXPECT_LE(paper.stats.cells, strict.stats.cells);
  EXPECT_GE(compareImages(strict.image, ref.image).within_2,
            compareImages(paper.image, ref.image).within_2);
  s.decompose = "loose";
  EXPECT_THROW(cells->render(g, s), Error);
}

// The cache: a second render reads the cells instead of decomposing again.
TEST(Cells, PreprocessingIsCached) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("cow.obj"));
  FrameSettings s = settingsFor(scene, 128, 30, 20);
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache-fresh";
  std::filesystem::remove_all(s.cell_cache_dir);
  const RenderResult first = makeRenderer(Method::Cells)->render(g, s);
  EXPECT_FALSE(first.stats.preprocess_cached);
  const RenderResult second = makeRenderer(Method::Cells)->render(g, s);
  EXPECT_TRUE(second.stats.preprocess_cached);
  EXPECT_EQ(first.stats.cells, second.stats.cells);
  EXPECT_EQ(compareImages(first.image, second.image).max_abs, 0);
}

// The decomposition is keyed on a mesh's own space, not on where its instance stands: moving an
// object reads the cache it wrote (no new decomposition, no new file) and still renders exactly.
TEST(Cells, MovingAnObjectKeepsItsCachedCells) {
  Scene scene = loadScene(test::modelPath("cow.obj"));
  ASSERT_EQ(scene.instances.size(), 1u);
  FrameSettings s = settingsFor(scene, 96, 30, 20);
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache-moving";
  std::filesystem::remove_all(s.cell_cache_dir);
  const auto files = [&] {
    size_t n = 0;
    for (const auto& e : std::filesystem::directory_iterator(s.cell_cache_dir))
      n += e.is_regular_file();
    return n;
  };
  const std::unique_ptr<MethodRenderer> cells = makeRenderer(Method::Cells);
  EXPECT_FALSE(cells->render(WorldGeometry::fromScene(scene), s).stats.preprocess_cached);
  const size_t written = files();
  EXPECT_EQ(written, 1u);
  for (int step = 1; step <= 3; ++step) {
    scene.instances[0].transform =
        glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0.05f * step, 0.0f, -0.03f * step)),
                    0.2f * step, glm::vec3(0.0f, 1.0f, 0.0f));
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    const RenderResult moved = cells->render(g, s);
    EXPECT_TRUE(moved.stats.preprocess_cached) << "step " << step;
    EXPECT_EQ(files(), written) << "step " << step;
    test::expectImagesMatch(moved.image, makeRenderer(Method::Embree)->render(g, s).image,
                            "cells-moved-cow-" + std::to_string(step));
  }
}

}  // namespace
}  // namespace strata
