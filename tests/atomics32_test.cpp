// The path without 64-bit atomics (DeviceOptions::atomics "32"): every OpenCL method gives the
// same image to the bit, the same fragments, losses and deepest pixel as with 64-bit atomics in
// the work-group form of its tile kernels, on a mesh, a textured, an instanced and a deep scene,
// and the exact methods stay within 2/255 of Embree; the work-group form is refused there.
#include "engine/frontend/texture_shading.h"
#include "test_support.h"

namespace strata {
namespace {

const DeviceOptions k64{"", "64"};
const DeviceOptions k32{"", "32"};

struct AtomicsCase {
  std::string scene, texture, label;
};

TEST(Atomics32, EveryMethodMatchesThe64BitPath) {
  const std::vector<AtomicsCase> cases = {
      {test::modelPath("horse.ply"), "", "horse"},
      {test::modelPath("spot.obj"), test::modelPath("spot_texture.png"), "spot-textured"},
      {"builtin:crowd:4", "", "crowd-instanced"},
      {"builtin:spheres:16", "", "spheres16"},
  };
  for (const AtomicsCase& c : cases) {
    Scene scene = loadScene(c.scene);
    if (!c.texture.empty()) applyTexture(scene, c.texture);
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    FrameSettings s = test::settingsFor(scene, 96, 35.0f, 20.0f);
    s.height = 80;  // not a whole number of tiles
    s.k = 32;
    const Image reference = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s).image;
    for (const MethodTraits& t : methodRegistry()) {
      if (!t.opencl) continue;
      SCOPED_TRACE(std::string(t.name) + " " + c.label);
      const RenderResult narrow = makeRenderer(t.method, k32)->render(g, s);
      EXPECT_EQ(narrow.stats.tile_kernels, "serial");
      // The same (serial) form with 64-bit atomics: the same image to the bit.
      FrameSettings serial = s;
      serial.tile_kernels = "serial";
      const RenderResult same_form = makeRenderer(t.method, k64)->render(g, serial);
      EXPECT_EQ(compareImages(narrow.image, same_form.image).max_abs, 0);
      test::expectImagesMatch(narrow.image, same_form.image,
                              std::string("atomics32-") + t.name + "-" + c.label, 1.0);
      EXPECT_EQ(narrow.stats.fragments, same_form.stats.fragments);
      // The work-group form, the path a GPU with 64-bit atomics runs: the same counts, and the
      // same image but for the cells composite, whose two forms can differ at single pixels
      // (one pixel of spheres:16 here, by 18/255; tracked in docs/results/devices.md).
      FrameSettings group = s;
      group.tile_kernels = "group";
      const RenderResult wide = makeRenderer(t.method, k64)->render(g, group);
      if (t.method == Method::Cells)
        test::expectImagesMatch(narrow.image, wide.image,
                                std::string("atomics32-group-") + t.name + "-" + c.label, 0.999);
      else
        test::expectImagesMatch(narrow.image, wide.image,
                                std::string("atomics32-group-") + t.name + "-" + c.label, 1.0);
      EXPECT_GT(narrow.stats.fragments, 0u);
      EXPECT_EQ(narrow.stats.fragments, wide.stats.fragments);
      EXPECT_EQ(narrow.stats.fragments_lost, wide.stats.fragments_lost);
      EXPECT_EQ(narrow.stats.max_depth_complexity, wide.stats.max_depth_complexity);
      if (t.exact && t.method != Method::Opaque && narrow.stats.fragments_lost == 0)
        test::expectImagesMatch(narrow.image, reference,
                                std::string("atomics32-embree-") + t.name + "-" + c.label);
    }
  }
}

TEST(Atomics32, RefusesTheWorkGroupForm) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:demo");
  FrameSettings s = test::settingsFor(scene, 32, 0.0f, 0.0f);
  s.tile_kernels = "group";
  try {
    makeRenderer(Method::Ppll, k32)->render(g, s);
    ADD_FAILURE() << "the work-group form ran without 64-bit atomics";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("need 64-bit atomics"), std::string::npos) << e.what();
  }
  EXPECT_THROW(makeRenderer(Method::Ppll, DeviceOptions{"", "16"}), Error);
}

}  // namespace
}  // namespace strata
