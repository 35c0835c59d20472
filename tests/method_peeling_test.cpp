// Depth peeling (dp) and dual depth peeling (ddp): exact against the Embree reference, the number
// of geometry passes each runs, ties at equal depth peeled in triangle-id order, and termination
// on an empty view.
#include <array>
#include <cmath>

#include "engine/reference/embree_reference.h"
#include "test_support.h"

namespace strata {
namespace {

// The pass counts the two methods implement: dp peels one layer per pass and stops after the
// first pass that peels nothing; ddp peels the nearest and the farthest layer per pass.
uint64_t expectedPasses(Method m, uint64_t max_depth) {
  return m == Method::Dp ? max_depth + 1 : (max_depth + 1) / 2 + 1;
}

std::string label(Method m) { return methodName(m); }

// Checks one rendering against Embree and against ppll's fragment counts (same rasterizer, so
// the counts agree exactly), and the pass bookkeeping.
void checkFrame(Method m, const RenderResult& r, const RenderResult& reference,
                const RenderResult& ppll, uint64_t triangles, const std::string& name) {
  EXPECT_EQ(r.stats.fragments, ppll.stats.fragments) << name;
  EXPECT_EQ(r.stats.max_depth_complexity, ppll.stats.max_depth_complexity) << name;
  EXPECT_EQ(r.stats.geometry_passes, expectedPasses(m, r.stats.max_depth_complexity)) << name;
  EXPECT_EQ(r.stats.triangles_read, r.stats.geometry_passes * triangles) << name;
  EXPECT_EQ(r.stats.fragments_lost, 0u) << name;
  // Per-pixel state only: it does not depend on the depth complexity.
  const uint64_t pixels = uint64_t(r.image.width) * r.image.height;
  EXPECT_EQ(r.stats.fragment_bytes, pixels * (m == Method::Dp ? 24u : 48u)) << name;
  test::expectImagesMatch(r.image, reference.image, name);
}

struct Case {
  std::string scene;
  std::string label;
  std::vector<std::array<float, 2>> views;
};

std::vector<Case> cases() {
  const std::vector<std::array<float, 2>> views = {{30, 20}, {150, -30}, {260, 55}};
  return {{test::modelPath("teapot.obj"), "teapot", views},
          {test::modelPath("stanford-bunny.obj"), "bunny", views},
          {test::modelPath("horse.ply"), "horse", views},
          {test::modelPath("fandisk.obj"), "fandisk", views},
          {test::modelPath("spot.obj"), "spot", views},
          // Along the stacking axis: up to 32 layers.
          {"builtin:spheres:32", "spheres32", {{0, 0}}}};
}

inline void PrintTo(const Case& c, std::ostream* os) { *os << c.label; }

class PeelingImages : public test::SceneImageTest<Case> {};

TEST_P(PeelingImages, DpAndDdpMatchEmbree) {
  const Case& c = GetParam();
  auto dp = makeRenderer(Method::Dp);
  auto ddp = makeRenderer(Method::Ddp);
  auto ppll = makeRenderer(Method::Ppll);
  for (const auto& v : c.views) {
    const FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    const RenderResult ref = embree->render(g, s);
    const RenderResult list = ppll->render(g, s);
    ASSERT_GT(list.stats.fragments, 0u);
    const std::string view = "-" + std::to_string(int(v[0])) + "-" + std::to_string(int(v[1]));
    checkFrame(Method::Dp, dp->render(g, s), ref, list, g.triangleCount(), c.label + "-dp" + view);
    checkFrame(Method::Ddp, ddp->render(g, s), ref, list, g.triangleCount(),
               c.label + "-ddp" + view);
  }
}

INSTANTIATE_TEST_SUITE_P(Models, PeelingImages, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return info.param.label; });

TEST(Peeling, SpheresNeedManyPasses) {
  // The deep scene really exercises the loop: dp runs one pass per layer, ddp about half.
  const auto [scene, g] = test::sceneAndGeometry("builtin:spheres:32");
  const FrameSettings s = test::settingsFor(scene, 64, 0, 0);
  const RenderResult a = makeRenderer(Method::Dp)->render(g, s);
  const RenderResult b = makeRenderer(Method::Ddp)->render(g, s);
  EXPECT_GE(a.stats.max_depth_complexity, 24u);
  EXPECT_EQ(a.stats.geometry_passes, a.stats.max_depth_complexity + 1);
  EXPECT_EQ(b.stats.geometry_passes, (b.stats.max_depth_complexity + 1) / 2 + 1);
  EXPECT_LT(b.stats.geometry_passes, a.stats.geometry_passes);
  // One peel launch per pass plus the resolve, after the front end.
  EXPECT_EQ(a.stats.kernel_launches - b.stats.kernel_launches,
            a.stats.geometry_passes - b.stats.geometry_passes);
  test::expectImagesMatch(a.image, b.image, "spheres32-dp-vs-ddp-64");
}

TEST(Peeling, OddFrameSizesAndDepthComplexityMap) {
  // Partial tiles on the right and bottom; the depth-complexity map comes from the first pass.
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("stanford-bunny.obj"));
  FrameSettings s = test::settingsFor(scene, 203, 75, 10);
  s.height = 117;
  s.capture_depth_complexity = true;
  const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  const RenderResult list = makeRenderer(Method::Ppll)->render(g, s);
  for (Method m : {Method::Dp, Method::Ddp}) {
    const RenderResult r = makeRenderer(m)->render(g, s);
    checkFrame(m, r, ref, list, g.triangleCount(), "bunny-odd-" + label(m));
    EXPECT_EQ(r.depth_complexity, list.depth_complexity) << label(m);
  }
}

TEST(Peeling, SeveralFramesGiveTheSamePassesAndImage) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("teapot.obj"));
  FrameSettings s = test::settingsFor(scene, 128, 30, 20);
  for (Method m : {Method::Dp, Method::Ddp}) {
    auto r = makeRenderer(m);
    const RenderResult one = r->render(g, s);
    s.frames = 3;
    const RenderResult three = r->render(g, s);
    s.frames = 1;
    EXPECT_EQ(three.stats.geometry_passes, one.stats.geometry_passes) << label(m);
    EXPECT_EQ(three.stats.frame_ms.runs, 3) << label(m);
    EXPECT_EQ(compareImages(one.image, three.image).max_abs, 0) << label(m);
  }
}

// ---- Ties: coplanar, overlapping triangles at the same depth peel in triangle-id order. ----

void addQuad(WorldGeometry& g, glm::vec3 centre, float half, uint32_t material) {
  const uint32_t base = uint32_t(g.positions.size());
  g.positions.insert(g.positions.end(),
                     {centre + glm::vec3(-half, -half, 0), centre + glm::vec3(half, -half, 0),
                      centre + glm::vec3(half, half, 0), centre + glm::vec3(-half, half, 0)});
  g.indices.insert(g.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  g.triangle_material.insert(g.triangle_material.end(), {material, material});
  g.triangle_object.insert(g.triangle_object.end(), {0, 0});
}

// Three identical quads in the plane z = 0 (ids 0-1, 2-3, 4-5: red, green, blue) in front of a
// yellow quad at z = -1: four layers where the quads overlap, the first three at one depth.
WorldGeometry coplanarScene(bool reversed_ids) {
  WorldGeometry g;
  g.material_colors = {{0.9f, 0.1f, 0.1f, 0.5f},
                       {0.1f, 0.9f, 0.1f, 0.4f},
                       {0.1f, 0.1f, 0.9f, 0.6f},
                       {0.9f, 0.9f, 0.1f, 0.7f}};
  const uint32_t order[3] = {0, 1, 2};
  for (int i = 0; i < 3; ++i) addQuad(g, {0, 0, 0}, 0.6f, reversed_ids ? order[2 - i] : order[i]);
  addQuad(g, {0.3f, 0.3f, -1.0f}, 0.8f, 3);
  return g;
}

FrameSettings coplanarView() {
  FrameSettings s;
  s.width = s.height = 96;
  s.camera = Camera::lookAt({0.1f, 0.05f, 4.0f}, {0.0f, 0.0f, 0.0f});
  s.background.checker = false;
  s.capture_depth_complexity = true;
  return s;
}

TEST(Peeling, CoplanarTrianglesPeelInIdOrder) {
  const FrameSettings s = coplanarView();
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (bool reversed : {false, true}) {
    const WorldGeometry g = coplanarScene(reversed);
    const RenderResult ref = embree->render(g, s);
    const RenderResult list = makeRenderer(Method::Ppll)->render(g, s);
    ASSERT_EQ(list.stats.max_depth_complexity, 4u);
    for (Method m : {Method::Dp, Method::Ddp}) {
      const std::string name = "coplanar-" + label(m) + (reversed ? "-reversed" : "");
      const RenderResult r = makeRenderer(m)->render(g, s);
      checkFrame(m, r, ref, list, g.triangleCount(), name);
      EXPECT_EQ(r.stats.geometry_passes, m == Method::Dp ? 5u : 3u) << name;

      // The centre pixel, composited by hand in id order over the solid background.
      const glm::vec3 light = s.camera.lightDirection();
      glm::vec3 color(0.0f);
      float t = 1.0f;
      for (uint32_t tri : {0u, 2u, 4u, 6u}) {  // one triangle of each quad, in id order
        const glm::vec4 c = shadeTriangle(g, tri, light);
        color += t * c.a * glm::vec3(c);
        t *= 1.0f - c.a;
      }
      color += t * s.background.color;
      const size_t centre = size_t(s.height / 2) * s.width + s.width / 2;
      EXPECT_EQ(r.depth_complexity[centre], 4u) << name;
      for (int ch = 0; ch < 3; ++ch)
        EXPECT_NEAR(r.image.rgba[centre * 4 + ch], std::lround(color[ch] * 255.0f), 1)
            << name << " channel " << ch;
    }
  }
  // The order is visible: the two id orders give different images.
  const RenderResult a = makeRenderer(Method::Dp)->render(coplanarScene(false), s);
  const RenderResult b = makeRenderer(Method::Dp)->render(coplanarScene(true), s);
  EXPECT_LT(compareImages(a.image, b.image).within_2, 0.9);
}

// ---- An empty view: one pass that peels nothing, then the background. ----

TEST(Peeling, EmptyViewTerminatesAfterOnePass) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("cow.obj"));
  FrameSettings s = test::settingsFor(scene, 64, 30, 20);
  const glm::vec3 away = s.camera.eye + (s.camera.eye - s.camera.target);
  s.camera = Camera::lookAt(s.camera.eye, away);  // the model is behind the camera
  const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  for (Method m : {Method::Dp, Method::Ddp}) {
    const RenderResult r = makeRenderer(m)->render(g, s);
    EXPECT_EQ(r.stats.fragments, 0u) << label(m);
    EXPECT_EQ(r.stats.max_depth_complexity, 0u) << label(m);
    EXPECT_EQ(r.stats.geometry_passes, 1u) << label(m);
    EXPECT_EQ(r.stats.triangles_read, g.triangleCount()) << label(m);
    test::expectImagesMatch(r.image, ref.image, "empty-" + label(m));
    // Every pixel is the checker background.
    size_t wrong = 0;
    for (int y = 0; y < r.image.height; ++y)
      for (int x = 0; x < r.image.width; ++x) {
        const bool second = ((x / 16) + (y / 16)) & 1;
        const glm::vec3 bg = second ? s.background.color2 : s.background.color;
        const uint8_t* px = &r.image.rgba[(size_t(y) * r.image.width + x) * 4];
        for (int ch = 0; ch < 3; ++ch)
          wrong += std::abs(int(px[ch]) - int(std::lround(bg[ch] * 255.0f))) > 1;
      }
    EXPECT_EQ(wrong, 0u) << label(m);
  }
}

}  // namespace
}  // namespace strata
