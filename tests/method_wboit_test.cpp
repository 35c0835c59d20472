// wboit, weighted blended OIT (McGuire and Bavoil 2013), an approximate method: its blend against
// the paper's formula worked out by hand on stacked quads (the revealage exact, the colour an
// average in which nearer layers weigh more), exact where a pixel's layers share one colour,
// independent of the drawing order, and its error against the Embree reference on real meshes
// measured and bounded, in both tile kernel forms.
#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

// The paper's weight functions, its equations (7) to (10); (10) with the depth-buffer value
// d = 1 - near / z (kernels/wboit.cl).
double weight(WboitWeight eq, double a, double z, double near_distance) {
  double w = 0.0;
  switch (eq) {
    case WboitWeight::Eq7:
      w = 10.0 / (1e-5 + std::pow(z / 5.0, 2.0) + std::pow(z / 200.0, 6.0));
      break;
    case WboitWeight::Eq8:
      w = 10.0 / (1e-5 + std::pow(z / 10.0, 3.0) + std::pow(z / 200.0, 6.0));
      break;
    case WboitWeight::Eq9:
      w = 0.03 / (1e-5 + std::pow(z / 200.0, 4.0));
      break;
    case WboitWeight::Eq10:
      w = 3e3 * std::pow(near_distance / std::max(z, near_distance), 3.0);
      break;
  }
  return a * std::clamp(w, 1e-2, 3e3);
}

using Layer = StackedLayer;

// The paper's equation (6) at a pixel that every layer covers, channel ch.
double paperBlend(const std::vector<Layer>& layers, const FrameSettings& s, int ch) {
  const double shade = st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
  double colour = 0.0, coverage = 0.0, revealage = 1.0;
  for (const Layer& l : layers) {
    const double w = weight(s.wboit.weight, l.alpha, 5.0 - l.z, s.camera.near_distance);
    colour += shade * l.color[ch] * l.alpha * w;
    coverage += l.alpha * w;
    revealage *= 1.0 - l.alpha;
  }
  return colour / std::clamp(coverage, 1e-4, 5e4) * (1.0 - revealage) +
         s.background.color[ch] * revealage;
}

RenderResult renderWboit(const WorldGeometry& g, FrameSettings s,
                         const std::string& form = "auto") {
  s.tile_kernels = form;
  return makeRenderer(Method::Wboit)->render(g, s);
}

TEST(Wboit, StackedQuadsFollowThePapersBlendWithEachWeightInEitherTileForm) {
  const std::vector<Layer> layers = {{{0.9f, 0.2f, 0.1f}, 0.6f, 0.5f},
                                     {{0.1f, 0.3f, 0.9f}, 0.3f, 0.0f},
                                     {{0.2f, 0.8f, 0.3f}, 0.5f, -0.5f}};
  FrameSettings s = orthoTopDown(kStackSize);
  for (const char* name : {"eq7", "eq8", "eq9", "eq10"})
    for (const char* form : {"group", "serial"}) {
      SCOPED_TRACE(std::string(name) + " " + form);
      s.wboit.weight = parseWboitWeight(name);
      EXPECT_STREQ(optionName(s.wboit.weight), name);
      const RenderResult r = renderWboit(stackedQuads(layers), s, form);
      for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(int(r.image.pixel(kInsideX, kInsideY)[c]),
                    int(unorm8(paperBlend(layers, s, c))), 1)
            << "channel " << c;
      EXPECT_EQ(r.image.pixel(2, 2)[0], unorm8(s.background.color[0]));  // outside the quads
      EXPECT_EQ(r.stats.max_depth_complexity, 3u);
      EXPECT_EQ(r.stats.geometry_passes, 1u);
      EXPECT_EQ(r.stats.fragment_bytes, 0u);
    }
  expectErrorContaining([] { parseWboitWeight("eq11"); }, "'eq11'");
}

TEST(Wboit, NearerLayersWeighMoreAndDrawingOrderDoesNotMatter) {
  const glm::vec3 red(0.9f, 0.2f, 0.1f), blue(0.1f, 0.3f, 0.9f);
  const FrameSettings s = orthoTopDown(kStackSize);
  const RenderResult red_front =
      renderWboit(stackedQuads({{red, 0.5f, 0.5f}, {blue, 0.5f, -2.0f}}), s);
  const RenderResult blue_front =
      renderWboit(stackedQuads({{red, 0.5f, -2.0f}, {blue, 0.5f, 0.5f}}), s);
  const uint8_t* rf = red_front.image.pixel(kInsideX, kInsideY);
  const uint8_t* bf = blue_front.image.pixel(kInsideX, kInsideY);
  EXPECT_GT(rf[0], bf[0]);
  EXPECT_LT(rf[2], bf[2]);
  // The same layers drawn in the other order: the sums are the same up to float rounding.
  const RenderResult reordered =
      renderWboit(stackedQuads({{blue, 0.5f, -2.0f}, {red, 0.5f, 0.5f}}), s);
  EXPECT_LE(compareImages(reordered.image, red_front.image).max_abs, 1);
}

TEST(Wboit, LayersOfOneColourAreExact) {
  const glm::vec3 grey(0.6f, 0.5f, 0.4f);
  WorldGeometry g = stackedQuads({{grey, 0.7f, 0.5f}, {grey, 0.2f, 0.0f}, {grey, 0.45f, -0.7f}});
  // A second colour where only it covers a pixel: one layer is exact too.
  addQuad(g, 0.6f, 0.6f, 0.9f, 0.9f, 0.2f, addMaterial(g, {0.1f, 0.7f, 0.9f}, 0.4f));
  const FrameSettings s = orthoTopDown(kStackSize);
  const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  const RenderResult r = renderWboit(g, s);
  EXPECT_LE(compareImages(r.image, ref.image).max_abs, 1);
  expectImagesMatch(r.image, ref.image, "wboit-one-colour", 1.0);
}

// On real meshes the average colour is not the sorted composite: the error against the exact
// reference is bounded, not zero (measured on these views: PSNR 34-44 dB, mean error
// 0.4-1.4/255; the bound leaves room for other devices' rounding). The fragments are those every
// exact method counts, and the two tile forms agree.
TEST(Wboit, RealMeshesWithinABoundedErrorOfEmbree) {
  for (const std::string& scene :
       {modelPath("horse.ply"), modelPath("stanford-bunny.obj"), std::string("builtin:spheres:16"),
        std::string("builtin:textured:4")}) {
    SCOPED_TRACE(scene);
    const Scene sc = loadScene(scene);
    const WorldGeometry g = WorldGeometry::fromScene(sc);
    const FrameSettings s = settingsFor(sc, 192, 30.0f, 20.0f);
    const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
    const RenderResult ppll = makeRenderer(Method::Ppll)->render(g, s);
    const RenderResult serial = renderWboit(g, s, "serial");
    const RenderResult group = renderWboit(g, s, "group");
    const ImageDiff d = compareImages(serial.image, ref.image);
    EXPECT_GE(d.psnr, 28.0) << "mean " << d.mean_abs << "/255, max " << d.max_abs << "/255";
    EXPECT_LE(d.mean_abs, 4.0);
    EXPECT_LT(d.within_2, 0.9999) << "wboit should not be exact on a real mesh";
    EXPECT_EQ(serial.stats.fragments, ppll.stats.fragments);
    EXPECT_EQ(serial.stats.max_depth_complexity, ppll.stats.max_depth_complexity);
    EXPECT_LE(compareImages(group.image, serial.image).max_abs, 1);
  }
}

}  // namespace
}  // namespace strata
