// What the layered approximate methods (mlab, hybrid: each pixel's k nearest fragments kept in
// the tile's local memory, the rest approximated) must show on real meshes, shared by their
// tests.
#pragma once

#include <algorithm>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata::test {

// Four layers of distinct colours, opacities and depths: the stacked-quad tests' stack
// (test_geometry.h).
inline std::vector<StackedLayer> fourStackedLayers() {
  return {{{0.9f, 0.2f, 0.1f}, 0.6f, 0.5f},
          {{0.1f, 0.3f, 0.9f}, 0.3f, 0.0f},
          {{0.2f, 0.8f, 0.3f}, 0.5f, -0.5f},
          {{0.8f, 0.7f, 0.2f}, 0.4f, -1.0f}};
}

// Calls fn(drawn, order) for every drawing order of `layers` (order 0, 1, ...); returns how many
// there were.
template <typename Fn>
int forEveryDrawingOrder(std::vector<StackedLayer> layers, Fn fn) {
  auto nearer = [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; };
  std::sort(layers.begin(), layers.end(), nearer);
  int orders = 0;
  do {
    fn(static_cast<const std::vector<StackedLayer>&>(layers), orders++);
  } while (std::next_permutation(layers.begin(), layers.end(), nearer));
  return orders;
}

// The diffuse shading of a layer under the top-down view.
inline double stackShade(const FrameSettings& s) {
  return st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
}

// The layers composited front to back over the background: the exact blend.
inline glm::dvec3 exactStackBlend(std::vector<StackedLayer> layers, const FrameSettings& s) {
  std::sort(layers.begin(), layers.end(),
            [](const StackedLayer& a, const StackedLayer& b) { return a.z > b.z; });
  glm::dvec3 colour(0.0);
  double t = 1.0;
  for (const StackedLayer& l : layers) {
    colour += t * double(l.alpha) * glm::dvec3(l.color) * stackShade(s);
    t *= 1.0 - l.alpha;
  }
  return colour + t * glm::dvec3(s.background.color);
}

// `front` composited front to back in the order given, behind it `tail` blended by Bavoil and
// Myers' weighted average (its opacity-weighted mean colour C and mean opacity a over its n
// layers, as C (1 - (1 - a)^n)), then the background: hybrid's resolve and the tail-blended
// A-buffer's.
inline glm::dvec3 frontThenTail(const std::vector<StackedLayer>& front,
                                const std::vector<StackedLayer>& tail, const FrameSettings& s) {
  glm::dvec3 colour(0.0), tail_sum(0.0);
  double t = 1.0, tail_alpha = 0.0;
  for (const StackedLayer& l : front) {
    colour += t * double(l.alpha) * glm::dvec3(l.color) * stackShade(s);
    t *= 1.0 - l.alpha;
  }
  for (const StackedLayer& l : tail) {
    tail_sum += double(l.alpha) * glm::dvec3(l.color) * stackShade(s);
    tail_alpha += l.alpha;
  }
  if (!tail.empty()) {
    const double n = double(tail.size()), tail_t = std::pow(1.0 - tail_alpha / n, n);
    colour += t * (1.0 - tail_t) * tail_sum / tail_alpha;
    t *= tail_t;
  }
  return colour + t * glm::dvec3(s.background.color);
}

// The stack's rendered pixel within 1 of `expected` (0..1 per channel) and a pixel outside the
// quads the background; every layer counted at the pixel, none lost.
inline void expectStackPixel(const RenderResult& r, const glm::dvec3& expected,
                             const FrameSettings& s, size_t layers) {
  const uint8_t* px = r.image.pixel(kInsideX, kInsideY);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(int(px[c]), int(unorm8(expected[c])), 1) << "channel " << c;
  EXPECT_EQ(r.image.pixel(2, 2)[0], unorm8(s.background.color[0]));  // outside the quads
  EXPECT_EQ(r.stats.max_depth_complexity, layers);
  EXPECT_EQ(r.stats.fragments_lost, 0u);
}

// For each scene (a file of tests/models, or a builtin: spec) seen from (30, 20) at size x size:
// fn(geometry, settings, the Embree reference, whether it is a model file).
template <typename Fn>
void forEachSceneWithReference(std::initializer_list<const char*> scenes, int size, Fn fn) {
  for (const char* scene : scenes) {
    SCOPED_TRACE(scene);
    const bool model = std::string(scene).rfind("builtin:", 0) != 0;
    const auto [sc, g] = sceneAndGeometry(model ? modelPath(scene) : scene);
    const FrameSettings s = settingsFor(sc, size, 30.0f, 20.0f);
    fn(g, s, makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s), model);
  }
}

// `method` at k, in the tile kernel form `form`.
inline RenderResult renderLayered(Method method, const WorldGeometry& g, FrameSettings s, int k,
                                  const std::string& form = "auto") {
  s.k = k;
  s.tile_kernels = form;
  return makeRenderer(method)->render(g, s);
}

// On horse, spheres:16 and textured:4 at 192 x 192: while k covers every pixel's fragments
// nothing is approximated and the image equals Embree's (and counts ppll's fragments); below
// that the error is bounded (PSNR >= min_psnr) and shrinks as k grows; in both cases the two
// tile forms agree bit for bit, since each pixel takes its fragments in drawing order in both.
inline void expectExactAtDepthAndCloserAsKGrows(Method method, const std::string& name,
                                                double min_psnr) {
  const std::pair<std::string, const char*> scenes[] = {{modelPath("horse.ply"), "horse"},
                                                        {"builtin:spheres:16", "spheres"},
                                                        {"builtin:textured:4", "textured"}};
  for (const auto& [scene, label] : scenes) {
    SCOPED_TRACE(scene);
    const auto [sc, g] = sceneAndGeometry(scene);
    const FrameSettings s = settingsFor(sc, 192, 30.0f, 20.0f);
    const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
    const RenderResult ppll = makeRenderer(Method::Ppll)->render(g, s);
    const int depth = int(ppll.stats.max_depth_complexity);
    ASSERT_LE(depth, ST_MAX_K);
    const RenderResult serial = renderLayered(method, g, s, depth, "serial");
    const RenderResult group = renderLayered(method, g, s, depth, "group");
    EXPECT_EQ(serial.image.rgba, group.image.rgba) << "the tile forms differ";
    EXPECT_EQ(serial.stats.fragments, ppll.stats.fragments);
    EXPECT_EQ(serial.stats.fragments_lost, 0u);
    expectImagesMatch(serial.image, ref.image, name + "-exact-" + label);
    double previous = 1e9;
    for (int k : {1, 4, 16}) {
      const RenderResult approx = renderLayered(method, g, s, k, "serial");
      EXPECT_EQ(approx.image.rgba, renderLayered(method, g, s, k, "group").image.rgba)
          << "k " << k << ": the tile forms differ";
      const ImageDiff d = compareImages(approx.image, ref.image);
      EXPECT_GE(d.psnr, min_psnr) << "k " << k << ": mean " << d.mean_abs << "/255";
      EXPECT_LE(d.mean_abs, previous + 0.05) << "k " << k;
      previous = d.mean_abs;
    }
  }
}

}  // namespace strata::test
