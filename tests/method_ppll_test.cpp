// The linked lists on pathological depth: pixels far deeper than the resolve's private array
// (thousands of coincident faces) are resolved in windows of that array, not by an O(n^2)
// selection walk, and stop once no light gets through; the image still matches exact methods.
#include <gtest/gtest.h>

#include "engine/renderer.h"
#include "test_support.h"

namespace strata {
namespace {

// `copies` copies of one triangle facing the camera, each of opacity `alpha`.
WorldGeometry coincidentFaces(int copies, float alpha) {
  WorldGeometry g;
  g.positions = {{-1.0f, -1.0f, 0.0f}, {1.0f, -1.0f, 0.0f}, {0.0f, 1.0f, 0.0f}};
  for (int i = 0; i < copies; ++i) {
    g.indices.insert(g.indices.end(), {0u, 1u, 2u});
    g.triangle_material.push_back(uint32_t(i % 3));
    g.triangle_object.push_back(0);
  }
  g.material_colors = {glm::vec4(0.9f, 0.2f, 0.1f, alpha), glm::vec4(0.1f, 0.8f, 0.2f, alpha),
                       glm::vec4(0.2f, 0.3f, 0.9f, alpha)};
  return g;
}

FrameSettings frontView(int size) {
  FrameSettings s;
  s.width = s.height = size;
  s.camera = Camera::lookAt({0.0f, 0.0f, 3.0f}, {0.0f, 0.0f, 0.0f});
  return s;
}

// 400 faint layers: every one counts, in (depth, id) order, as depth peeling composites them.
TEST(PpllDeepPixels, WindowedResolveMatchesDepthPeeling) {
  const WorldGeometry g = coincidentFaces(400, 0.01f);
  const FrameSettings s = frontView(32);
  const RenderResult lists = makeRenderer(Method::Ppll)->render(g, s);
  const RenderResult peeled = makeRenderer(Method::Dp)->render(g, s);
  EXPECT_EQ(lists.stats.max_depth_complexity, 400u);
  EXPECT_EQ(lists.stats.fragments, peeled.stats.fragments);
  EXPECT_LE(compareImages(lists.image, peeled.image).max_abs, 1);
}

// 10,000 layers of one colour at opacity 0.5 (the fuzzed hang): resolved at once, and the pixel
// is that colour within a step, as one opaque layer would be.
TEST(PpllDeepPixels, TenThousandCoincidentFacesResolveAsTheNearestOpaqueLayer) {
  WorldGeometry g = coincidentFaces(10000, 0.5f);
  for (uint32_t& m : g.triangle_material) m = 0;  // one colour: the layers add up to it
  const FrameSettings s = frontView(32);
  const RenderResult lists = makeRenderer(Method::Ppll)->render(g, s);
  EXPECT_EQ(lists.stats.max_depth_complexity, 10000u);
  WorldGeometry opaque_front = coincidentFaces(1, 1.0f);
  const RenderResult front = makeRenderer(Method::Ppll)->render(opaque_front, s);
  EXPECT_LE(compareImages(lists.image, front.image).max_abs, 1);
}

}  // namespace
}  // namespace strata
