// What every method of the registry must do, exact or approximate: a single layer (no pixel
// covered twice) is the exact image, in both tile kernel forms, with its fragments all counted.
#include <string>

#include "engine/reference/embree_reference.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

TEST(EveryMethod, ASingleLayerIsExactInEitherTileForm) {
  // Two quads of different colour and opacity that do not overlap, at different depths.
  WorldGeometry g = stackedQuads({{{0.9f, 0.3f, 0.2f}, 0.6f, 0.0f}});
  addQuad(g, 0.6f, 0.6f, 0.9f, 0.9f, 0.3f, addMaterial(g, {0.2f, 0.5f, 0.9f}, 0.35f));
  FrameSettings s = orthoTopDown(kStackSize);
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/every-method-cache";
  const RenderResult transparent = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  const RenderResult opaque = makeEmbreeRenderer(EmbreeMode::Opaque)->render(g, s);
  int methods = 0;
  for (const std::string& name : methodNames()) {
    const Method method = parseMethod(name);
    if (method == Method::Embree) continue;
    ++methods;
    const RenderResult& ref = method == Method::Opaque ? opaque : transparent;
    for (const char* form : {"group", "serial"}) {
      SCOPED_TRACE(name + " " + form);
      s.tile_kernels = form;
      const RenderResult r = makeRenderer(method)->render(g, s);
      EXPECT_LE(compareImages(r.image, ref.image).max_abs, 1);
      EXPECT_EQ(r.stats.fragments, ref.stats.fragments);
      EXPECT_EQ(r.stats.max_depth_complexity, 1u);
      EXPECT_EQ(r.stats.fragments_lost, 0u);
    }
  }
  EXPECT_GE(methods, 14);
}

}  // namespace
}  // namespace strata
