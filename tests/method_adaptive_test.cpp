// adaptive, adaptive transparency (Salvi, Montgomery and Lefohn 2011), an approximate method:
// its visibility function and compression against the paper's worked out on the host for
// stacked quads drawn in every order (the least-area removal makes the order matter), the total
// transmittance exact whatever k, exact against the Embree reference while k covers a pixel's
// fragments, its error on real meshes bounded and shrinking as k grows, and the two tile kernel
// forms equal bit for bit.
#include <algorithm>
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

struct Node {
  double depth, t;
};

// The paper's visibility function after the layers arrive in the given order: each inserted as
// a node (the nodes behind it darkened), and when there are k + 1 nodes the one whose removal
// takes away the least area under the curve (d_i - d_{i-1}) (T_{i-1} - T_i), i >= 1, removed by
// moving its step onto the node in front.
std::vector<Node> paperVisibility(const std::vector<StackedLayer>& drawn, int k) {
  std::vector<Node> nodes;
  for (const StackedLayer& l : drawn) {
    const double depth = 5.0 - l.z, t = 1.0 - l.alpha;
    size_t at = 0;
    while (at < nodes.size() && nodes[at].depth < depth) ++at;
    for (size_t i = at; i < nodes.size(); ++i) nodes[i].t *= t;
    nodes.insert(nodes.begin() + long(at), {depth, (at > 0 ? nodes[at - 1].t : 1.0) * t});
    if (int(nodes.size()) <= k) continue;
    size_t removed = 1;
    double least = std::numeric_limits<double>::infinity();
    for (size_t i = 1; i < nodes.size(); ++i) {
      const double area = (nodes[i].depth - nodes[i - 1].depth) * (nodes[i - 1].t - nodes[i].t);
      if (area < least) least = area, removed = i;
    }
    nodes[removed - 1].t = nodes[removed].t;
    nodes.erase(nodes.begin() + long(removed));
  }
  return nodes;
}

// Every layer's premultiplied colour through vis(its depth), then the background through the
// total transmittance.
glm::dvec3 paperBlend(const std::vector<StackedLayer>& drawn, int k, const FrameSettings& s,
                      double* total = nullptr) {
  const double shade = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  const std::vector<Node> nodes = paperVisibility(drawn, k);
  glm::dvec3 colour(0.0);
  for (const StackedLayer& l : drawn) {
    double vis = 1.0;
    for (const Node& n : nodes)
      if (n.depth < 5.0 - l.z) vis = n.t;
    colour += vis * double(l.alpha) * glm::dvec3(l.color) * shade;
  }
  const double t = nodes.back().t;
  if (total) *total = t;
  return colour + t * glm::dvec3(s.background.color);
}

TEST(Adaptive, StackedQuadsInEveryDrawingOrderFollowThePapersCompressionInEitherTileForm) {
  const FrameSettings s = orthoTopDown(kStackSize);
  std::vector<StackedLayer> layers = fourStackedLayers();
  layers[2].z = -0.3f;  // uneven gaps: the least-area choice is not a tie
  double exact_total = 0.0;
  const glm::dvec3 exact = paperBlend(layers, 4, s, &exact_total);
  int approximated = 0;
  const int orders = forEveryDrawingOrder(layers, [&](const auto& drawn, int order) {
    for (int k : {1, 2, 3, 4}) {
      SCOPED_TRACE("k " + std::to_string(k) + " order " + std::to_string(order));
      double total = 0.0;
      const glm::dvec3 expected = paperBlend(drawn, k, s, &total);
      EXPECT_NEAR(total, exact_total, 1e-12);  // compression keeps the total transmittance
      if (glm::length(expected - exact) > 4.0 / 255.0) ++approximated;
      const RenderResult serial =
          renderLayered(Method::Adaptive, stackedQuads(drawn), s, k, "serial");
      expectStackPixel(serial, expected, s, drawn.size());
      EXPECT_EQ(serial.stats.fragment_bytes, 0u);
      EXPECT_EQ(serial.image.rgba,
                renderLayered(Method::Adaptive, stackedQuads(drawn), s, k, "group").image.rgba)
          << "the tile forms differ";
    }
  });
  EXPECT_EQ(orders, 24);
  EXPECT_GT(approximated, 24);  // the compression is exercised, not only the exact case
}

TEST(Adaptive, KOutsideItsRangeIsRefused) {
  const WorldGeometry g = stackedQuads({{{0.5f, 0.5f, 0.5f}, 0.5f, 0.0f}});
  const FrameSettings s = orthoTopDown(kStackSize);
  expectErrorContaining([&] { renderLayered(Method::Adaptive, g, s, 0); },
                        "adaptive: the per-pixel budget k = 0");
  expectErrorContaining([&] { renderLayered(Method::Adaptive, g, s, ST_MAX_K + 1); },
                        "between 1 and");
}

// Exact while k covers the depth, closer as k grows, the forms equal where nodes are removed.
// With few nodes the function darkens everything behind the nearest layers (at 256 x 256,
// spheres:16, 16 layers deep: 15.0 dB at k = 1, 31.1 at 4, 53.2 at 8, exact at 16).
TEST(Adaptive, RealMeshesExactWhileKCoversTheDepthAndCloserAsKGrows) {
  expectExactAtDepthAndCloserAsKGrows(Method::Adaptive, "adaptive", 12.0);
}

}  // namespace
}  // namespace strata
