// What the layered approximate methods (mlab, hybrid: each pixel's k nearest fragments kept in
// the tile's local memory, the rest approximated) must show on real meshes, shared by their
// tests.
#pragma once

#include <string>
#include <utility>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "test_support.h"

namespace strata::test {

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
