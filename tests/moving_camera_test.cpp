// A moving camera (FrameSettings::orbit_deg, `strata render --orbit`): cells stays exact against
// Embree over 16 consecutive orbit frames on real meshes, the demo and a glTF assembly; a render
// of N orbit frames ends on exactly the image of its last view rendered still, for every kind of
// per-view state (the cells order, the octree's leaf order, texturing records, Embree's camera);
// the statistics say that the view moved.
#include <filesystem>

#include "engine/reference/embree_reference.h"
#include "preprocess/mesh_loader.h"
#include "test_support.h"

namespace strata {
namespace {

std::string cacheDir() { return std::string(STRATA_TEST_OUTPUT_DIR) + "/moving-cache"; }

FrameSettings startView(const Scene& scene, int size) {
  FrameSettings s = test::settingsFor(scene, size, 20.0f, 25.0f);
  s.cell_cache_dir = cacheDir();
  return s;
}

class MovingCells : public test::SceneImageTest<test::SceneCase> {};

// Frame f of `--orbit 1` is the start view turned by f degrees: each is rendered by one cells
// renderer in turn (so it orders every view anew from its state of the last one) and compared
// with Embree.
TEST_P(MovingCells, SixteenOrbitFramesMatchEmbree) {
  const test::SceneCase& c = GetParam();
  auto cells = makeRenderer(Method::Cells);
  const FrameSettings start = startView(scene, 256);
  for (int f = 0; f < 16; ++f) {
    FrameSettings s = start;
    s.orbit_deg = 1.0f;
    s.camera = frameCamera(s, f);
    s.orbit_deg = 0.0f;
    const RenderResult a = cells->render(g, s);
    const RenderResult ref = embree->render(g, s);
    SCOPED_TRACE(c.label + " frame " + std::to_string(f));
    EXPECT_EQ(a.stats.triangles_read, a.stats.triangles);
    EXPECT_EQ(a.stats.fragments_lost, 0u);
    test::expectImagesMatch(a.image, ref.image, "moving-" + c.label + "-" + std::to_string(f));
  }
}

std::vector<test::SceneCase> movingCases() {
  std::vector<test::SceneCase> out = {{test::modelPath("horse.ply"), "horse"},
                                      {test::modelPath("stanford-bunny.obj"), "bunny"},
                                      {test::modelPath("teapot.obj"), "teapot"},
                                      {test::modelPath("spot.obj"), "spot"},
                                      {"builtin:demo", "demo"},
                                      {std::string(STRATA_ASSIMP_MODELS_DIR) +
                                           "/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
                                       "engine-glb"}};
  return out;
}

INSTANTIATE_TEST_SUITE_P(Scenes, MovingCells, ::testing::ValuesIn(movingCases()),
                         [](const auto& info) {
                           std::string n = info.param.label;
                           for (char& ch : n)
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           return n;
                         });

// A render of 4 frames turning 7 degrees each ends on the view turned 21 degrees: the same image
// as that view rendered still, by a fresh renderer.
void expectOrbitEndsOnItsLastView(Method method, const std::string& scene_name,
                                  Effect effect = Effect::Transparency) {
  const auto [scene, g] = test::sceneAndGeometry(scene_name);
  FrameSettings moving = startView(scene, 96);
  moving.effect = effect;
  moving.sigma = 1.0f / scene.boundingSphere().radius;
  moving.frames = 4;
  moving.orbit_deg = 7.0f;
  const RenderResult a = makeRenderer(method)->render(g, moving);
  FrameSettings still = moving;
  still.camera = frameCamera(moving, 3);
  still.orbit_deg = 0.0f;
  still.frames = 1;
  const RenderResult b = makeRenderer(method)->render(g, still);
  SCOPED_TRACE(methodName(method) + " on " + scene_name);
  EXPECT_EQ(a.stats.orbit_deg, 7.0f);
  EXPECT_EQ(b.stats.orbit_deg, 0.0f);
  EXPECT_EQ(a.stats.frame_ms.runs, 4);
  ASSERT_EQ(a.image.rgba.size(), b.image.rgba.size());
  EXPECT_TRUE(a.image.rgba == b.image.rgba) << "the last orbit frame differs from its still view";
  // ... and not the image of the first view (the camera did move).
  still.camera = moving.camera;
  const RenderResult first = makeRenderer(method)->render(g, still);
  EXPECT_FALSE(a.image.rgba == first.image.rgba);
}

TEST(MovingCamera, OrbitEndsOnItsLastView) {
  for (Method m : {Method::Opaque, Method::Ppll, Method::Cells, Method::Octree, Method::Embree})
    expectOrbitEndsOnItsLastView(m, "builtin:demo");
}

TEST(MovingCamera, TexturedOrbitEndsOnItsLastView) {
  // Texturing records are per view: a moving camera rebuilds them every frame.
  for (Method m : {Method::Ppll, Method::Cells, Method::Octree, Method::Embree})
    expectOrbitEndsOnItsLastView(m, "builtin:textured:4");
}

TEST(MovingCamera, TranslucentOrbitEndsOnItsLastView) {
  for (Method m : {Method::Cells, Method::Octree, Method::Embree})
    expectOrbitEndsOnItsLastView(m, test::modelPath("cow.obj"), Effect::Translucency);
}

TEST(MovingCamera, CellsOrdersEveryFrameOfAMovingCamera) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("teapot.obj"));
  FrameSettings s = startView(scene, 128);
  s.frames = 5;
  auto cells = makeRenderer(Method::Cells);
  const RenderResult still = cells->render(g, s);
  EXPECT_EQ(still.stats.order_cached_frames, 5u);  // ordered in the untimed warm-up
  s.orbit_deg = 2.0f;
  const RenderResult moving = cells->render(g, s);
  EXPECT_EQ(moving.stats.order_cached_frames, 0u);
  EXPECT_GT(moving.stats.order_ms, 0.0);
}

// The order's pixel masks and pairs found on the device (cells_order_masks.cl,
// cells_order_pairs.cl) give the same frames as the host's, through the renderer and its order
// made ahead on a host thread (which then uses the device's queue of its own); the statistics
// say where the masks were made.
TEST(MovingCamera, CellsOrderMasksOnTheDeviceRenderTheSameFrames) {
  for (const std::string& name : {test::modelPath("horse.ply"), test::modelPath("spot.obj")}) {
    SCOPED_TRACE(name);
    const auto [scene, g] = test::sceneAndGeometry(name);
    FrameSettings s = startView(scene, 160);
    s.frames = 4;
    s.orbit_deg = 5.0f;
    RenderResult r[2];
    for (int i = 0; i < 2; ++i) {
      s.cells.order_masks = i == 0 ? "host" : "device";
      r[i] = makeRenderer(Method::Cells)->render(g, s);
    }
    EXPECT_EQ(r[0].stats.order_masks, "host");
    EXPECT_EQ(r[1].stats.order_masks, "device");
    EXPECT_EQ(r[0].stats.order_device_cells, 0u);
    EXPECT_GT(r[1].stats.order_device_cells, 0u);
    EXPECT_EQ(r[0].stats.cell_groups, r[1].stats.cell_groups);
    EXPECT_EQ(r[0].stats.cell_passes, r[1].stats.cell_passes);
    EXPECT_EQ(r[0].stats.fragments, r[1].stats.fragments);
    EXPECT_TRUE(r[0].image.rgba == r[1].image.rgba);
  }
  const Scene scene = loadScene("builtin:demo");
  FrameSettings s = startView(scene, 64);
  s.cells.order_masks = "gpu";
  EXPECT_THROW(makeRenderer(Method::Cells)->render(WorldGeometry::fromScene(scene), s), Error);
}

// Ordering each next view on a host thread while the device draws the current one changes
// nothing in the images: the same frames with and without it end on the same image (the last
// view's, rendered still), with the same fragments, and the statistics say which frames used an
// order made ahead.
TEST(MovingCamera, CellsOrderAheadRendersTheSameFrames) {
  for (const std::string& name : {test::modelPath("teapot.obj"), std::string("builtin:demo")}) {
    SCOPED_TRACE(name);
    const auto [scene, g] = test::sceneAndGeometry(name);
    FrameSettings s = startView(scene, 128);
    s.frames = 5;
    s.orbit_deg = 3.0f;
    s.cells.order_reuse = 0;  // every frame orders its own view
    RenderResult r[2];
    for (int i = 0; i < 2; ++i) {
      s.cells.order_ahead = i == 1;
      r[i] = makeRenderer(Method::Cells)->render(g, s);
      EXPECT_EQ(r[i].stats.order_cached_frames, 0u);
      EXPECT_GT(r[i].stats.order_ms, 0.0);
    }
    EXPECT_EQ(r[0].stats.order_overlapped_frames, 0u);
    EXPECT_EQ(r[1].stats.order_overlapped_frames, 5u);
    EXPECT_EQ(r[0].stats.fragments, r[1].stats.fragments);
    EXPECT_TRUE(r[0].image.rgba == r[1].image.rgba);
    FrameSettings still = s;
    still.camera = frameCamera(s, 4);
    still.orbit_deg = 0.0f;
    still.frames = 1;
    EXPECT_TRUE(makeRenderer(Method::Cells)->render(g, still).image.rgba == r[1].image.rgba);
    // One renderer, moving then still: the still view is its own, not an order left over from
    // the moving frames.
    auto cells = makeRenderer(Method::Cells);
    cells->render(g, s);
    const RenderResult again_still = cells->render(g, still);
    EXPECT_TRUE(again_still.image.rgba == r[1].image.rgba);
  }
}

// A moving camera's frame drawn with the order of an earlier view (CellsOptions::order_reuse)
// is checked as it is composited and repaired where that order fails: the last frame of a
// render whose every timed frame reused the warm-up's order, `frames` views on, matches Embree
// and is the image its own view gives still, whatever the age of the order; a large turn makes
// the check fail somewhere, so the repair is what keeps it exact.
TEST(MovingCamera, CellsFramesDrawnWithAnEarlierViewsOrderStayExact) {
  for (const std::string& name :
       {test::modelPath("horse.ply"), test::modelPath("teapot.obj"), std::string("builtin:demo")}) {
    const auto [scene, g] = test::sceneAndGeometry(name);
    auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
    // The serial composite; the group one walking passes, or the earlier view's tile segments.
    for (const std::string composite : {"serial", "group", "group+segments"}) {
      uint64_t repaired = 0;
      for (int frames : {1, 3, 6}) {
        FrameSettings s = startView(scene, 160);
        s.frames = frames;
        s.orbit_deg = 6.0f;
        s.cells.order_reuse = 100;
        s.cells.composite = composite == "serial" ? "serial" : "group";
        s.cells.tile_segments = composite == "group+segments" ? "on" : "auto";
        const RenderResult moving = makeRenderer(Method::Cells)->render(g, s);
        SCOPED_TRACE(name + ", " + std::to_string(frames) + " frames, " + composite);
        EXPECT_EQ(moving.stats.order_reused_frames, uint64_t(frames));
        EXPECT_EQ(moving.stats.fragments_lost, 0u);
        repaired += uint64_t(moving.stats.order_repair_tiles);
        EXPECT_GE(moving.stats.order_repair_pixels, moving.stats.order_repair_tiles);
        FrameSettings still = s;
        still.camera = frameCamera(s, frames - 1);
        still.orbit_deg = 0.0f;
        still.frames = 1;
        const RenderResult own = makeRenderer(Method::Cells)->render(g, still);
        EXPECT_EQ(own.stats.order_reused_frames, 0u);
        EXPECT_EQ(moving.stats.fragments, own.stats.fragments);
        test::expectImagesMatch(moving.image, embree->render(g, still).image,
                                "reused-order-" + std::filesystem::path(name).stem().string() +
                                    "-" + std::to_string(frames) + "-" + composite);
        if (name != "builtin:demo") {  // a clean mesh: no two fragments of a pixel at one depth
          EXPECT_TRUE(moving.image.rgba == own.image.rgba);
        }
      }
      if (name == test::modelPath("horse.ply")) {
        EXPECT_GT(repaired, 0u) << composite;  // the legs cross
      }
    }
  }
}

// Reuse needs strict cells and a frame of one batch: otherwise every frame orders its own view.
TEST(MovingCamera, CellsOrderReuseOnlyWhereItCanBeChecked) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("teapot.obj"));
  FrameSettings s = startView(scene, 96);
  s.frames = 3;
  s.orbit_deg = 2.0f;
  EXPECT_EQ(makeRenderer(Method::Cells)->render(g, s).stats.order_reused_frames, 3u);
  FrameSettings group = s;
  group.cells.composite = "group";
  EXPECT_EQ(makeRenderer(Method::Cells)->render(g, group).stats.order_reused_frames, 3u);
  FrameSettings paper = s;
  paper.decompose = "paper";
  EXPECT_EQ(makeRenderer(Method::Cells)->render(g, paper).stats.order_reused_frames, 0u);
  FrameSettings batches = s;
  batches.cells.batch_triangles = 1000;
  EXPECT_EQ(makeRenderer(Method::Cells)->render(g, batches).stats.order_reused_frames, 0u);
  FrameSettings off = s;
  off.cells.order_reuse = 0;
  EXPECT_EQ(makeRenderer(Method::Cells)->render(g, off).stats.order_reused_frames, 0u);
}

// The group composite's tile segments: by default the order skips them for a moving camera
// (each frame a new view) and lists them for a still one; either way the frames are the same.
TEST(MovingCamera, CellsTileSegmentsOnlyForAStillCameraByDefault) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("teapot.obj"));
  FrameSettings s = startView(scene, 128);
  s.cells.composite = "group";
  s.frames = 3;
  s.orbit_deg = 4.0f;
  auto cells = makeRenderer(Method::Cells);
  const RenderResult moving_auto = cells->render(g, s);
  EXPECT_EQ(moving_auto.stats.cell_tile_segments, 0u);
  s.cells.tile_segments = "on";
  const RenderResult moving_on = cells->render(g, s);
  EXPECT_GT(moving_on.stats.cell_tile_segments, 0u);
  EXPECT_EQ(moving_on.stats.fragments, moving_auto.stats.fragments);
  EXPECT_TRUE(moving_on.image.rgba == moving_auto.image.rgba);
  s.cells.tile_segments = "auto";
  s.orbit_deg = 0.0f;
  s.frames = 1;
  EXPECT_GT(cells->render(g, s).stats.cell_tile_segments, 0u);
  s.cells.tile_segments = "sometimes";
  EXPECT_THROW(cells->render(g, s), Error);
}

TEST(MovingCamera, OrbitOutOfRangeIsRefused) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:demo");
  FrameSettings s = startView(scene, 32);
  for (float bad : {400.0f, -361.0f, std::nanf("")}) {
    s.orbit_deg = bad;
    EXPECT_THROW(makeRenderer(Method::Ppll)->render(g, s), Error);
  }
}

TEST(MovingCamera, TurningKeepsDistanceAndElevation) {
  const Camera c = Camera::lookAt({1.0f, 2.0f, 3.0f}, {0.5f, 0.0f, -1.0f});
  const Camera t = c.turned(90.0f);
  EXPECT_NEAR(glm::length(t.eye - t.target), glm::length(c.eye - c.target), 1e-5f);
  EXPECT_NEAR(t.eye.y, c.eye.y, 1e-6f);
  // A quarter turn about +Y: the offset (0.5, 2, 4) goes to (4, 2, -0.5).
  EXPECT_NEAR(t.eye.x, 0.5f + 4.0f, 1e-5f);
  EXPECT_NEAR(t.eye.z, -1.0f - 0.5f, 1e-5f);
  const Camera back = t.turned(-90.0f);
  EXPECT_NEAR(glm::length(back.eye - c.eye), 0.0f, 1e-5f);
}

}  // namespace
}  // namespace strata
