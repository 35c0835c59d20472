// abuffer with a blended tail (AbufferOptions::tail, `--tail blend`): the fragments past a
// pixel's K records are blended order-independently behind the K sorted ones instead of lost.
// Against the blend worked out on the host for stacked quads drawn in every order (the serial
// form keeps the first K to arrive), nothing lost at any K, exact against the Embree reference
// while K covers the depth, and closer to it than dropping when K does not.
#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "layered_methods.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

RenderResult renderAbuffer(const WorldGeometry& g, FrameSettings s, int k, AbufferTail tail,
                           const std::string& form) {
  s.abuffer.tail = tail;
  return renderLayered(Method::Abuffer, g, s, k, form);
}

// The first k layers to arrive sorted and composited front to back, then the others' opacity-
// weighted mean colour C and mean opacity a over their count n, as C (1 - (1 - a)^n), then the
// background.
glm::dvec3 tailBlend(const std::vector<StackedLayer>& drawn, int k, const FrameSettings& s) {
  const long kept = std::min<long>(k, long(drawn.size()));
  std::vector<StackedLayer> front(drawn.begin(), drawn.begin() + kept);
  std::sort(front.begin(), front.end(),
            [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; });
  return frontThenTail(front, {drawn.begin() + kept, drawn.end()}, s);
}

TEST(AbufferTail, StackedQuadsInEveryDrawingOrderBlendWhatDoesNotFit) {
  const FrameSettings s = orthoTopDown(kStackSize);
  const int orders = forEveryDrawingOrder(fourStackedLayers(), [&](const auto& drawn, int order) {
    for (int k : {1, 2, 3, 4}) {
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(order));
      expectStackPixel(renderAbuffer(stackedQuads(drawn), s, k, AbufferTail::Blend, "serial"),
                       tailBlend(drawn, k, s), s, drawn.size());
    }
  });
  EXPECT_EQ(orders, 24);
}

// Exact while K covers the depth (both forms; nothing goes to the tail); below it nothing is
// lost, and on meshes the image is closer to the reference than dropping the fragments past K.
// Not everywhere: the tail is shown behind the K kept, so where the fragments past K are the
// nearer ones (drawn far to near), blending them behind can be further off than dropping them
// (spheres:16 from (30, 20) at K = 4: 22.1 against 24.0 dB).
TEST(AbufferTail, RealMeshesExactWhileKCoversTheDepthAndCloserThanDroppingBelow) {
  forEachSceneWithReference(
      {"horse.ply", "stanford-bunny.obj", "builtin:spheres:16"}, 160,
      [](const WorldGeometry& g, const FrameSettings& s, const RenderResult& ref, bool mesh) {
        const int depth = int(makeRenderer(Method::Ppll)->render(g, s).stats.max_depth_complexity);
        for (const char* form : {"serial", "group"}) {
          const RenderResult exact = renderAbuffer(g, s, depth, AbufferTail::Blend, form);
          expectImagesMatch(exact.image, ref.image, std::string("abuffer-tail-exact-") + form);
          EXPECT_EQ(exact.stats.fragments_lost, 0u);
        }
        const int k = std::max(1, depth / 4);
        const RenderResult dropped = renderAbuffer(g, s, k, AbufferTail::Drop, "serial");
        EXPECT_GT(dropped.stats.fragments_lost, 0u);
        const double drop_psnr = compareImages(dropped.image, ref.image).psnr;
        // The group form keeps other fragments past K (its arrival order differs), with the same
        // counts.
        for (const char* form : {"serial", "group"}) {
          const RenderResult blended = renderAbuffer(g, s, k, AbufferTail::Blend, form);
          EXPECT_EQ(blended.stats.fragments_lost, 0u) << form;
          EXPECT_EQ(blended.stats.fragments, dropped.stats.fragments) << form;
          if (mesh) {
            EXPECT_GT(compareImages(blended.image, ref.image).psnr, drop_psnr + 1.0) << form;
          }
        }
      });
}

TEST(AbufferTail, UnknownTailIsRefused) {
  expectErrorContaining([] { parseAbufferTail("keep"); }, "unknown abuffer tail 'keep'");
  EXPECT_EQ(parseAbufferTail("blend"), AbufferTail::Blend);
  EXPECT_STREQ(optionName(AbufferTail::Drop), "drop");
}

}  // namespace
}  // namespace strata
