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
  std::stable_sort(layers.begin(), layers.end(),
                   [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; });
  const size_t core = std::min(layers.size(), size_t(k));
  return frontThenTail({layers.begin(), layers.begin() + long(core)},
                       {layers.begin() + long(core), layers.end()}, s);
}

TEST(Hybrid, StackedQuadsInEveryDrawingOrderFollowThePapersBlendInEitherTileForm) {
  const FrameSettings s = orthoTopDown(kStackSize);
  const int orders = forEveryDrawingOrder(fourStackedLayers(), [&](const auto& drawn, int order) {
    for (int k : {1, 2, 3, 4}) {
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(order));
      const RenderResult serial =
          renderLayered(Method::Hybrid, stackedQuads(drawn), s, k, "serial");
      expectStackPixel(serial, paperBlend(drawn, k, s), s, drawn.size());
      EXPECT_EQ(serial.stats.fragment_bytes, 0u);
      EXPECT_EQ(serial.image.rgba,
                renderLayered(Method::Hybrid, stackedQuads(drawn), s, k, "group").image.rgba)
          << "the tile forms differ";
    }
  });
  EXPECT_EQ(orders, 24);
  // The tail is an approximation: with one exact layer the four layers are not the exact blend.
  const std::vector<StackedLayer> layers = fourStackedLayers();
  EXPECT_GT(glm::length(paperBlend(layers, 1, s) - paperBlend(layers, 4, s)), 4.0 / 255.0);
}

// Exact while k covers the depth, closer as k grows, the forms equal where the tail is used.
TEST(Hybrid, RealMeshesExactWhileKCoversTheDepthAndCloserAsKGrows) {
  expectExactAtDepthAndCloserAsKGrows(Method::Hybrid, "hybrid", 25.0);
}

}  // namespace
}  // namespace strata
