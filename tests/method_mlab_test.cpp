// mlab, multi-layer alpha blending (Salvi and Vaidyanathan 2014), an approximate method: its
// blend against the paper's insert-and-merge worked out on the host for stacked quads drawn in
// every order (the merge makes the order matter), exact against the Embree reference while k
// covers a pixel's fragments, its error on real meshes bounded and shrinking as k grows, and
// the two tile kernel forms equal bit for bit (each pixel takes its fragments in drawing order).
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "kernels/strata_shared.h"
#include "layered_methods.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

using Layer = StackedLayer;

// The paper's blend at a pixel that every layer covers, the layers arriving in the given order:
// each inserted by depth into k slots of (premultiplied colour, transmittance, depth), the last
// two merged when there would be k + 1; then the slots composited front to back.
glm::dvec3 paperBlend(const std::vector<Layer>& drawn, int k, const FrameSettings& s) {
  const double shade = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  struct Slot {
    glm::dvec3 c{0.0};
    double t = 1.0, depth = std::numeric_limits<double>::infinity();
  };
  std::vector<Slot> slots(size_t(k) + 1);
  for (const Layer& l : drawn) {
    slots[size_t(k)] = {glm::dvec3(l.color) * shade * double(l.alpha), 1.0 - l.alpha, 5.0 - l.z};
    std::stable_sort(slots.begin(), slots.end(),
                     [](const Slot& a, const Slot& b) { return a.depth < b.depth; });
    Slot& front = slots[size_t(k) - 1];
    const Slot back = slots[size_t(k)];
    front.c += front.t * back.c;
    front.t *= back.t;
    slots[size_t(k)] = Slot{};
  }
  glm::dvec3 colour(0.0);
  double t = 1.0;
  for (int i = 0; i < k; ++i) {
    colour += t * slots[size_t(i)].c;
    t *= slots[size_t(i)].t;
  }
  return colour + t * glm::dvec3(s.background.color);
}

RenderResult renderMlab(const WorldGeometry& g, const FrameSettings& s, int k,
                        const std::string& form = "auto") {
  return renderLayered(Method::Mlab, g, s, k, form);
}

TEST(Mlab, StackedQuadsInEveryDrawingOrderFollowThePapersMergeInEitherTileForm) {
  const FrameSettings s = orthoTopDown(kStackSize);
  int order_mattered = 0;
  const int orders = forEveryDrawingOrder(fourStackedLayers(), [&](const auto& drawn, int order) {
    for (int k : {1, 2, 3, 4}) {
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(order));
      const RenderResult serial = renderMlab(stackedQuads(drawn), s, k, "serial");
      expectStackPixel(serial, paperBlend(drawn, k, s), s, drawn.size());
      EXPECT_EQ(serial.stats.fragment_bytes, 0u);
      EXPECT_EQ(serial.image.rgba, renderMlab(stackedQuads(drawn), s, k, "group").image.rgba)
          << "the tile forms differ";
    }
    // With one layer the merge is plain blending in arrival order: back to front is exact,
    // front to back (under instead of over) is not.
    if (glm::length(paperBlend(drawn, 4, s) - paperBlend(drawn, 1, s)) > 4.0 / 255.0)
      ++order_mattered;
  });
  EXPECT_EQ(orders, 24);
  EXPECT_GT(order_mattered, 0);  // the test exercises the merge, not only the exact case
}

TEST(Mlab, KOutsideItsRangeIsRefused) {
  const WorldGeometry g = stackedQuads({{{0.5f, 0.5f, 0.5f}, 0.5f, 0.0f}});
  const FrameSettings s = orthoTopDown(kStackSize);
  expectErrorContaining([&] { renderMlab(g, s, 0); }, "mlab: the per-pixel budget k = 0");
  expectErrorContaining([&] { renderMlab(g, s, ST_MAX_K + 1); }, "between 1 and");
}

// Exact while k covers the depth, closer as k grows, the forms equal where layers merge
// (measured at 192 x 192: spheres:16 37.5 dB at k = 1, 49 at 4, 63 at 8).
TEST(Mlab, RealMeshesExactWhileKCoversTheDepthAndCloserAsKGrows) {
  expectExactAtDepthAndCloserAsKGrows(Method::Mlab, "mlab", 25.0);
}

}  // namespace
}  // namespace strata
