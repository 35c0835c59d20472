// Image tests: the OpenCL methods against the independent Embree reference on real meshes.
#include "engine/embree_reference.h"
#include "preprocess/mesh_loader.h"
#include "test_support.h"

namespace strata {
namespace {

struct Case {
  std::string scene;
  std::string label;
};

std::vector<Case> cases() {
  return {{test::modelPath("teapot.obj"), "teapot"},
          {test::modelPath("stanford-bunny.obj"), "bunny"},
          {test::modelPath("horse.ply"), "horse"},
          {test::modelPath("fandisk.obj"), "fandisk"},
          {test::modelPath("spot.obj"), "spot"},
          {test::modelPath("rocker-arm.obj"), "rocker-arm"},
          {"builtin:spheres:16", "spheres16"},
          {"builtin:demo", "demo"}};
}

inline void PrintTo(const Case& c, std::ostream* os) { *os << c.label; }

// Views spread around the model: azimuths all round, elevations above and below.
const float kViews[][2] = {{30, 20}, {120, -35}, {210, 60}, {300, -10}, {0, 85}};

class ReferenceImages : public ::testing::TestWithParam<Case> {};

TEST_P(ReferenceImages, PpllMatchesEmbree) {
  const Case& c = GetParam();
  const Scene scene = loadScene(c.scene);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  auto ppll = makeRenderer(Method::Ppll);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (const auto& v : kViews) {
    const FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    RenderResult a = ppll->render(g, s);
    RenderResult b = embree->render(g, s);
    EXPECT_GT(a.stats.fragments, 0u);
    EXPECT_EQ(a.stats.triangles_read, g.triangleCount());
    // Same fragments within a fraction (edge pixels may differ between fill rules).
    EXPECT_NEAR(double(a.stats.fragments), double(b.stats.fragments), 0.005 * b.stats.fragments + 4);
    test::expectImagesMatch(a.image, b.image,
                            c.label + "-ppll-" + std::to_string(int(v[0])) + "-" + std::to_string(int(v[1])));
  }
}

TEST_P(ReferenceImages, OpaqueMatchesEmbreeNearestHit) {
  const Case& c = GetParam();
  const Scene scene = loadScene(c.scene);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  auto opaque = makeRenderer(Method::Opaque);
  auto embree = makeEmbreeRenderer(EmbreeMode::Opaque);
  for (const auto& v : kViews) {
    const FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    test::expectImagesMatch(opaque->render(g, s).image, embree->render(g, s).image,
                            c.label + "-opaque-" + std::to_string(int(v[0])) + "-" + std::to_string(int(v[1])));
  }
}

INSTANTIATE_TEST_SUITE_P(Models, ReferenceImages, ::testing::ValuesIn(cases()),
                         [](const auto& info) {
                           std::string n = info.param.label;
                           for (char& ch : n)
                             if (!isalnum((unsigned char)ch)) ch = '_';
                           return n;
                         });

TEST(ReferenceImagesSanity, ADifferentImageFailsTheComparison) {
  // The comparison itself must be able to fail: a view rotated by a few degrees differs.
  const Scene scene = loadScene(test::modelPath("cow.obj"));
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  auto ppll = makeRenderer(Method::Ppll);
  const Image a = ppll->render(g, test::settingsFor(scene, 128, 30, 20)).image;
  const Image b = ppll->render(g, test::settingsFor(scene, 128, 36, 20)).image;
  EXPECT_LT(compareImages(a, b).within_2, 0.995);
}

}  // namespace
}  // namespace strata
