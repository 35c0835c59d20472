// What the frame runner and the renderers keep between render() calls: a geometry with the same
// generation is not uploaded again, and a new generation is (never the stale scene).
#include "test_support.h"

namespace strata {
namespace {

TEST(FrameRunner, SameGenerationReusesTheSceneNewGenerationReplacesIt) {
  const Scene demo = loadScene("builtin:demo"), spheres = loadScene("builtin:spheres:16");
  const WorldGeometry a = WorldGeometry::fromScene(demo), b = WorldGeometry::fromScene(spheres);
  for (Method m : {Method::Ppll, Method::Cells}) {
    SCOPED_TRACE(methodName(m));
    const std::unique_ptr<MethodRenderer> r = makeRenderer(m);
    FrameSettings s = test::settingsFor(demo, 96, 30, 20);
    s.geometry_generation = 7;
    const RenderResult first = r->render(a, s);
    s.camera = test::settingsFor(demo, 96, 120, -10).camera;  // another view, same geometry
    const RenderResult again = r->render(a, s);
    if (m == Method::Ppll) {
      EXPECT_GT(first.stats.scene_upload_bytes, 0u);
      EXPECT_EQ(again.stats.scene_upload_bytes, 0u);
    }
    FrameSettings fresh_settings = s;
    fresh_settings.geometry_generation = 0;
    EXPECT_EQ(compareImages(again.image, makeRenderer(m)->render(a, fresh_settings).image).max_abs,
              0);
    // Another geometry under a new generation is uploaded and drawn.
    s.geometry_generation = 8;
    const RenderResult other = r->render(b, s);
    if (m == Method::Ppll) {
      EXPECT_GT(other.stats.scene_upload_bytes, 0u);
    }
    fresh_settings.geometry_generation = 0;
    EXPECT_EQ(compareImages(other.image, makeRenderer(m)->render(b, fresh_settings).image).max_abs,
              0);
    EXPECT_EQ(other.stats.triangles, b.triangleCount());
  }
}

}  // namespace
}  // namespace strata
