// The fixed-budget A-buffer methods of FreePipe: abuffer (ABS) and mdts (MDTS, 64-bit words)
// must match the Embree reference whenever the per-pixel budget K covers the depth complexity;
// with a smaller K they must lose exactly the fragments past the K-th of each pixel and say how
// much memory keeping them would have taken. mdts32 (the published 32-bit packing) is
// approximate: its error against the reference is measured and reported, and must be worse than
// mdts's but small.
#include <algorithm>
#include <cstdlib>
#include <iostream>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "test_support.h"

namespace strata {
namespace {

struct Case {
  std::string scene;
  std::string label;
};

std::vector<Case> modelCases() {
  return {{test::modelPath("teapot.obj"), "teapot"},
          {test::modelPath("stanford-bunny.obj"), "bunny"},
          {test::modelPath("horse.ply"), "horse"},
          {test::modelPath("fandisk.obj"), "fandisk"},
          {test::modelPath("spot.obj"), "spot"}};
}

inline void PrintTo(const Case& c, std::ostream* os) { *os << c.label; }

const float kViews[][2] = {{30, 20}, {120, -35}, {210, 60}};

std::string viewName(const std::string& label, const std::string& method, const float* v) {
  return label + "-" + method + "-" + std::to_string(int(v[0])) + "-" + std::to_string(int(v[1]));
}

// Fragments a budget of k per pixel cannot keep: every pixel's count past k.
uint64_t fragmentsPast(const std::vector<uint32_t>& depth_complexity, uint32_t k) {
  uint64_t lost = 0;
  for (uint32_t n : depth_complexity) lost += n > k ? n - k : 0;
  return lost;
}

uint64_t sum(const std::vector<uint32_t>& v) {
  uint64_t s = 0;
  for (uint32_t n : v) s += n;
  return s;
}

class FixedBudgetImages : public test::SceneImageTest<Case> {};

TEST_P(FixedBudgetImages, AbufferAndMdtsMatchEmbreeWhenKCoversTheDepth) {
  const Case& c = GetParam();
  const std::pair<Method, const char*> methods[] = {{Method::Abuffer, "abuffer"},
                                                    {Method::Mdts, "mdts"}};
  for (const auto& v : kViews) {
    FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    const RenderResult ref = embree->render(g, s);
    // A budget above the reference's deepest pixel (our fill rule may add one at shared edges).
    s.k = int(std::min<uint64_t>(ST_MAX_K, ref.stats.max_depth_complexity + 4));
    for (const auto& [method, name] : methods) {
      auto r = makeRenderer(method)->render(g, s);
      EXPECT_EQ(r.stats.fragments_lost, 0u) << name;
      EXPECT_EQ(r.stats.geometry_passes, 1u) << name;
      EXPECT_EQ(r.stats.triangles_read, g.triangleCount()) << name;
      EXPECT_GE(r.stats.fragment_bytes, uint64_t(s.k) * 256 * 256 * 8) << name;
      EXPECT_NEAR(double(r.stats.fragments), double(ref.stats.fragments),
                  0.005 * ref.stats.fragments + 4)
          << name;
      test::expectImagesMatch(r.image, ref.image, viewName(c.label, name, v));
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Models, FixedBudgetImages, ::testing::ValuesIn(modelCases()),
                         [](const auto& info) { return info.param.label; });

TEST(FixedBudget, SpheresMatchEmbreeWithKOf64) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:spheres:32");
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto abuffer = makeRenderer(Method::Abuffer);
  auto mdts = makeRenderer(Method::Mdts);
  // The scene's own view looks down the stacks (depth up to 32), plus two views from the side.
  std::vector<FrameSettings> views;
  FrameSettings front;
  front.width = front.height = 256;
  front.camera = Camera::orbit(scene.boundingSphere(), *scene.default_view);
  views.push_back(front);
  views.push_back(test::settingsFor(scene, 256, 30, 20));
  views.push_back(test::settingsFor(scene, 256, 120, -35));
  for (size_t i = 0; i < views.size(); ++i) {
    FrameSettings s = views[i];
    s.k = 64;
    const RenderResult ref = embree->render(g, s);
    ASSERT_LE(ref.stats.max_depth_complexity, 60u);
    for (auto* r : {abuffer.get(), mdts.get()}) {
      const RenderResult res = r->render(g, s);
      EXPECT_EQ(res.stats.fragments_lost, 0u) << res.stats.method;
      test::expectImagesMatch(res.image, ref.image,
                              "spheres32-" + res.stats.method + "-view" + std::to_string(i));
    }
  }
}

// With K below the depth complexity: exactly the fragments past the K-th of each pixel are lost,
// and the memory that would have kept them all is reported.
TEST(FixedBudget, SmallKLosesExactlyTheFragmentsPastK) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  const std::pair<Method, uint64_t> methods[] = {
      {Method::Abuffer, 8}, {Method::Mdts, 8}, {Method::Mdts32, 4}};
  for (const auto& [method, record_bytes] : methods) {
    auto r = makeRenderer(method);
    for (const auto& v : kViews) {
      FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
      s.k = 3;
      s.capture_depth_complexity = true;
      const RenderResult res = r->render(g, s);
      const std::string name = viewName("horse", res.stats.method, v);
      ASSERT_EQ(res.depth_complexity.size(), size_t(256) * 256) << name;
      EXPECT_EQ(sum(res.depth_complexity), res.stats.fragments) << name;
      EXPECT_EQ(*std::max_element(res.depth_complexity.begin(), res.depth_complexity.end()),
                res.stats.max_depth_complexity)
          << name;
      const uint64_t expected_lost = fragmentsPast(res.depth_complexity, 3);
      EXPECT_GT(expected_lost, 0u) << name;
      EXPECT_EQ(res.stats.fragments_lost, expected_lost) << name;
      EXPECT_EQ(res.stats.fragment_bytes, 3u * 256 * 256 * record_bytes) << name;
      EXPECT_EQ(res.stats.bytes_needed, res.stats.max_depth_complexity * 256 * 256 * record_bytes)
          << name;
      EXPECT_GT(res.stats.bytes_needed, res.stats.fragment_bytes) << name;
    }
  }
}

// MDTS keeps the K nearest fragments of every pixel: with K = 1 it is the opaque nearest hit,
// composited with the fragment's opacity over the background.
TEST(FixedBudget, MdtsWithKOfOneKeepsTheNearestFragment) {
  const Scene scene = loadScene(test::modelPath("fandisk.obj"));
  const WorldGeometry opaque_geometry = WorldGeometry::fromScene(scene, 1.0f);
  FrameSettings s = test::settingsFor(scene, 256, 30, 20);
  s.k = 1;
  const RenderResult mdts = makeRenderer(Method::Mdts)->render(opaque_geometry, s);
  const RenderResult nearest = makeRenderer(Method::Opaque)->render(opaque_geometry, s);
  EXPECT_GT(mdts.stats.fragments_lost, 0u);
  test::expectImagesMatch(mdts.image, nearest.image, "fandisk-mdts-k1-vs-opaque");
}

// Slots in global memory (the fallback when K does not fit the device's local memory) give the
// same images and counts as tile-local slots.
TEST(FixedBudget, MdtsGlobalSlotsMatchLocalSlots) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("horse.ply"));
  for (Method m : {Method::Mdts, Method::Mdts32}) {
    for (int k : {3, 40}) {
      FrameSettings s = test::settingsFor(scene, 200, 120, -35);  // partial border tiles
      s.k = k;
      const RenderResult local = makeRenderer(m)->render(g, s);
      s.mdts.global_slots = true;
      const RenderResult global = makeRenderer(m)->render(g, s);
      s.mdts.global_slots = false;
      const std::string name = methodName(m) + " k=" + std::to_string(k);
      EXPECT_EQ(global.image.rgba, local.image.rgba) << name;
      EXPECT_EQ(global.stats.fragments, local.stats.fragments) << name;
      EXPECT_EQ(global.stats.fragments_lost, local.stats.fragments_lost) << name;
      // Slots in local memory still count as fragment memory, so both report the same bytes.
      EXPECT_EQ(global.stats.device_bytes, local.stats.device_bytes) << name;
      EXPECT_EQ(global.stats.fragment_bytes, local.stats.fragment_bytes) << name;
    }
  }
}

// mdts32 packs depth and colour into 32 bits, as published: not exact. Its error against the
// reference is reported; it must be worse than mdts's on the deep spheres scene, yet mostly right.
TEST(FixedBudget, Mdts32ReportsItsPrecisionLoss) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:spheres:32");
  FrameSettings s;
  s.width = s.height = 256;
  s.camera = Camera::orbit(scene.boundingSphere(), *scene.default_view);
  s.k = 64;
  const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  const RenderResult exact = makeRenderer(Method::Mdts)->render(g, s);
  const RenderResult packed = makeRenderer(Method::Mdts32)->render(g, s);
  const ImageDiff de = compareImages(exact.image, ref.image);
  const ImageDiff dp = compareImages(packed.image, ref.image);
  std::cout << "[ mdts32  ] spheres:32 256x256 vs embree: within 2/255 " << 100.0 * dp.within_2
            << "%, mean error " << dp.mean_abs << "/255, max " << dp.max_abs << "/255, PSNR "
            << dp.psnr << " dB (mdts: " << 100.0 * de.within_2 << "%, mean " << de.mean_abs
            << ")\n";
  ::testing::Test::RecordProperty("mdts32_within_2", std::to_string(dp.within_2));
  ::testing::Test::RecordProperty("mdts32_mean_abs", std::to_string(dp.mean_abs));
  EXPECT_EQ(packed.stats.fragments, exact.stats.fragments);
  EXPECT_EQ(packed.stats.fragments_lost, 0u);
  EXPECT_EQ(packed.stats.fragment_bytes, exact.stats.fragment_bytes / 2);  // 4-byte words
  EXPECT_NE(packed.image.rgba, exact.image.rgba) << "the 32-bit packing lost nothing";
  EXPECT_LT(dp.within_2, de.within_2);
  EXPECT_GT(dp.mean_abs, de.mean_abs);
  EXPECT_GT(dp.within_2, 0.5);

  // On the meshes it renders, and its error is measured too.
  const Scene horse = loadScene(test::modelPath("horse.ply"));
  const WorldGeometry hg = WorldGeometry::fromScene(horse);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto mdts32 = makeRenderer(Method::Mdts32);
  for (const auto& v : kViews) {
    FrameSettings hs = test::settingsFor(horse, 256, v[0], v[1]);
    hs.k = 64;
    const ImageDiff d = compareImages(mdts32->render(hg, hs).image, embree->render(hg, hs).image);
    std::cout << "[ mdts32  ] " << viewName("horse", "mdts32", v) << ": within 2/255 "
              << 100.0 * d.within_2 << "%, mean error " << d.mean_abs << "/255\n";
    EXPECT_GT(d.within_2, 0.5);
  }
}

TEST(FixedBudget, BudgetOutsideOneTo256IsAnError) {
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("teapot.obj"));
  for (Method m : {Method::Abuffer, Method::Mdts, Method::Mdts32}) {
    auto r = makeRenderer(m);
    for (int k : {0, ST_MAX_K + 1}) {
      FrameSettings s = test::settingsFor(scene, 64, 30, 20);
      s.k = k;
      EXPECT_THROW(r->render(g, s), Error) << methodName(m) << " k=" << k;
    }
  }
}

}  // namespace
}  // namespace strata
