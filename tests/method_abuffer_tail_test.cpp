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
  const double shade = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  std::vector<StackedLayer> kept(drawn.begin(),
                                 drawn.begin() + std::min<long>(k, long(drawn.size())));
  std::sort(kept.begin(), kept.end(),
            [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; });
  glm::dvec3 colour(0.0), tail_sum(0.0);
  double t = 1.0, tail_alpha = 0.0;
  for (const StackedLayer& l : kept) {
    colour += t * double(l.alpha) * glm::dvec3(l.color) * shade;
    t *= 1.0 - l.alpha;
  }
  int n = 0;
  for (size_t i = kept.size(); i < drawn.size(); ++i, ++n) {
    tail_sum += double(drawn[i].alpha) * glm::dvec3(drawn[i].color) * shade;
    tail_alpha += drawn[i].alpha;
  }
  if (n > 0) {
    const double tail_t = std::pow(1.0 - tail_alpha / n, n);
    colour += t * (1.0 - tail_t) * tail_sum / tail_alpha;
    t *= tail_t;
  }
  return colour + t * glm::dvec3(s.background.color);
}

TEST(AbufferTail, StackedQuadsInEveryDrawingOrderBlendWhatDoesNotFit) {
  std::vector<StackedLayer> layers = {{{0.9f, 0.2f, 0.1f}, 0.6f, 0.5f},
                                      {{0.1f, 0.3f, 0.9f}, 0.3f, 0.0f},
                                      {{0.2f, 0.8f, 0.3f}, 0.5f, -0.5f},
                                      {{0.8f, 0.7f, 0.2f}, 0.4f, -1.0f}};
  const FrameSettings s = orthoTopDown(kStackSize);
  auto nearer = [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; };
  std::sort(layers.begin(), layers.end(), nearer);
  int orders = 0;
  do {
    for (int k : {1, 2, 3, 4}) {
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(orders));
      const glm::dvec3 expected = tailBlend(layers, k, s);
      const RenderResult r =
          renderAbuffer(stackedQuads(layers), s, k, AbufferTail::Blend, "serial");
      const uint8_t* px = r.image.pixel(kInsideX, kInsideY);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(int(px[c]), int(unorm8(expected[c])), 1) << "channel " << c;
      EXPECT_EQ(r.image.pixel(2, 2)[0], unorm8(s.background.color[0]));  // outside
      EXPECT_EQ(r.stats.fragments_lost, 0u);
      EXPECT_EQ(r.stats.max_depth_complexity, 4u);
    }
    ++orders;
  } while (std::next_permutation(layers.begin(), layers.end(), nearer));
  EXPECT_EQ(orders, 24);
}

// Exact while K covers the depth (both forms; nothing goes to the tail); below it nothing is
// lost, and on meshes the image is closer to the reference than dropping the fragments past K.
// Not everywhere: the tail is shown behind the K kept, so where the fragments past K are the
// nearer ones (drawn far to near), blending them behind can be further off than dropping them
// (spheres:16 from (30, 20) at K = 4: 22.1 against 24.0 dB).
TEST(AbufferTail, RealMeshesExactWhileKCoversTheDepthAndCloserThanDroppingBelow) {
  for (const char* scene : {"horse.ply", "stanford-bunny.obj", "builtin:spheres:16"}) {
    SCOPED_TRACE(scene);
    const bool mesh = std::string(scene).rfind("builtin:", 0) != 0;
    const auto [sc, g] = sceneAndGeometry(mesh ? modelPath(scene) : scene);
    const FrameSettings s = settingsFor(sc, 160, 30.0f, 20.0f);
    const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
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
      if (mesh) EXPECT_GT(compareImages(blended.image, ref.image).psnr, drop_psnr + 1.0) << form;
    }
  }
}

TEST(AbufferTail, UnknownTailIsRefused) {
  expectErrorContaining([] { parseAbufferTail("keep"); }, "unknown abuffer tail 'keep'");
  EXPECT_EQ(parseAbufferTail("blend"), AbufferTail::Blend);
  EXPECT_STREQ(optionName(AbufferTail::Drop), "drop");
}

}  // namespace
}  // namespace strata
