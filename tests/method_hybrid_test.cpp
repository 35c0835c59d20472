// hybrid, hybrid transparency (Maule, Comba, Torchelsen and Bastos 2013), an approximate method:
// its blend against the paper's worked out on the host for stacked quads drawn in every order
// (the k nearest exact and in order, the rest as Bavoil and Myers' weighted average, whatever the
// order), exact against the Embree reference while k covers a pixel's fragments, its error on
// real meshes bounded and shrinking as k grows, and the two tile kernel forms equal bit for bit.
#include <algorithm>
#include <cmath>
#include <vector>

#include "kernels/strata_shared.h"
#include "layered_methods.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

// The paper's blend at a pixel that every layer covers: the k nearest composited front to
// back, behind them the others' opacity-weighted mean colour C and mean opacity a over their
// count n, as C (1 - (1 - a)^n), then the background.
glm::dvec3 paperBlend(std::vector<StackedLayer> layers, int k, const FrameSettings& s) {
  const double shade = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  std::stable_sort(layers.begin(), layers.end(),
                   [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; });
  glm::dvec3 colour(0.0), tail_sum(0.0);
  double t = 1.0, tail_alpha = 0.0;
  int n = 0;
  for (size_t i = 0; i < layers.size(); ++i) {
    const glm::dvec3 c = glm::dvec3(layers[i].color) * shade;
    const double a = layers[i].alpha;
    if (int(i) < k) {
      colour += t * a * c;
      t *= 1.0 - a;
    } else {
      tail_sum += a * c;
      tail_alpha += a;
      ++n;
    }
  }
  if (n > 0) {
    const double tail_t = std::pow(1.0 - tail_alpha / n, n);
    colour += t * (1.0 - tail_t) * tail_sum / tail_alpha;
    t *= tail_t;
  }
  return colour + t * glm::dvec3(s.background.color);
}

TEST(Hybrid, StackedQuadsInEveryDrawingOrderFollowThePapersBlendInEitherTileForm) {
  std::vector<StackedLayer> layers = {{{0.9f, 0.2f, 0.1f}, 0.6f, 0.5f},
                                      {{0.1f, 0.3f, 0.9f}, 0.3f, 0.0f},
                                      {{0.2f, 0.8f, 0.3f}, 0.5f, -0.5f},
                                      {{0.8f, 0.7f, 0.2f}, 0.4f, -1.0f}};
  const FrameSettings s = orthoTopDown(kStackSize);
  auto nearer = [](const StackedLayer& a, const StackedLayer& b) { return a.z < b.z; };
  std::sort(layers.begin(), layers.end(), nearer);
  int orders = 0;
  do {
    for (int k : {1, 2, 3, 4}) {
      const glm::dvec3 expected = paperBlend(layers, k, s);
      const RenderResult serial =
          renderLayered(Method::Hybrid, stackedQuads(layers), s, k, "serial");
      const RenderResult group = renderLayered(Method::Hybrid, stackedQuads(layers), s, k, "group");
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(orders));
      const uint8_t* px = serial.image.pixel(kInsideX, kInsideY);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(int(px[c]), int(unorm8(expected[c])), 1) << "channel " << c;
      EXPECT_EQ(serial.image.rgba, group.image.rgba) << "the tile forms differ";
      EXPECT_EQ(serial.image.pixel(2, 2)[0], unorm8(s.background.color[0]));  // outside
      EXPECT_EQ(serial.stats.max_depth_complexity, 4u);
      EXPECT_EQ(serial.stats.fragment_bytes, 0u);
    }
    ++orders;
  } while (std::next_permutation(layers.begin(), layers.end(), nearer));
  EXPECT_EQ(orders, 24);
  // The tail is an approximation: with one exact layer the four layers are not the exact blend.
  EXPECT_GT(glm::length(paperBlend(layers, 1, s) - paperBlend(layers, 4, s)), 4.0 / 255.0);
}

// Exact while k covers the depth, closer as k grows, the forms equal where the tail is used.
TEST(Hybrid, RealMeshesExactWhileKCoversTheDepthAndCloserAsKGrows) {
  expectExactAtDepthAndCloserAsKGrows(Method::Hybrid, "hybrid", 25.0);
}

}  // namespace
}  // namespace strata
