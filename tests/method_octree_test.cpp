// The octree method (`octree`): the claim rule (every ray parameter in exactly one leaf, tested
// at the planes' own values and one ulp either side), then images and fragment counts against
// the Embree reference on shared models and the massive built-ins from outside, inside and
// orthographic views, every variant, translucency, and bad settings.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <set>
#include <vector>

#include <glm/glm.hpp>

#include "engine/octree/octree_leaves.h"
#include "engine/reference/embree_reference.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/mesh_loader.h"
#include "preprocess/octree_scene.h"
#include "test_support.h"

namespace strata {
namespace {

std::string cacheDir() { return std::string(STRATA_TEST_OUTPUT_DIR) + "/octree-cache"; }

// A view of `scene` for the octree: the tests' cache folder and `leaf_triangles` per leaf.
FrameSettings octreeSettings(const Scene& scene, int size, float az, float el,
                             uint32_t leaf_triangles) {
  FrameSettings s = test::settingsFor(scene, size, az, el);
  s.cell_cache_dir = cacheDir();
  s.octree.leaf_triangles = leaf_triangles;
  return s;
}

MeshView meshOf(const WorldGeometry& g) {
  return {g.positions.data(), g.positions.size(), g.indices.data(), g.triangleCount()};
}

// How many leaves claim ray parameter t.
int claimsOf(const std::vector<LeafPlanes>& leaves, const float o[3], const float d[3],
             const float inv[3], float t) {
  int n = 0;
  for (const LeafPlanes& l : leaves) {
    float a, b;
    st_octree_leaf_interval(l.box.lo, l.box.hi, o, d, inv, &a, &b);
    n += st_octree_claims(a, b, t);
  }
  return n;
}

// Every parameter along a ray belongs to exactly one leaf: at every leaf's interval ends (the
// values the rule compares with), one ulp either side of them, and in between. A rule off by
// one ulp either way (a closed end, or an end moved by an ulp) claims a plane's value twice or
// never. The tree is adaptive (leaves of several levels share faces) and the rays include ones
// parallel to axes, from inside and outside the root.
TEST(OctreeClaimRule, EveryRayParameterIsInExactlyOneLeaf) {
  const WorldGeometry g = WorldGeometry::fromScene(loadScene(test::modelPath("horse.ply")));
  OctreeOptions options;
  options.leaf_triangles = 600;
  const Octree tree = buildOctree(meshOf(g), options);
  const std::vector<LeafPlanes> leaves = octreeLeafPlanes(tree, true);
  ASSERT_GT(leaves.size(), 50u);
  std::set<uint32_t> levels;
  for (const LeafPlanes& l : leaves) levels.insert(tree.nodes[l.node].level);
  ASSERT_GT(levels.size(), 1u) << "the tree should have leaves on several levels";

  const OctreeNode& root = tree.nodes[tree.root()];
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  int rays = 0, checked = 0;
  for (int r = 0; r < 60; ++r) {
    const glm::vec3 c = root.center();
    const float spread = r % 2 ? 0.4f : 1.5f;  // inside the root, or around it
    float o[3], d[3], inv[3];
    for (int a = 0; a < 3; ++a) {
      o[a] = c[a] + spread * root.size * u(rng);
      d[a] = u(rng);
    }
    if (r % 5 == 0) d[r % 3] = 0.0f;                   // parallel to a plane
    if (r % 7 == 0) d[(r + 1) % 3] = d[r % 3] = 0.0f;  // along an axis
    if (d[0] == 0.0f && d[1] == 0.0f && d[2] == 0.0f) d[2] = 1.0f;
    for (int a = 0; a < 3; ++a) inv[a] = 1.0f / d[a];
    std::vector<float> ts;
    for (const LeafPlanes& l : leaves) {
      float a, b;
      st_octree_leaf_interval(l.box.lo, l.box.hi, o, d, inv, &a, &b);
      for (float t : {a, b}) {
        if (!std::isfinite(t)) continue;
        ts.push_back(t);
        ts.push_back(std::nextafter(t, INFINITY));
        ts.push_back(std::nextafter(t, -INFINITY));
      }
    }
    for (int k = 0; k < 50; ++k) ts.push_back(4.0f * root.size * u(rng));
    for (float t : ts) {
      const int n = claimsOf(leaves, o, d, inv, t);
      ++checked;
      if (n != 1) {
        ADD_FAILURE() << "ray " << r << " parameter " << t << " is claimed by " << n << " leaves";
        return;
      }
    }
    ++rays;
  }
  EXPECT_EQ(rays, 60);
  EXPECT_GT(checked, 10000);
}

// Outside views all round, one from inside the scene's bounds and an orthographic one.
std::vector<FrameSettings> views(const Scene& scene, int size) {
  std::vector<FrameSettings> out;
  for (const auto& v : {std::pair{30.0f, 20.0f}, {160.0f, -35.0f}, {275.0f, 60.0f}})
    out.push_back(test::settingsFor(scene, size, v.first, v.second));
  const BoundingSphere sphere = scene.boundingSphere();
  FrameSettings inside = out[0];
  inside.camera = Camera::lookAt(sphere.center + glm::vec3(0.05f, 0.02f, 0.1f) * sphere.radius,
                                 sphere.center + glm::vec3(1.0f, -0.3f, 0.2f) * sphere.radius);
  inside.camera.near_distance = 1e-3f * sphere.radius;
  out.push_back(inside);
  FrameSettings ortho = out[1];
  ortho.camera = Camera::orbit(sphere, OrbitView{70.0f, 25.0f, std::nullopt, std::nullopt},
                               Projection::Orthographic);
  out.push_back(ortho);
  return out;
}

struct OctreeCase {
  std::string scene, label;
  uint32_t leaf_tris;
};
void PrintTo(const OctreeCase& c, std::ostream* os) { *os << c.label; }

class OctreeImages : public test::SceneImageTest<OctreeCase> {};

// Images within 2/255 of Embree on 99.5% of pixels, and the fragment count within 0.5% of
// Embree's hits and equal to the linked lists' (the same raster: no fragment dropped or counted
// twice where leaves share triangles).
TEST_P(OctreeImages, MatchEmbreeAndCountEveryFragmentOnce) {
  const OctreeCase& c = GetParam();
  auto octree = makeRenderer(Method::Octree);
  auto ppll = makeRenderer(Method::Ppll);
  int n = 0;
  for (FrameSettings s : views(scene, 256)) {
    s.cell_cache_dir = cacheDir();
    s.octree.leaf_triangles = c.leaf_tris;
    SCOPED_TRACE(c.label + " view " + std::to_string(n));
    const RenderResult ref = embree->render(g, s);
    const RenderResult a = octree->render(g, s);
    const RenderResult lists = ppll->render(g, s);
    EXPECT_GT(a.stats.octree_leaves, 1u);
    EXPECT_EQ(a.stats.fragments, lists.stats.fragments);
    EXPECT_EQ(a.stats.max_depth_complexity, lists.stats.max_depth_complexity);
    EXPECT_NEAR(double(a.stats.fragments), double(ref.stats.fragments),
                0.005 * double(ref.stats.fragments) + 2.0);
    test::expectImagesMatch(a.image, ref.image, "octree-" + c.label + "-" + std::to_string(n));
    ++n;
  }
}

INSTANTIATE_TEST_SUITE_P(
    SharedAndMassive, OctreeImages,
    ::testing::Values(OctreeCase{test::modelPath("horse.ply"), "horse", 2000},
                      OctreeCase{test::modelPath("stanford-bunny.obj"), "bunny", 1000},
                      OctreeCase{test::modelPath("teapot.obj"), "teapot", 64},
                      OctreeCase{test::modelPath("spot.obj"), "spot", 500},
                      OctreeCase{test::modelPath("fandisk.obj"), "fandisk", 300},
                      OctreeCase{"builtin:demo", "demo", 200},
                      OctreeCase{"builtin:hairball:60", "hairball", 4000},
                      OctreeCase{"builtin:city:6", "city", 2000},
                      OctreeCase{"builtin:shells:3", "shells", 6000},
                      OctreeCase{"builtin:soup:20000", "soup", 1500}),
    [](const ::testing::TestParamInfo<OctreeCase>& i) { return i.param.label; });

// Every variant renders the same fragments and the same image; per-leaf resolves read fewer
// triangles than depth peeling, and the whole-scene variants read as many as it does.
TEST(OctreeVariants, AllAgreeAndBlocksReadLessThanDepthPeeling) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:shells:3");
  FrameSettings s = octreeSettings(scene, 192, 40.0f, 25.0f, 3000);
  const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  auto octree = makeRenderer(Method::Octree);
  for (const char* v : {"kbuffer", "blocks-histogram", "blocks", "histogram", "dp"}) {
    SCOPED_TRACE(v);
    s.octree.variant = v;
    for (uint32_t k : {1u, 3u, 16u}) {
      if (k != 16 && std::string(v) != "kbuffer") continue;
      s.octree.k = k;
      const RenderResult a = octree->render(g, s);
      EXPECT_EQ(a.stats.octree_variant, v);
      EXPECT_NEAR(double(a.stats.fragments), double(ref.stats.fragments),
                  0.005 * double(ref.stats.fragments));
      test::expectImagesMatch(a.image, ref.image, std::string("octree-variant-") + v);
      const bool whole = std::string(v) == "histogram" || std::string(v) == "dp";
      if (whole) {
        EXPECT_EQ(a.stats.octree_leaves, 1u);
        EXPECT_EQ(a.stats.triangles_read, a.stats.dp_triangles_read);
      } else {
        EXPECT_GT(a.stats.octree_leaves, 1u);
        EXPECT_LT(a.stats.triangles_read, a.stats.dp_triangles_read);
      }
    }
  }
}

TEST(OctreeTranslucency, MatchesEmbree) {
  for (const char* name : {"builtin:shells:3", "horse"}) {
    const std::string path = std::string(name) == "horse" ? test::modelPath("horse.ply") : name;
    const auto [scene, g] = test::sceneAndGeometry(path);
    FrameSettings s = test::settingsFor(scene, 256, 120.0f, 15.0f);
    s.effect = Effect::Translucency;
    s.sigma = 1.0f / scene.boundingSphere().radius;
    s.cell_cache_dir = cacheDir();
    s.octree.leaf_triangles = 2500;
    const RenderResult ref = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
    const RenderResult a = makeRenderer(Method::Octree)->render(g, s);
    EXPECT_GT(a.stats.octree_leaves, 1u);
    test::expectImagesMatch(a.image, ref.image, std::string("octree-translucency-") + name);
  }
}

TEST(OctreeSettings, DefaultFaceLimitIsTheOctreeBuildsDefault) {
  EXPECT_EQ(OctreeMethodOptions{}.leaf_triangles, kDefaultLeafTriangles);
}

TEST(OctreeSettings, BadOnesAreRefusedWithAClearMessage) {
  const WorldGeometry g = WorldGeometry::fromScene(loadScene("builtin:demo"));
  auto octree = makeRenderer(Method::Octree);
  auto expectError = [&](FrameSettings s, const std::string& fragment) {
    s.width = s.height = 32;
    s.cell_cache_dir = cacheDir();
    try {
      octree->render(g, s);
      ADD_FAILURE() << "rendered although it should fail with '" << fragment << "'";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  FrameSettings s;
  s.octree.leaf_triangles = 0;
  expectError(s, "face limit");
  s = FrameSettings{};
  s.octree.variant = "fastest";
  expectError(s, "unknown variant 'fastest'");
  s = FrameSettings{};
  s.octree.k = 0;
  expectError(s, "between 1 and 64");
  s.octree.k = 65;
  expectError(s, "between 1 and 64");
  s = FrameSettings{};
  s.octree.batch_triangles = 0;
  expectError(s, "batch size");
}

// The early out stops at pixels that let less than 0.5/255 through: the image stays within
// 1/255 of the full resolve (and within 2/255 of Embree), with fewer fragments composited.
TEST(OctreeEarlyOut, DeepScenesStayWithinOneStepWithFewerFragments) {
  for (const char* name : {"builtin:soup:20000", "builtin:hairball:60"}) {
    SCOPED_TRACE(name);
    const Scene scene = loadScene(name);
    const WorldGeometry g = WorldGeometry::fromScene(scene, 0.5f);
    FrameSettings s = octreeSettings(scene, 192, 50.0f, 20.0f, 2000);
    auto octree = makeRenderer(Method::Octree);
    const RenderResult full = octree->render(g, s);
    s.octree.early_out = true;
    const RenderResult early = octree->render(g, s);
    EXPECT_TRUE(early.stats.octree_early_out);
    EXPECT_LT(early.stats.fragments, full.stats.fragments);
    EXPECT_LE(compareImages(early.image, full.image).max_abs, 1);
    test::expectMatchesEmbree(early.image, g, s, std::string("octree-early-") + name);
  }
}

// Batches: a frame cut into many small batches renders what one batch renders.
TEST(OctreeBatches, SmallBatchesRenderTheSameImage) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:city:6");
  FrameSettings s = octreeSettings(scene, 192, 200.0f, 30.0f, 1500);
  auto octree = makeRenderer(Method::Octree);
  const RenderResult one = octree->render(g, s);
  s.octree.batch_triangles = 4000;
  const RenderResult many = octree->render(g, s);
  EXPECT_EQ(one.stats.batches, 1u);
  EXPECT_GT(many.stats.batches, 5u);
  EXPECT_EQ(one.stats.fragments, many.stats.fragments);
  test::expectImagesMatch(many.image, one.image, "octree-batches", 0.999);
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

uint64_t geometryBytes(const WorldGeometry& g) {
  return g.positions.size() * sizeof(glm::vec3) + g.triangleCount() * 16;
}

// Under a memory budget several times smaller than the scene's triangles, the frame streams
// them per batch, every device buffer together stays within the budget, and the image is the
// unbounded one (within the 16-bit accumulator's rounding between batches) and Embree's.
TEST(OctreeMemoryBudget, SceneSeveralTimesTheBudgetRendersExactlyWithinIt) {
  for (const char* name : {"builtin:city:12", "builtin:textured:6"}) {
    SCOPED_TRACE(name);
    const auto [scene, g] = test::sceneAndGeometry(name);
    FrameSettings s = octreeSettings(scene, 160, 35.0f, 30.0f, 2000);
    auto octree = makeRenderer(Method::Octree);
    const RenderResult free = octree->render(g, s);
    EXPECT_FALSE(free.stats.streamed);
    // The textured scene has few triangles: its budget is its image and atlas, and it streams
    // because it is told to.
    const bool textured = std::string(name) == "builtin:textured:6";
    const uint64_t budget = textured ? free.stats.peak_device_bytes : geometryBytes(g) / 3;
    s.memory_budget = budget;
    s.octree.stream = textured;
    if (textured) s.octree.batch_triangles = 1500;
    const RenderResult bounded = octree->render(g, s);
    EXPECT_TRUE(bounded.stats.streamed) << "geometry " << geometryBytes(g) << " budget " << budget;
    EXPECT_LE(bounded.stats.peak_device_bytes, budget);
    EXPECT_GT(bounded.stats.streamed_bytes, 0u);
    EXPECT_GT(bounded.stats.batches, 1u);
    EXPECT_EQ(bounded.stats.fragments, free.stats.fragments);
    const ImageDiff d = compareImages(bounded.image, free.image);
    EXPECT_LE(d.max_abs, 1);
    test::expectMatchesEmbree(bounded.image, g, s, std::string("octree-budget-") + name);
  }
}

// A budget between the resident scene and nothing: the triangles stay on the device and the
// batches shrink to fit.
TEST(OctreeMemoryBudget, ResidentSceneWithSmallerBatchesStaysWithinIt) {
  const auto [scene, g] = test::sceneAndGeometry("builtin:city:12");
  FrameSettings s = octreeSettings(scene, 160, 35.0f, 30.0f, 2000);
  auto octree = makeRenderer(Method::Octree);
  const RenderResult free = octree->render(g, s);
  const uint64_t budget = geometryBytes(g) * 2;
  ASSERT_LT(budget, free.stats.peak_device_bytes);
  s.memory_budget = budget;
  const RenderResult bounded = octree->render(g, s);
  EXPECT_FALSE(bounded.stats.streamed);
  EXPECT_LE(bounded.stats.peak_device_bytes, budget);
  EXPECT_GT(bounded.stats.batches, free.stats.batches);
  EXPECT_EQ(bounded.stats.fragments, free.stats.fragments);
  EXPECT_LE(compareImages(bounded.image, free.image).max_abs, 1);
}

// The other OpenCL methods do not stream: over the budget they fail with what they needed.
TEST(OctreeMemoryBudget, OtherMethodsOverTheBudgetAreRefused) {
  const WorldGeometry g = WorldGeometry::fromScene(loadScene("builtin:city:6"));
  FrameSettings s;
  s.width = s.height = 128;
  s.memory_budget = 1u << 20;
  try {
    makeRenderer(Method::Ppll)->render(g, s);
    ADD_FAILURE() << "ppll rendered within 1 MB";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("over the memory budget of 1.0 MB"), std::string::npos)
        << e.what();
  }
  s.memory_budget = 1u << 30;
  EXPECT_NO_THROW(makeRenderer(Method::Ppll)->render(g, s));
}

// An octree scene written from a scene and loaded back: the file (not the scene) is all the
// renderer has. `leaf_tris` small enough for many leaves and batches.
std::string writeSceneFile(const std::string& spec, const std::string& name, uint32_t leaf_tris,
                           Scene* scene_out = nullptr, WorldGeometry* geometry_out = nullptr) {
  const auto [scene, g] = test::sceneAndGeometry(spec);
  OctreeOptions options;
  options.leaf_triangles = leaf_tris;
  const Octree tree = loadOrBuildOctree(meshOf(g), options, cacheDir());
  const std::string path = std::string(STRATA_TEST_OUTPUT_DIR) + "/" + name + ".octree";
  writeOctreeScene(path, scene, g, tree);
  if (scene_out) *scene_out = scene;
  if (geometry_out) *geometry_out = g;
  return path;
}

// Out of core: the octree method renders an octree scene by reading each batch's leaves from
// the file, and the image and fragments are those of the scene rendered from memory, and
// Embree's; under a budget a third of the triangles' bytes, every device buffer stays within
// it. From outside, inside and orthographic views, transparency and translucency.
TEST(OctreeSceneFile, StreamsFromDiskAsTheSceneRendersFromMemory) {
  Scene scene;
  WorldGeometry g;
  const std::string path = writeSceneFile("builtin:city:12", "city12", 2000, &scene, &g);
  const Scene on_disk = loadScene(path);
  ASSERT_TRUE(on_disk.out_of_core);
  EXPECT_TRUE(on_disk.meshes.empty());
  EXPECT_EQ(on_disk.triangleCount(), scene.triangleCount());
  EXPECT_EQ(on_disk.boundingSphere().center, scene.boundingSphere().center);
  EXPECT_EQ(on_disk.boundingSphere().radius, scene.boundingSphere().radius);
  const WorldGeometry ooc = WorldGeometry::fromScene(on_disk);
  ASSERT_TRUE(ooc.out_of_core);
  EXPECT_EQ(ooc.triangleCount(), 0u);  // nothing of the triangles in host memory
  EXPECT_EQ(ooc.material_colors, g.material_colors);

  auto from_disk = makeRenderer(Method::Octree);
  auto from_memory = makeRenderer(Method::Octree);
  auto embree = makeRenderer(Method::Embree);
  struct View {
    float az, el;
    bool inside, ortho, translucent;
  };
  for (const View v : {View{35, 30, false, false, false}, View{200, 15, true, false, false},
                       View{80, 60, false, true, false}, View{300, 25, false, false, true}}) {
    SCOPED_TRACE(testing::Message()
                 << "view " << v.az << "," << v.el << (v.inside ? " inside" : "")
                 << (v.ortho ? " ortho" : "") << (v.translucent ? " translucent" : ""));
    FrameSettings s = test::settingsFor(scene, 160, v.az, v.el);
    OrbitView orbit;
    orbit.azimuth_deg = v.az;
    orbit.elevation_deg = v.el;
    if (v.inside) orbit.distance_radii = 0.3f;
    s.camera = Camera::orbit(scene.boundingSphere(), orbit,
                             v.ortho ? Projection::Orthographic : Projection::Perspective);
    s.cell_cache_dir = cacheDir();
    s.octree.leaf_triangles = 2000;
    if (v.translucent) {
      s.effect = Effect::Translucency;
      s.sigma = 1.0f / scene.boundingSphere().radius;
    }
    const RenderResult mem = from_memory->render(g, s);
    const RenderResult disk = from_disk->render(ooc, s);
    EXPECT_EQ(disk.stats.stream_source, "disk");
    EXPECT_GT(disk.stats.disk_read_bytes, 0u);
    EXPECT_EQ(disk.stats.triangles, g.triangleCount());
    EXPECT_EQ(disk.stats.octree_leaves, mem.stats.octree_leaves);
    EXPECT_EQ(disk.stats.fragments, mem.stats.fragments);
    EXPECT_LE(compareImages(disk.image, mem.image).max_abs, 1);
    // Translucency of the city's open walls and coplanar faces is checked against memory
    // only; against Embree on the closed shells below.
    if (!v.translucent)
      test::expectImagesMatch(disk.image, embree->render(g, s).image, "octree-scene-file");
    // A budget a third of the triangles' own bytes.
    s.memory_budget = geometryBytes(g) / 3;
    const RenderResult bounded = from_disk->render(ooc, s);
    EXPECT_LE(bounded.stats.peak_device_bytes, s.memory_budget);
    EXPECT_GT(bounded.stats.batches, 1u);
    EXPECT_EQ(bounded.stats.fragments, mem.stats.fragments);
    EXPECT_LE(compareImages(bounded.image, mem.image).max_abs, 1);
  }
  Scene shells;
  WorldGeometry shells_g;
  const WorldGeometry shells_file = WorldGeometry::fromScene(
      loadScene(writeSceneFile("builtin:shells:3", "shells3", 2500, &shells, &shells_g)));
  FrameSettings s = test::settingsFor(shells, 200, 120.0f, 15.0f);
  s.effect = Effect::Translucency;
  s.sigma = 1.0f / shells.boundingSphere().radius;
  s.memory_budget = geometryBytes(shells_g) / 2;
  const RenderResult disk = from_disk->render(shells_file, s);
  EXPECT_EQ(disk.stats.stream_source, "disk");
  test::expectImagesMatch(disk.image, embree->render(shells_g, s).image,
                          "octree-scene-file-translucency");
}

// Every other method reads the octree scene whole: the same triangles, materials and order as
// the scene it was written from, so the same image and fragments; the dp and histogram
// variants (the whole scene as one block) are refused with the reason.
TEST(OctreeSceneFile, OtherMethodsReadItWhole) {
  Scene scene;
  WorldGeometry g;
  const std::string path = writeSceneFile("builtin:soup:20000", "soup", 1500, &scene, &g);
  const WorldGeometry ooc = WorldGeometry::fromScene(loadScene(path));
  const WorldGeometry whole = inCore(ooc);
  ASSERT_EQ(whole.triangleCount(), g.triangleCount());
  for (uint32_t t = 0; t < g.triangleCount(); ++t)
    for (int c = 0; c < 3; ++c)
      ASSERT_EQ(whole.positions[whole.indices[3 * t + c]], g.positions[g.indices[3 * t + c]])
          << "triangle " << t;
  EXPECT_EQ(whole.triangle_material, g.triangle_material);
  FrameSettings s = test::settingsFor(scene, 128, 20.0f, 25.0f);
  s.cell_cache_dir = cacheDir();
  for (Method m : {Method::Ppll, Method::Embree}) {
    SCOPED_TRACE(methodName(m));
    const RenderResult a = makeRenderer(m)->render(ooc, s);
    const RenderResult b = makeRenderer(m)->render(g, s);
    EXPECT_EQ(a.stats.fragments, b.stats.fragments);
    EXPECT_EQ(compareImages(a.image, b.image).max_abs, 0);
  }
  for (const char* variant : {"dp", "histogram"}) {
    s.octree.variant = variant;
    try {
      makeRenderer(Method::Octree)->render(ooc, s);
      ADD_FAILURE() << variant << " rendered an octree scene";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": the " + variant + " variant"),
                std::string::npos)
          << e.what();
    }
  }
}

// A damaged octree scene is refused with one line naming the file: a changed byte in a leaf's
// triangles (found when the leaf is read), in the index or the tail (found on opening), a
// truncated file, the octree cache format, and a file cut short after it was opened.
TEST(OctreeSceneFile, DamagedFilesAreRefusedNamingTheFile) {
  const std::string path = writeSceneFile("builtin:city:6", "damaged-source", 2000);
  const std::string bytes = test::readBytes(path);
  ASSERT_GT(bytes.size(), 10000u);
  const std::string bad = std::string(STRATA_TEST_OUTPUT_DIR) + "/damaged.octree";
  FrameSettings s;
  s.width = s.height = 64;
  const auto renderError = [&]() -> std::string {
    try {
      const WorldGeometry ooc = WorldGeometry::fromScene(loadScene(bad));
      makeRenderer(Method::Octree)->render(ooc, s);
    } catch (const Error& e) {
      return e.what();
    }
    return {};
  };
  struct Damage {
    size_t at;
    const char* expect;
  };
  // The leaves start right after the 24-byte head; the tail's checksum is the last 8 bytes.
  for (const Damage d :
       {Damage{24 + 5, "fail their checksum"}, Damage{bytes.size() / 2, "fail their checksum"},
        Damage{bytes.size() - 100, "checksum mismatch"},
        Damage{bytes.size() - 3, "checksum mismatch"}, Damage{3, "not an octree"}}) {
    SCOPED_TRACE(d.at);
    std::string changed = bytes;
    changed[d.at] = char(changed[d.at] ^ 0x40);
    test::writeBytes(bad, changed);
    test::expectLoadError(bad, renderError(), d.expect);
  }
  test::writeBytes(bad, bytes.substr(0, bytes.size() - 1));
  test::expectLoadError(bad, renderError(), "inconsistent sizes");
  test::writeBytes(bad, bytes.substr(0, 40));
  test::expectLoadError(bad, renderError(), "too short");
  test::writeBytes(bad, "STRATAOCTREE" + std::string(200, '\0'));
  test::expectLoadError(bad, renderError(), "an octree cache file");
  // Cut short after opening: the leaves that are gone cannot be read.
  test::writeBytes(bad, bytes);
  const WorldGeometry ooc = WorldGeometry::fromScene(loadScene(bad));
  std::filesystem::resize_file(bad, 1000);
  std::string cut;
  try {
    makeRenderer(Method::Octree)->render(ooc, s);
  } catch (const Error& e) {
    cut = e.what();
  }
  test::expectLoadError(bad, cut, "cannot read the triangles of leaf");
}

TEST(OctreeMemoryBudget, TooSmallNamesTheSmallestThatWorks) {
  const WorldGeometry g = WorldGeometry::fromScene(loadScene("builtin:city:6"));
  FrameSettings s;
  s.width = s.height = 128;
  s.cell_cache_dir = cacheDir();
  s.memory_budget = 256 * 1024;
  try {
    makeRenderer(Method::Octree)->render(g, s);
    ADD_FAILURE() << "rendered within 256 KB";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("memory budget of 0.2 MB is too small"), std::string::npos) << m;
    EXPECT_NE(m.find("need at least"), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos);
  }
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

// Meshes the method was not written for: every PLY, STL and OBJ of Debian's assimp test models
// that loads (open scans, quads, n-gons, strips, lone triangles), each against Embree with small
// leaves, and every fragment counted once (the linked lists' count).
TEST(OctreeUnseenMeshes, AssimpModelsMatchEmbree) {
  namespace fs = std::filesystem;
  const fs::path root = STRATA_ASSIMP_MODELS_DIR;
  if (!fs::exists(root)) GTEST_SKIP() << "assimp-testmodels not installed";
  std::vector<fs::path> files;
  for (const char* dir : {"PLY", "STL", "OBJ"}) {
    if (!fs::exists(root / dir)) continue;
    for (const auto& e : fs::directory_iterator(root / dir))
      if (e.is_regular_file()) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto octree = makeRenderer(Method::Octree);
  auto ppll = makeRenderer(Method::Ppll);
  int rendered = 0;
  for (const fs::path& f : files) {
    Scene scene;
    try {
      scene = loadScene(f.string());
    } catch (const Error&) {
      continue;  // the loaders' own tests cover what fails to load
    }
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    if (g.triangleCount() == 0 || g.triangleCount() > 300000) continue;
    SCOPED_TRACE(f.string());
    FrameSettings s = octreeSettings(scene, 128, 40.0f, 25.0f,
                                     std::max<uint32_t>(16, uint32_t(g.triangleCount() / 40)));
    const RenderResult ref = embree->render(g, s);
    const RenderResult a = octree->render(g, s);
    EXPECT_EQ(a.stats.fragments, ppll->render(g, s).stats.fragments);
    test::expectImagesMatch(a.image, ref.image, "octree-assimp-" + f.stem().string());
    ++rendered;
  }
  EXPECT_GE(rendered, 10);
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

// A renderer reused on a scene of the same triangles in other colours renders the new colours
// (the scene's key covers its materials, not only its geometry).
TEST(OctreeScenes, SameGeometryInOtherColoursIsNotTakenForTheLastScene) {
  WorldGeometry g = WorldGeometry::fromScene(loadScene(test::modelPath("teapot.obj")));
  FrameSettings s = test::settingsFor(loadScene(test::modelPath("teapot.obj")), 96, 30, 20);
  s.cell_cache_dir = cacheDir();
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (Method m : {Method::Octree, Method::Cells}) {
    SCOPED_TRACE(methodName(m));
    auto r = makeRenderer(m);
    WorldGeometry red = g;
    for (glm::vec4& c : red.material_colors) c = glm::vec4(0.9f, 0.1f, 0.1f, 0.5f);
    WorldGeometry blue = g;
    for (glm::vec4& c : blue.material_colors) c = glm::vec4(0.1f, 0.1f, 0.9f, 0.5f);
    test::expectImagesMatch(r->render(red, s).image, embree->render(red, s).image,
                            "octree-colours-red-" + methodName(m));
    test::expectImagesMatch(r->render(blue, s).image, embree->render(blue, s).image,
                            "octree-colours-blue-" + methodName(m));
  }
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

// Large triangles across a tree made deep in one corner by a cluster of tiny ones: each large
// triangle is referenced by leaves of many sizes, down to tiny ones, and the diagonal views
// run along leaf edges and through leaf corners. Every fragment is still counted once.
TEST(OctreeSharedTriangles, LargeTrianglesAcrossManyTinyLeaves) {
  WorldGeometry g;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  auto add = [&](glm::vec3 a, glm::vec3 b, glm::vec3 c, uint32_t material) {
    const uint32_t v = uint32_t(g.positions.size());
    g.positions.insert(g.positions.end(), {a, b, c});
    g.indices.insert(g.indices.end(), {v, v + 1, v + 2});
    g.triangle_material.push_back(material);
    g.triangle_object.push_back(0);
  };
  for (int i = 0; i < 16; ++i)
    add({u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}, {u(rng), u(rng), u(rng)}, i % 2);
  // Axis-aligned large triangles on the tree's own planes (x = 0, y = 0.5, z = -0.5).
  add({0, -1, -1}, {0, 1, -1}, {0, -1, 1}, 0);
  add({-1, 0.5f, -1}, {1, 0.5f, -1}, {-1, 0.5f, 1}, 1);
  add({-1, -1, -0.5f}, {1, -1, -0.5f}, {-1, 1, -0.5f}, 0);
  for (int i = 0; i < 3000; ++i) {
    const glm::vec3 c(0.9f + 0.1f * u(rng), 0.9f + 0.1f * u(rng), 0.9f + 0.1f * u(rng));
    add(c, c + 0.01f * glm::vec3(u(rng), u(rng), u(rng)),
        c + 0.01f * glm::vec3(u(rng), u(rng), u(rng)), 1);
  }
  g.material_colors = {glm::vec4(0.8f, 0.3f, 0.2f, 0.5f), glm::vec4(0.2f, 0.5f, 0.9f, 0.4f)};

  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  auto octree = makeRenderer(Method::Octree);
  auto ppll = makeRenderer(Method::Ppll);
  std::vector<FrameSettings> views;
  FrameSettings s;
  s.width = s.height = 200;
  s.cell_cache_dir = cacheDir();
  s.octree.leaf_triangles = 40;
  s.camera = Camera::lookAt({2.5f, 1.8f, 3.0f}, {0, 0, 0});
  views.push_back(s);
  s.camera = Camera::lookAt({3.0f, 3.0f, 3.0f}, {0, 0, 0});  // along the cube's diagonal
  s.camera.projection = Projection::Orthographic;
  s.camera.ortho_height = 3.0f;
  views.push_back(s);
  s.camera = Camera::lookAt({0.0f, 0.0f, 4.0f}, {0, 0, 0});  // along z, through leaf edges
  views.push_back(s);
  s.camera = Camera::lookAt({0.95f, 0.95f, 0.95f}, {-1, -0.5f, -0.8f});  // inside the cluster
  s.camera.projection = Projection::Perspective;
  s.camera.near_distance = 1e-3f;
  views.push_back(s);
  int n = 0;
  for (const FrameSettings& v : views) {
    SCOPED_TRACE("view " + std::to_string(n));
    const RenderResult a = octree->render(g, v);
    EXPECT_GT(a.stats.octree_leaves, 50u);
    EXPECT_GT(a.stats.octree_duplicate_refs, 100u);
    EXPECT_EQ(a.stats.fragments, ppll->render(g, v).stats.fragments);
    test::expectImagesMatch(a.image, embree->render(g, v).image,
                            "octree-shared-" + std::to_string(n));
    ++n;
  }
}

}  // namespace
}  // namespace strata

namespace strata {
namespace {

// A stack of 500 translucent squares 1e-4 apart, which no leaf limit can split apart, beside
// a torus: with a small tile bound each leaf stops after the walks the bound allows, and the
// fragments behind are counted lost, not composited. Every variant and both kernel forms count
// the same fragments as without the bound, read a bounded number of references per tile, and
// agree with each other; the k-buffer, whose walks take 32 layers each, still saturates the
// stack, so its image stays within 1/255 of the unbounded one.
TEST(OctreeTileReads, DeepLeavesStopAtTheBoundAndCountWhatTheyLeave) {
  Scene scene;
  scene.source = "stack";
  Mesh stack;
  const int layers = 500;
  for (int i = 0; i < layers; ++i) {
    const float z = 1e-4f * float(i);
    const uint32_t b = uint32_t(stack.positions.size());
    stack.positions.insert(stack.positions.end(), {{-1, -1, z}, {1, -1, z}, {1, 1, z}, {-1, 1, z}});
    stack.indices.insert(stack.indices.end(), {b, b + 1, b + 2, b, b + 2, b + 3});
  }
  scene.meshes.push_back(stack);
  Mesh torus = makeTorus(0.8f, 0.3f, 24, 12);
  for (glm::vec3& p : torus.positions) p += glm::vec3(2.5f, 0.0f, 0.0f);
  scene.meshes.push_back(torus);
  Material glass;
  glass.color = {0.3f, 0.6f, 1.0f, 0.4f};
  glass.opacity = 0.4f;
  scene.materials.push_back(glass);
  for (uint32_t m = 0; m < 2; ++m) {
    scene.meshes[m].material = 0;
    Instance in;
    in.mesh = m;
    scene.instances.push_back(in);
  }
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const uint64_t triangles = g.triangleCount();
  auto octree = makeRenderer(Method::Octree);
  for (const char* variant : {"kbuffer", "blocks-histogram", "blocks", "histogram", "dp"}) {
    SCOPED_TRACE(variant);
    FrameSettings s = test::settingsFor(scene, 64, 20.0f, 35.0f);
    s.cell_cache_dir = cacheDir();
    s.octree.variant = variant;
    s.octree.tile_reads = 0;
    const RenderResult full = octree->render(g, s);
    EXPECT_EQ(full.stats.fragments_lost, 0u);
    ASSERT_GE(full.stats.max_depth_complexity, uint64_t(layers));
    const uint32_t bound = 5000;
    s.octree.tile_reads = bound;
    RenderResult first;
    for (const char* kernels : {"group", "serial"}) {
      SCOPED_TRACE(kernels);
      s.tile_kernels = kernels;
      const RenderResult r = octree->render(g, s);
      EXPECT_EQ(r.stats.fragments, full.stats.fragments);
      EXPECT_GT(r.stats.fragments_lost, full.stats.fragments / 2);
      const uint64_t tiles = (64 / 8) * (64 / 8);
      // Each tile: the bound, plus each leaf's least walks and its count (four passes at most).
      EXPECT_LE(r.stats.bin_entry_reads, tiles * (bound + 4 * triangles));
      EXPECT_LT(r.stats.bin_entry_reads * 2, full.stats.bin_entry_reads);
      if (std::string(kernels) == "group") {
        first = r;
      } else {
        EXPECT_EQ(r.stats.fragments_lost, first.stats.fragments_lost);
        EXPECT_EQ(r.stats.bin_entry_reads, first.stats.bin_entry_reads);
        EXPECT_EQ(compareImages(r.image, first.image).max_abs, 0);
      }
    }
    if (std::string(variant) == "kbuffer") {
      EXPECT_LE(compareImages(first.image, full.image).max_abs, 1);
    }
  }
}

}  // namespace
}  // namespace strata
