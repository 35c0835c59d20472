// The per-view order of convex cells (engine/cells/cell_order.cpp) on tiny hand-made scenes whose
// answer is known: a separable pair drawn nearest first, cells disjoint on screen sharing a
// pass, nested cells and a cyclic overlap of three sticks drawn as one group, passes joined in
// a tile's segment. Each scene is also rendered with cells against the Embree reference. On
// real meshes, a brute-force check of the segments centre by centre.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <tuple>

#include <glm/gtc/matrix_transform.hpp>

#include "engine/cells/cell_masks_device.h"
#include "engine/cells/cell_order.h"
#include "engine/reference/embree_reference.h"
#include "test_support.h"

namespace strata {
namespace {

// One unit box mesh, placed by each instance's transform (an affine image of a box is convex:
// one cell per instance).
Scene boxes(const std::vector<glm::mat4>& transforms) {
  Scene s;
  s.source = "test:cell-order";
  s.meshes.push_back(makeBox(glm::vec3(0.5f)));
  Material m;
  m.color = glm::vec4(0.3f, 0.6f, 0.9f, 1.0f);
  m.opacity = 0.5f;
  s.materials.push_back(m);
  for (size_t i = 0; i < transforms.size(); ++i)
    s.instances.push_back({0, transforms[i], uint32_t(i), "box" + std::to_string(i)});
  return s;
}

glm::mat4 box(glm::vec3 centre, glm::vec3 size) {
  return glm::scale(glm::translate(glm::mat4(1.0f), centre), size);
}

struct Ordered {
  CellScene cells;
  CellOrder order;
  FrameSettings settings;
};

// The order seen from +Z looking at the origin, and the cells image against Embree.
Ordered orderFromFront(const Scene& scene, const std::string& name) {
  Ordered o;
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  o.settings.width = o.settings.height = 128;
  o.settings.camera = Camera::lookAt({0.0f, 0.0f, 12.0f}, {0.0f, 0.0f, 0.0f});
  o.settings.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache";
  o.cells = CellScene::build(g, DecomposeOptions{}, o.settings.cell_cache_dir);
  o.order = orderCells(o.cells, o.settings.camera, o.settings.width, o.settings.height);
  test::expectImagesMatch(makeRenderer(Method::Cells)->render(g, o.settings).image,
                          makeRenderer(Method::Embree)->render(g, o.settings).image,
                          "cell-order-" + name);
  return o;
}

// The group holding cell c.
uint32_t groupOf(const CellOrder& order, uint32_t c) {
  for (uint32_t g = 0; g < order.groupCount(); ++g)
    for (uint32_t k = order.group_first[g]; k < order.group_first[g + 1]; ++k)
      if (order.cells[k] == c) return g;
  ADD_FAILURE() << "cell " << c << " is not ordered";
  return UINT32_MAX;
}

TEST(CellOrder, SeparablePairIsDrawnNearestFirst) {
  // Box 0 behind box 1, overlapping on screen.
  const Ordered o =
      orderFromFront(boxes({box({0, 0, -2}, {2, 2, 1}), box({0.3f, 0.2f, 2}, {2, 2, 1})}), "pair");
  ASSERT_EQ(o.cells.cellCount(), 2u);
  ASSERT_EQ(o.order.groupCount(), 2u);
  EXPECT_LT(groupOf(o.order, 1), groupOf(o.order, 0));
  // Overlapping on screen: the later group is in a later pass.
  EXPECT_LT(o.order.group_pass[groupOf(o.order, 1)], o.order.group_pass[groupOf(o.order, 0)]);
  EXPECT_EQ(o.order.largest_group, 1u);
  EXPECT_EQ(o.order.merged_groups, 0u);
}

TEST(CellOrder, CellsDisjointOnScreenShareAPass) {
  const Ordered o =
      orderFromFront(boxes({box({-3, 0, -2}, {1, 1, 1}), box({3, 0, 2}, {1, 1, 1})}), "disjoint");
  ASSERT_EQ(o.order.groupCount(), 2u);
  EXPECT_EQ(o.order.passes, 1u);
  EXPECT_EQ(o.order.group_pass[0], o.order.group_pass[1]);
}

TEST(CellOrder, NestedCellsAreOneGroup) {
  // A small box inside a large one: no plane separates them, so neither can be drawn whole
  // before the other.
  const Ordered o =
      orderFromFront(boxes({box({0, 0, 0}, {4, 4, 4}), box({0.2f, 0.1f, 0}, {1, 1, 1})}), "nested");
  ASSERT_EQ(o.cells.cellCount(), 2u);
  EXPECT_EQ(o.order.groupCount(), 1u);
  EXPECT_EQ(o.order.largest_group, 2u);
  EXPECT_EQ(o.order.merged_groups, 1u);
  EXPECT_EQ(o.order.merged_cells, 2u);
}

TEST(CellOrder, ThreeStickCycleIsOneGroup) {
  // Three sticks round a triangle, each rising along its length: at every corner the arriving
  // stick lies over the leaving one, so each is in front of the next: a cycle.
  std::vector<glm::mat4> sticks;
  const float r = 2.0f;
  for (int i = 0; i < 3; ++i) {
    const float a0 = glm::radians(90.0f + 120.0f * i), a1 = glm::radians(90.0f + 120.0f * (i + 1));
    const glm::vec3 c0(r * std::cos(a0), r * std::sin(a0), -0.6f),
        c1(r * std::cos(a1), r * std::sin(a1), 0.6f);
    const glm::vec3 axis = (c1 - c0) * 1.3f;  // past both corners
    const glm::vec3 width = 0.5f * glm::normalize(glm::vec3(-axis.y, axis.x, 0.0f));
    const glm::vec3 thick(0.0f, 0.0f, 0.3f);
    glm::mat4 m(1.0f);
    m[0] = glm::vec4(axis, 0.0f);
    m[1] = glm::vec4(width, 0.0f);
    m[2] = glm::vec4(thick, 0.0f);
    m[3] = glm::vec4(0.5f * (c0 + c1), 1.0f);
    sticks.push_back(m);
  }
  const Ordered o = orderFromFront(boxes(sticks), "three-sticks");
  ASSERT_EQ(o.cells.cellCount(), 3u);
  EXPECT_EQ(o.order.groupCount(), 1u);
  EXPECT_EQ(o.order.largest_group, 3u);
  EXPECT_GE(o.order.merged_pairs, 1u);
}

TEST(CellOrder, TheOrderFollowsTheEye) {
  // The same pair seen from the other side is drawn the other way round.
  const Scene scene = boxes({box({0, 0, -2}, {2, 2, 1}), box({0.3f, 0.2f, 2}, {2, 2, 1})});
  const CellScene cells =
      CellScene::build(WorldGeometry::fromScene(scene), DecomposeOptions{},
                       std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache");
  const CellOrder front = orderCells(cells, Camera::lookAt({0, 0, 12}, {0, 0, 0}), 128, 128);
  const CellOrder back = orderCells(cells, Camera::lookAt({0, 0, -12}, {0, 0, 0}), 128, 128);
  ASSERT_EQ(front.groupCount(), 2u);
  ASSERT_EQ(back.groupCount(), 2u);
  EXPECT_LT(groupOf(front, 1), groupOf(front, 0));
  EXPECT_LT(groupOf(back, 0), groupOf(back, 1));
}

TEST(CellOrder, AViewCrossingASeparatingPlaneBetweenFramesFlipsTheOrder) {
  // Two plates of one mesh, parallel to the plane x + z = 0 on either side of it, their boxes
  // overlapping (so only the pair's separating plane can order them). A camera turning round
  // them in quarter turns crosses that plane between the second and third frame: the plate on
  // the eye's side is drawn first in every frame, and every frame matches Embree.
  Scene scene;
  scene.source = "test:crossing-plates";
  Mesh plates;
  const glm::vec3 normal = glm::normalize(glm::vec3(1.0f, 0.0f, 1.0f));
  const glm::mat4 tilt = glm::rotate(glm::mat4(1.0f), glm::radians(45.0f), glm::vec3(0, 1, 0));
  for (float side : {-1.0f, 1.0f}) {
    const Mesh box = makeBox(glm::vec3(1.0f, 1.0f, 0.05f));
    const uint32_t base = uint32_t(plates.positions.size());
    const glm::mat4 place = glm::translate(glm::mat4(1.0f), side * 0.3f * normal) * tilt;
    for (const glm::vec3& p : box.positions)
      plates.positions.push_back(glm::vec3(place * glm::vec4(p, 1.0f)));
    for (uint32_t i : box.indices) plates.indices.push_back(base + i);
  }
  scene.meshes.push_back(plates);
  Material m;
  m.color = glm::vec4(0.8f, 0.4f, 0.2f, 1.0f);
  m.opacity = 0.5f;
  scene.materials.push_back(m);
  scene.instances.push_back({0, glm::mat4(1.0f), 0, "plates"});
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s;
  s.width = s.height = 128;
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache";
  s.camera = Camera::lookAt({0.0f, 1.0f, 8.0f}, {0.0f, 0.0f, 0.0f});
  s.orbit_deg = 90.0f;
  const CellScene cells = CellScene::build(g, DecomposeOptions{}, s.cell_cache_dir);
  ASSERT_EQ(cells.cellCount(), 2u);
  ASSERT_EQ(cells.separable_pairs, 1u);
  // Cell 0 is the plate on the negative side of x + z = 0.
  auto cellCentre = [&](uint32_t c) {
    glm::vec3 sum(0.0f);
    for (uint32_t k = cells.cell_vertex_first[c]; k < cells.cell_vertex_first[c + 1]; ++k)
      sum += cells.vertices[cells.cell_vertex_index[k]];
    return sum / float(cells.cell_vertex_first[c + 1] - cells.cell_vertex_first[c]);
  };
  const uint32_t negative = glm::dot(cellCentre(0), normal) < 0.0f ? 0u : 1u;
  auto cells_renderer = makeRenderer(Method::Cells);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (int f = 0; f < 4; ++f) {
    FrameSettings frame = s;
    frame.camera = frameCamera(s, f);
    frame.orbit_deg = 0.0f;
    const bool eye_positive = glm::dot(frame.camera.eye, normal) > 0.0f;
    EXPECT_EQ(eye_positive, f < 2) << "frame " << f;
    const CellOrder order = orderCells(cells, frame.camera, 128, 128);
    ASSERT_EQ(order.groupCount(), 2u) << "frame " << f;
    const uint32_t near = eye_positive ? 1u - negative : negative;
    EXPECT_LT(groupOf(order, near), groupOf(order, 1u - near)) << "frame " << f;
    EXPECT_EQ(order.passes, 2u) << "frame " << f << ": the plates overlap on screen";
    test::expectImagesMatch(cells_renderer->render(g, frame).image, embree->render(g, frame).image,
                            "cell-order-crossing-" + std::to_string(f));
  }
}

// One mesh of unit boxes placed by the transforms (one part, so its cells are ordered
// against each other pixel by pixel).
Scene boxesInOneMesh(const std::vector<glm::mat4>& transforms) {
  Scene s = boxes({glm::mat4(1.0f)});
  Mesh merged;
  for (const glm::mat4& t : transforms) {
    const uint32_t base = uint32_t(merged.positions.size());
    for (const glm::vec3& p : s.meshes[0].positions)
      merged.positions.push_back(glm::vec3(t * glm::vec4(p, 1.0f)));
    for (uint32_t i : s.meshes[0].indices) merged.indices.push_back(base + i);
  }
  s.meshes[0] = merged;
  return s;
}

TEST(CellOrder, PassesSharingNoPixelInATileShareItsSegment) {
  // Boxes 0 and 1 side by side with a gap of a few pixels inside a column of tiles, which holds
  // pixels of both; box 2 in front of box 0 only. Box 0 comes a pass after box 2 and box 1 has the
  // first pass: along the gap the two passes share no pixel centre and one segment takes both.
  const Ordered o = orderFromFront(
      boxesInOneMesh({box({-0.85f, 0, 0}, {1.9f, 2, 0.5f}), box({1.35f, 0, 0}, {1.9f, 2, 0.5f}),
                      box({-1.5f, 1.0f, 3}, {1, 1, 0.5f})}),
      "segments");
  ASSERT_EQ(o.cells.cellCount(), 3u);
  ASSERT_EQ(o.order.passes, 2u);
  EXPECT_EQ(o.order.group_pass[groupOf(o.order, 2)], 0u);
  EXPECT_EQ(o.order.group_pass[groupOf(o.order, 0)], 1u);
  EXPECT_EQ(o.order.group_pass[groupOf(o.order, 1)], 0u);
  ASSERT_EQ(o.order.tile_break_first.size(), 16u * 16u + 1u);
  EXPECT_LT(o.order.tile_breaks.size(), o.order.tile_passes);
  // Where box 2 covers box 0 the passes stay apart: some tile has two segments.
  bool split = false;
  for (size_t t = 0; t + 1 < o.order.tile_break_first.size(); ++t)
    split = split || o.order.tile_break_first[t + 1] - o.order.tile_break_first[t] == 2;
  EXPECT_TRUE(split);
}

// Without the tile segments (what the serial composite draws) the order is the same: the same
// cells, groups and passes, only no segments.
TEST(CellOrder, OrderWithoutSegmentsIsTheSameOrder) {
  for (const char* model : {"horse.ply", "teapot.obj"}) {
    const Scene scene = loadScene(test::modelPath(model));
    const CellScene cells =
        CellScene::build(WorldGeometry::fromScene(scene), DecomposeOptions{},
                         std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache");
    const FrameSettings fs = test::settingsFor(scene, 384, 30.0f, 20.0f);
    const CellOrder with = orderCells(cells, fs.camera, fs.width, fs.height);
    const CellOrder without = orderCells(cells, fs.camera, fs.width, fs.height, false);
    SCOPED_TRACE(model);
    EXPECT_FALSE(with.tile_breaks.empty());
    EXPECT_EQ(without.cells, with.cells);
    EXPECT_EQ(without.group_first, with.group_first);
    EXPECT_EQ(without.group_pass, with.group_pass);
    EXPECT_EQ(without.passes, with.passes);
    EXPECT_TRUE(without.tile_break_first.empty());
    EXPECT_TRUE(without.tile_breaks.empty());
    EXPECT_EQ(without.tile_passes, 0u);
  }
}

// The pixel masks computed by the device's kernel (cells_order_masks.cl) are the host's bit for
// bit, and the pairs it finds with them (cells_order_pairs.cl) are the host's with the same
// relations, so the order is the same: the same cells, groups, passes and tile segments, on meshes
// of many small cells (nearly all of them sent to the device), of a few large ones (kept on the
// host) and a scene of several parts, at image sizes that are not whole tiles, from views near
// and far.
TEST(CellOrder, DeviceMasksAndPairsGiveTheHostOrder) {
  const std::shared_ptr<ClRuntime> runtime = ClRuntime::acquire("");
  for (const std::string& model : {test::modelPath("horse.ply"), test::modelPath("teapot.obj"),
                                   test::modelPath("spot.obj"), std::string("builtin:demo")}) {
    const Scene scene = loadScene(model);
    const CellScene cells =
        CellScene::build(WorldGeometry::fromScene(scene), DecomposeOptions{},
                         std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache");
    ClCellMasks masks(*runtime, cells);
    uint32_t device_cells = 0;
    uint64_t device_pairs = 0;
    for (const auto& [w, h, az, distance] :
         {std::tuple<int, int, float, float>{301, 187, 30.0f, 0.0f},
          {640, 480, 130.0f, 0.0f},
          {250, 250, 200.0f, 0.8f}}) {  // distance in radii; 0: framed
      SCOPED_TRACE(model + " " + std::to_string(w) + "x" + std::to_string(h));
      OrbitView v = scene.default_view.value_or(OrbitView{});
      v.azimuth_deg = az;
      v.elevation_deg = 20.0f;
      if (distance > 0.0f) v.distance_radii = distance;
      const Camera camera = Camera::orbit(scene.boundingSphere(), v);
      const CellOrder host = orderCells(cells, camera, w, h);
      const CellOrder device = orderCells(cells, camera, w, h, true, &masks);
      device_cells += device.device_mask_cells;
      device_pairs += device.device_pairs;
      // Near the horse, cells of both kinds in one group: the merge interleaves the device's
      // masks with the host's (lists of several threads).
      if (model.find("horse") != std::string::npos && distance > 0.0f) {
        EXPECT_GT(device.device_mask_cells, cells.cellCount() / 4);
        EXPECT_LT(device.device_mask_cells, cells.cellCount());
      }
      EXPECT_EQ(device.cells, host.cells);
      EXPECT_EQ(device.group_first, host.group_first);
      EXPECT_EQ(device.group_pass, host.group_pass);
      EXPECT_EQ(device.tile_break_first, host.tile_break_first);
      EXPECT_EQ(device.tile_breaks, host.tile_breaks);
      EXPECT_EQ(device.pairs_tested, host.pairs_tested);
    }
    if (model.find("horse") != std::string::npos) {
      EXPECT_GT(device_cells, 2 * cells.cellCount());  // most cells of three views
    }
    // The demo's parts are each too few cells for a device call; the meshes are one part.
    if (model.rfind("builtin:", 0) != 0) {
      EXPECT_GT(device_pairs, 0u);
    }
  }
}

TEST(CellOrder, LargeConvexPartsMakeEveryPassASegment) {
  // Nested spheres, each one convex cell of its own part: their pixels are not rasterized by
  // the ordering, so their coverage is whole tiles, and past a few screens of those (here a
  // narrow view that every sphere fills) the segments are dropped: every pass is a segment of its
  // own (the images are tested against Embree with and without segments elsewhere).
  const Scene scene = loadScene("builtin:spheres:32");
  FrameSettings fs;
  fs.width = fs.height = 1024;
  fs.camera = Camera::orbit(scene.boundingSphere(), scene.default_view.value_or(OrbitView{}),
                            Projection::Perspective, 15.0f);
  const CellScene cells =
      CellScene::build(WorldGeometry::fromScene(scene), DecomposeOptions{},
                       std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache");
  const CellOrder order = orderCells(cells, fs.camera, fs.width, fs.height);
  EXPECT_GE(order.passes, 8u);
  EXPECT_TRUE(order.tile_break_first.empty());
  EXPECT_TRUE(order.tile_breaks.empty());
  EXPECT_EQ(order.tile_passes, 0u);
}

// Every pixel centre that two groups certainly cover (inside each by more than any rounding of
// the host's or the device's) lies in a tile whose segments put the two groups apart: a
// brute-force test of the segments on a real mesh, centre by centre.
TEST(CellOrder, SegmentsNeverJoinGroupsSharingAPixelCentre) {
  // Meshes of many small cells, and nested spheres (whole tiles per sphere, no pass joined).
  for (const std::string& model : {test::modelPath("horse.ply"), test::modelPath("teapot.obj"),
                                   std::string("builtin:spheres:16")}) {
    const bool meshes = model.rfind("builtin:", 0) != 0;
    const Scene scene = loadScene(model);
    const FrameSettings fs = test::settingsFor(scene, 256, 30.0f, 20.0f);
    const int w = fs.width, h = fs.height, tiles_x = (w + 7) / 8;
    const CellScene cells =
        CellScene::build(WorldGeometry::fromScene(scene), DecomposeOptions{},
                         std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache");
    const CellOrder order = orderCells(cells, fs.camera, w, h);
    ASSERT_EQ(order.tile_break_first.size(), size_t(tiles_x) * ((h + 7) / 8) + 1);
    for (size_t t = 0; t + 1 < order.tile_break_first.size(); ++t)
      for (uint32_t k = order.tile_break_first[t] + 1; k < order.tile_break_first[t + 1]; ++k)
        ASSERT_LT(order.tile_breaks[k - 1], order.tile_breaks[k]) << model << " tile " << t;
    const glm::mat4 vp = fs.camera.projectionMatrix(float(w) / float(h)) * fs.camera.viewMatrix();
    std::vector<std::vector<uint32_t>> groups_at(size_t(w) * h);
    for (uint32_t g = 0; g < order.groupCount(); ++g) {
      for (uint32_t k = order.group_first[g]; k < order.group_first[g + 1]; ++k) {
        const uint32_t c = order.cells[k];
        const uint32_t v0 = cells.cell_vertex_first[c];
        for (uint32_t t = cells.cell_first[c]; t < cells.cell_first[c + 1]; ++t) {
          glm::vec2 p[3];
          bool in_front = true;
          for (int i = 0; i < 3; ++i) {
            const uint32_t corner = cells.cell_corners[size_t(t) * 3 + i];
            const glm::vec4 q =
                vp * glm::vec4(cells.vertices[cells.cell_vertex_index[v0 + corner]], 1);
            in_front = in_front && q.w > fs.camera.near_distance;
            p[i] = glm::vec2((q.x / q.w * 0.5f + 0.5f) * w, (0.5f - q.y / q.w * 0.5f) * h);
          }
          const float area =
              (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[2].x - p[0].x) * (p[1].y - p[0].y);
          if (!in_front || std::fabs(area) < 1e-3f) continue;
          const int x0 = std::max(0, int(std::floor(std::min({p[0].x, p[1].x, p[2].x}))));
          const int x1 = std::min(w - 1, int(std::ceil(std::max({p[0].x, p[1].x, p[2].x}))));
          const int y0 = std::max(0, int(std::floor(std::min({p[0].y, p[1].y, p[2].y}))));
          const int y1 = std::min(h - 1, int(std::ceil(std::max({p[0].y, p[1].y, p[2].y}))));
          for (int y = y0; y <= y1; ++y)
            for (int x = x0; x <= x1; ++x) {
              const glm::vec2 c(x + 0.5f, y + 0.5f);
              bool inside = true;
              for (int i = 0; i < 3 && inside; ++i) {
                const glm::vec2 a = p[i], b = p[(i + 1) % 3];
                const float cross = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
                inside = (area > 0 ? cross : -cross) > 0.01f * glm::length(b - a);
              }
              auto& at = groups_at[size_t(y) * w + x];
              if (inside && (at.empty() || at.back() != g)) at.push_back(g);
            }
        }
      }
    }
    size_t shared = 0;
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const auto& at = groups_at[size_t(y) * w + x];
        const size_t t = size_t(y / 8) * tiles_x + x / 8;
        const auto first = order.tile_breaks.begin() + order.tile_break_first[t];
        const auto last = order.tile_breaks.begin() + order.tile_break_first[t + 1];
        for (size_t i = 1; i < at.size(); ++i) {
          // Groups come in drawing order, so passes ascend: a break must lie in (p, q].
          const uint32_t p = order.group_pass[at[i - 1]], q = order.group_pass[at[i]];
          ASSERT_LT(p, q) << model << ": two groups of one pass share pixel " << x << "," << y;
          const auto b = std::upper_bound(first, last, p);
          ASSERT_TRUE(b != last && *b <= q)
              << model << ": passes " << p << " and " << q << " share pixel " << x << "," << y
              << " in one segment";
          ++shared;
        }
      }
    EXPECT_GT(shared, 1000u) << model << ": the test should see overlapping groups";
    if (meshes) {
      EXPECT_LT(order.tile_breaks.size(), order.tile_passes) << model;
    }
  }
}

// Thousands of small boxes crowding a small image: their screen rectangles overlap dozens of
// others each, so the instance level is skipped and they are ordered cell by cell, where only
// cells sharing a pixel centre are paired (not the square of the instances per pixel). The
// image matches ppll's and the reference; a few dozen boxes keep the instance level.
TEST(CellOrder, CrowdedInstancesAreOrderedCellByCell) {
  std::vector<glm::mat4> many;
  test::SignedUniform next(7);
  for (int i = 0; i < 3000; ++i)
    many.push_back(box({next() * 3.0f, next() * 3.0f, next() * 3.0f}, glm::vec3(0.3f)));
  const Scene scene = boxes(many);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s;
  s.width = s.height = 96;
  s.camera = Camera::lookAt({1.0f, 2.0f, 12.0f}, {0.0f, 0.0f, 0.0f});
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-order-cache";
  const CellScene cells = CellScene::build(g, DecomposeOptions{}, s.cell_cache_dir);
  const CellOrder order = orderCells(cells, s.camera, s.width, s.height);
  EXPECT_TRUE(order.crowded);
  EXPECT_LT(order.pairs_tested, 20u * many.size());
  const RenderResult a = makeRenderer(Method::Cells)->render(g, s);
  const RenderResult b = makeRenderer(Method::Ppll)->render(g, s);
  EXPECT_EQ(a.stats.fragments_lost, 0u);
  EXPECT_EQ(a.stats.fragments, b.stats.fragments);
  test::expectImagesMatch(a.image, b.image, "cell-order-crowded-ppll");
  test::expectImagesMatch(a.image, makeRenderer(Method::Embree)->render(g, s).image,
                          "cell-order-crowded");

  std::vector<glm::mat4> few(many.begin(), many.begin() + 40);
  const Scene sparse = boxes(few);
  const CellScene few_cells =
      CellScene::build(WorldGeometry::fromScene(sparse), DecomposeOptions{}, s.cell_cache_dir);
  EXPECT_FALSE(orderCells(few_cells, s.camera, s.width, s.height).crowded);
}

}  // namespace
}  // namespace strata
