// stochastic, stochastic transparency (Enderton, Sintorn, Shirley and Luebke 2010), an
// approximate method: without the alpha correction its expectation is the exact image (the
// mean over many pixels and seeds of stacked quads), its error against the Embree reference
// falls roughly as 1 / sqrt(S), a seed gives one image in both tile kernel forms and another
// seed another, and its options are checked.
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

FrameSettings withStochastic(FrameSettings s, uint32_t samples, uint32_t seed, bool correction,
                             const std::string& form = "auto") {
  s.stochastic.samples = samples;
  s.stochastic.seed = seed;
  s.stochastic.alpha_correction = correction;
  s.tile_kernels = form;
  return s;
}

RenderResult renderStochastic(const WorldGeometry& g, const FrameSettings& s) {
  return makeRenderer(Method::Stochastic)->render(g, s);
}

// Every pixel inside the quads is an independent estimate (its masks hash the pixel): their
// mean over a few seeds is the estimator's expectation, within rounding to 8 bits.
TEST(Stochastic, WithoutAlphaCorrectionTheExpectationIsTheExactImage) {
  const std::vector<StackedLayer> layers = fourStackedLayers();
  const FrameSettings base = orthoTopDown(kStackSize);
  const glm::dvec3 exact = exactStackBlend(layers, base);
  for (uint32_t samples : {4u, 16u}) {
    SCOPED_TRACE("samples " + std::to_string(samples));
    glm::dvec3 sum(0.0);
    double worst = 0.0;
    int n = 0;
    for (uint32_t seed = 0; seed < 8; ++seed) {
      const RenderResult r =
          renderStochastic(stackedQuads(layers), withStochastic(base, samples, seed, false));
      for (int y = 20; y < 45; ++y)
        for (int x = 20; x < 45; ++x) {
          const uint8_t* px = r.image.pixel(x, y);
          const glm::dvec3 c(px[0] / 255.0, px[1] / 255.0, px[2] / 255.0);
          sum += c;
          worst = std::max(worst, glm::length(c - exact));
          ++n;
        }
    }
    const glm::dvec3 mean = sum / double(n);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c] * 255.0, exact[c] * 255.0, 1.5) << c;
    EXPECT_GT(worst * 255.0, 10.0);  // each pixel alone is a noisy estimate
  }
}

TEST(Stochastic, ASeedGivesOneImageInEitherTileFormAndAnotherSeedAnother) {
  const auto [sc, g] = sceneAndGeometry("builtin:spheres:16");
  const FrameSettings s = settingsFor(sc, 96, 30.0f, 20.0f);
  const RenderResult serial = renderStochastic(g, withStochastic(s, 8, 7, true, "serial"));
  const RenderResult group = renderStochastic(g, withStochastic(s, 8, 7, true, "group"));
  EXPECT_EQ(serial.image.rgba, group.image.rgba) << "the tile forms differ";
  EXPECT_EQ(serial.image.rgba,
            renderStochastic(g, withStochastic(s, 8, 7, true, "serial")).image.rgba);
  EXPECT_NE(serial.image.rgba,
            renderStochastic(g, withStochastic(s, 8, 8, true, "serial")).image.rgba);
  EXPECT_EQ(serial.stats.fragment_bytes, 0u);
  EXPECT_EQ(serial.stats.fragments_lost, 0u);
  EXPECT_EQ(serial.stats.fragments, makeRenderer(Method::Ppll)->render(g, s).stats.fragments);
}

TEST(Stochastic, SamplesOutsideTheirRangeAreRefused) {
  const WorldGeometry g = stackedQuads({{{0.5f, 0.5f, 0.5f}, 0.5f, 0.0f}});
  const FrameSettings s = orthoTopDown(kStackSize);
  expectErrorContaining([&] { renderStochastic(g, withStochastic(s, 0, 0, true)); },
                        "stochastic: samples = 0 must be between 1 and 64");
  expectErrorContaining(
      [&] { renderStochastic(g, withStochastic(s, ST_STOCHASTIC_MAX_SAMPLES + 1, 0, true)); },
      "between 1 and");
}

// The error against the reference falls as 1 / sqrt(S): about 2x per 4x samples (measured at
// 256 x 256 on spheres:16, RMSE 1.71, 0.92, 0.52 / 255 at S = 4, 16, 64).
TEST(Stochastic, ErrorFallsRoughlyAsOneOverTheRootOfTheSamples) {
  forEachSceneWithReference(
      {"builtin:spheres:16", "builtin:textured:4"}, 192,
      [](const WorldGeometry& g, const FrameSettings& s, const RenderResult& ref, bool) {
        std::vector<double> rmse;
        for (uint32_t samples : {4u, 16u, 64u}) {
          const ImageDiff d = compareImages(
              renderStochastic(g, withStochastic(s, samples, 1, true)).image, ref.image);
          rmse.push_back(d.rmse);
        }
        EXPECT_GT(rmse[0], rmse[1] * 1.4);
        EXPECT_GT(rmse[1], rmse[2] * 1.3);
        EXPECT_GT(rmse[0] / rmse[2], 2.5);
        EXPECT_LT(rmse[0] / rmse[2], 6.0);
        EXPECT_LT(rmse[2], 2.0);
      });
}

}  // namespace
}  // namespace strata
