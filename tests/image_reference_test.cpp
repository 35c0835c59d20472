// Image tests: the OpenCL methods against the independent Embree reference on real meshes.
#include "engine/reference/embree_reference.h"
#include "preprocess/mesh_loader.h"
#include "test_support.h"

namespace strata {
namespace {

using Case = test::SceneCase;

std::vector<Case> cases() { return test::sharedSceneCases({16, 32}); }

// Views spread around the model: azimuths all round, elevations above and below.
const float kViews[][2] = {{30, 20}, {120, -35}, {210, 60}, {300, -10}, {0, 85}};

class ReferenceImages : public test::SceneImageTest<Case> {};

// The exact transparency methods, each against the same Embree image: ppll, the fixed-budget
// A-buffers with K above the depth, and depth / dual depth peeling.
TEST_P(ReferenceImages, ExactTransparencyMethodsMatchEmbree) {
  const Case& c = GetParam();
  const Method methods[] = {Method::Ppll, Method::Abuffer, Method::Mdts, Method::Dp, Method::Ddp};
  std::vector<std::unique_ptr<MethodRenderer>> renderers;
  for (Method m : methods) renderers.push_back(makeRenderer(m));
  const bool deep = c.scene.rfind("builtin:spheres", 0) == 0;
  for (const auto& v : kViews) {
    if (deep && &v - kViews >= 2) break;  // two views of the deep scenes keep the suite quick
    FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    s.k = 64;  // above every depth complexity here, so the fixed budgets lose nothing
    const RenderResult ref = embree->render(g, s);
    for (size_t i = 0; i < renderers.size(); ++i) {
      const std::string name = methodName(methods[i]);
      SCOPED_TRACE(name);
      const RenderResult a = renderers[i]->render(g, s);
      EXPECT_GT(a.stats.fragments, 0u);
      EXPECT_EQ(a.stats.fragments_lost, 0u);
      EXPECT_EQ(a.stats.triangles_read, g.triangleCount() * a.stats.geometry_passes);
      // Same fragments within a fraction (edge pixels may differ between fill rules).
      EXPECT_NEAR(double(a.stats.fragments), double(ref.stats.fragments),
                  0.005 * ref.stats.fragments + 4);
      test::expectImagesMatch(
          a.image, ref.image,
          c.label + "-" + name + "-" + std::to_string(int(v[0])) + "-" + std::to_string(int(v[1])));
    }
  }
}

TEST_P(ReferenceImages, OpaqueMatchesEmbreeNearestHit) {
  const Case& c = GetParam();
  auto opaque = makeRenderer(Method::Opaque);
  embree = makeEmbreeRenderer(EmbreeMode::Opaque);
  for (const auto& v : kViews) {
    const FrameSettings s = test::settingsFor(scene, 256, v[0], v[1]);
    test::expectImagesMatch(
        opaque->render(g, s).image, embree->render(g, s).image,
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
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("cow.obj"));
  auto ppll = makeRenderer(Method::Ppll);
  const Image a = ppll->render(g, test::settingsFor(scene, 128, 30, 20)).image;
  const Image b = ppll->render(g, test::settingsFor(scene, 128, 36, 20)).image;
  EXPECT_LT(compareImages(a, b).within_2, 0.995);
}

}  // namespace
}  // namespace strata
