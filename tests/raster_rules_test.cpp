// Rasterization rules of the OpenCL pipeline: fill-rule coverage, closed-mesh parity, clipping.
#include <cmath>
#include <random>

#include <glm/gtc/matrix_transform.hpp>

#include "engine/reference/embree_reference.h"
#include "kernels/strata_shared.h"
#include "test_support.h"

namespace strata {
namespace {

WorldGeometry singleMaterial(float alpha = 0.5f) {
  WorldGeometry g;
  g.material_colors.push_back({0.6f, 0.7f, 0.8f, alpha});
  return g;
}

void addTriangle(WorldGeometry& g, glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const uint32_t base = uint32_t(g.positions.size());
  g.positions.insert(g.positions.end(), {a, b, c});
  g.indices.insert(g.indices.end(), {base, base + 1, base + 2});
  g.triangle_material.push_back(0);
  g.triangle_object.push_back(0);
}

// A fan around `centre` whose rim lies far outside the view, in the plane through `centre` with
// the given axes; shared edges and the shared centre vertex are where a fill rule is tested.
WorldGeometry randomFan(std::mt19937& rng, glm::vec3 centre, glm::vec3 u, glm::vec3 v, float rim,
                        int spokes) {
  WorldGeometry g = singleMaterial();
  std::uniform_real_distribution<float> jitter(0.2f, 1.0f);
  std::vector<float> angles;
  for (int i = 0; i < spokes; ++i)
    angles.push_back((float(i) + jitter(rng) * 0.8f) * 6.2831853f / float(spokes));
  const uint32_t c = 0;
  g.positions.push_back(centre);
  for (float a : angles) g.positions.push_back(centre + rim * (std::cos(a) * u + std::sin(a) * v));
  for (int i = 0; i < spokes; ++i) {
    g.indices.insert(g.indices.end(), {c, uint32_t(1 + i), uint32_t(1 + (i + 1) % spokes)});
    g.triangle_material.push_back(0);
    g.triangle_object.push_back(0);
  }
  return g;
}

// An orthographic view of the z = 0 plane, two world units high, capturing depth complexity.
FrameSettings planeView(int width, int height) {
  FrameSettings s;
  s.width = width;
  s.height = height;
  s.capture_depth_complexity = true;
  s.camera = Camera::lookAt({0.0f, 0.0f, 5.0f}, {0.0f, 0.0f, 0.0f});
  s.camera.projection = Projection::Orthographic;
  s.camera.ortho_height = 2.0f;
  s.camera.near_distance = 0.1f;
  return s;
}

void expectEveryPixelOnce(const RenderResult& r, const std::string& what) {
  ASSERT_EQ(r.depth_complexity.size(), size_t(r.image.width) * r.image.height);
  size_t wrong = 0;
  for (uint32_t n : r.depth_complexity) wrong += n != 1;
  EXPECT_EQ(wrong, 0u) << what << ": pixels not covered exactly once";
  EXPECT_EQ(r.stats.fragments, uint64_t(r.image.width) * r.image.height) << what;
}

TEST(RasterRules, RandomFansCoverEveryPixelCentreExactlyOnce) {
  std::mt19937 rng(7);
  auto ppll = makeRenderer(Method::Ppll);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (int trial = 0; trial < 12; ++trial) {
    // Orthographic view of the z = 0 plane; odd sizes so tiles are partial.
    const FrameSettings s = planeView(97 + trial * 13, 61 + trial * 7);
    // Centres on exact pixel centres and corners too, where the top-left rule decides.
    glm::vec3 centre(unit(rng) * 0.8f, unit(rng) * 0.8f, 0.0f);
    if (trial % 3 == 0) {
      const float px = 2.0f / float(s.height);  // world units per pixel
      centre = glm::vec3((std::round(centre.x / px) + (trial % 2 ? 0.5f : 0.0f)) * px,
                         std::round(centre.y / px) * px, 0.0f);
    }
    WorldGeometry g = randomFan(rng, centre, {1, 0, 0}, {0, 1, 0}, 50.0f, 5 + trial * 3);
    RenderResult r = ppll->render(g, s);
    expectEveryPixelOnce(r, "orthographic fan " + std::to_string(trial));
  }
}

TEST(RasterRules, FansOfVeryLongEdgesCoverEveryPixelCentreExactlyOnce) {
  // Spokes tens of thousands of pixels long, inside the guard band (no clipping): their edge
  // functions leave 32 bits across a tile, so the tile coverage takes its 64-bit path there;
  // the short spokes of the other trials stay on the 32-bit steps. Both must keep the fill rule.
  std::mt19937 rng(23);
  auto opaque = makeRenderer(Method::Opaque);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  for (int trial = 0; trial < 6; ++trial) {
    const FrameSettings s = planeView(101 + trial * 29, 77 + trial * 11);
    const glm::vec3 centre(unit(rng) * 0.7f, unit(rng) * 0.7f, 0.0f);
    const float rim = trial % 2 ? 3000.0f : 10.0f;  // ~100k px spokes, or a few hundred
    WorldGeometry g = randomFan(rng, centre, {1, 0, 0}, {0, 1, 0}, rim, 5 + trial * 2);
    RenderResult r = opaque->render(g, s);
    expectEveryPixelOnce(r,
                         "fan of rim " + std::to_string(rim) + ", trial " + std::to_string(trial));
    EXPECT_EQ(r.stats.clipped, 0u);
  }
}

TEST(RasterRules, JitteredGridsOfSmallAndLargeTrianglesCoverEveryPixelCentreExactlyOnce) {
  // Meshes of triangles a few pixels to about a hundred across: the tile coverage evaluates a
  // triangle spanning under 64 pixels (2^14 subpixels) on both axes in 32-bit steps from its
  // edges alone, a larger one from its edges' extremes over the tile, so these grids put
  // triangles of both kinds side by side along shared edges, with vertices on pixel centres
  // and corners where the fill rule decides.
  std::mt19937 rng(11);
  auto ppll = makeRenderer(Method::Ppll);
  for (float spacing : {2.5f, 7.0f, 31.0f, 44.0f, 61.0f, 90.0f}) {
    const FrameSettings s = planeView(203, 149);
    const float px = 2.0f / float(s.height);  // world units per pixel
    const float half_w = float(s.width) / float(s.height);
    const int nx = int(std::ceil(float(s.width) / spacing)) + 3;
    const int ny = int(std::ceil(float(s.height) / spacing)) + 3;
    // Small enough that no quad folds over, with the snap's half pixel.
    std::uniform_real_distribution<float> jitter(-0.2f, 0.2f);
    std::uniform_int_distribution<int> snap(0, 3);
    WorldGeometry g = singleMaterial();
    for (int j = 0; j < ny; ++j) {
      for (int i = 0; i < nx; ++i) {
        // Inner vertices jittered; every fourth or so onto a pixel centre or corner.
        const bool rim = i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
        float x = (float(i) - 1.0f + (rim ? 0.0f : jitter(rng))) * spacing;
        float y = (float(j) - 1.0f + (rim ? 0.0f : jitter(rng))) * spacing;
        const int k = snap(rng);
        if (!rim && k < 2 && spacing > 5.0f) {
          x = std::round(x) + (k ? 0.5f : 0.0f);
          y = std::round(y) + (k ? 0.5f : 0.0f);
        }
        g.positions.push_back({-half_w + x * px, 1.0f - y * px, 0.0f});
      }
    }
    for (int j = 0; j + 1 < ny; ++j) {
      for (int i = 0; i + 1 < nx; ++i) {
        const uint32_t a = uint32_t(j * nx + i), b = a + 1, c = a + uint32_t(nx), d = c + 1;
        const bool flip = (i + j) % 2 != 0;  // both diagonals
        const uint32_t b_c[6] = {a, b, c, b, d, c}, a_d[6] = {a, b, d, a, d, c};
        g.indices.insert(g.indices.end(), flip ? a_d : b_c, (flip ? a_d : b_c) + 6);
        for (int t = 0; t < 2; ++t) {
          g.triangle_material.push_back(0);
          g.triangle_object.push_back(0);
        }
      }
    }
    RenderResult r = ppll->render(g, s);
    expectEveryPixelOnce(r, "grid of spacing " + std::to_string(spacing) + " px");
  }
}

TEST(RasterRules, FansCrossingTheNearPlaneCoverEveryPixelOnce) {
  // A tilted plane seen in perspective: the fan's rim reaches behind the eye, so triangles are
  // clipped at the near plane (and the far rim by the guard band) yet the view stays covered.
  std::mt19937 rng(11);
  auto ppll = makeRenderer(Method::Ppll);
  for (int trial = 0; trial < 6; ++trial) {
    FrameSettings s;
    s.width = 128 + trial * 17;
    s.height = 96 + trial * 9;
    s.capture_depth_complexity = true;
    s.camera = Camera::lookAt({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f});
    s.camera.fov_y_deg = 60.0f;
    s.camera.near_distance = 0.05f;
    const glm::vec3 centre(0.1f * trial, -0.05f * trial, -1.0f - 0.05f * trial);
    const glm::vec3 u = glm::normalize(glm::vec3(1.0f, 0.0f, -0.5f));  // the plane tilts away
    WorldGeometry g = randomFan(rng, centre, u, {0.0f, 1.0f, 0.0f}, 1e4f, 7 + trial);
    RenderResult r = ppll->render(g, s);
    expectEveryPixelOnce(r, "perspective fan " + std::to_string(trial));
    EXPECT_GT(r.stats.clipped, 0u);
  }
}

TEST(RasterRules, ClosedMeshesGiveEvenFragmentCounts) {
  auto ppll = makeRenderer(Method::Ppll);
  for (const char* spec : {"builtin:demo", "builtin:spheres:16"}) {
    const auto [scene, g] = test::sceneAndGeometry(spec);
    for (float az : {0.0f, 37.0f, 123.0f}) {
      FrameSettings s = test::settingsFor(scene, 160, az, 25.0f);
      s.capture_depth_complexity = true;
      RenderResult r = ppll->render(g, s);
      size_t odd = 0, covered = 0;
      for (uint32_t n : r.depth_complexity) {
        odd += n % 2;
        covered += n > 0;
      }
      EXPECT_GT(covered, 1000u) << spec;
      EXPECT_EQ(odd, 0u) << spec << " az " << az << ": pixels with an odd fragment count";
    }
  }
  for (const char* file : {"cow.obj", "fandisk.obj", "horse.ply"}) {
    const auto [scene, g] = test::sceneAndGeometry(test::modelPath(file));
    FrameSettings s = test::settingsFor(scene, 200, 45.0f, 30.0f);
    s.capture_depth_complexity = true;
    RenderResult r = ppll->render(g, s);
    size_t odd = 0;
    for (uint32_t n : r.depth_complexity) odd += n % 2;
    EXPECT_EQ(odd, 0u) << file << ": pixels with an odd fragment count";
  }
}

TEST(RasterRules, TrianglesCrossingTheNearPlaneMatchTheReference) {
  // The eye inside the scene: many triangles cross the near plane. The result must have no
  // NaN/garbage pixels: it matches the Embree reference, whose rays start at the near plane.
  const auto [scene, g] = test::sceneAndGeometry("builtin:demo");
  auto ppll = makeRenderer(Method::Ppll);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  for (float dist : {0.3f, 0.9f, 1.1f}) {
    FrameSettings s;
    s.width = s.height = 192;
    OrbitView v;
    v.azimuth_deg = 20.0f;
    v.elevation_deg = 10.0f;
    v.distance_radii = dist;
    s.camera = Camera::orbit(scene.boundingSphere(), v);
    // A near plane that cuts through the shapes, so clipping is exercised.
    s.camera.near_distance = 0.6f * scene.boundingSphere().radius;
    RenderResult a = ppll->render(g, s);
    RenderResult b = embree->render(g, s);
    EXPECT_GT(a.stats.clipped, 0u) << "distance " << dist;
    test::expectImagesMatch(a.image, b.image, "near-plane-" + std::to_string(dist));
  }
}

TEST(RasterRules, OpaqueAndPpllSeeTheSameFragmentsAsEmbree) {
  // Per-pixel fragment counts of the two OpenCL methods agree exactly (same front end), and with
  // the Embree reference except where a ray grazes a shared edge.
  const auto [scene, g] = test::sceneAndGeometry(test::modelPath("rocker-arm.obj"));
  FrameSettings s = test::settingsFor(scene, 200, 75.0f, 15.0f);
  s.capture_depth_complexity = true;
  const RenderResult a = makeRenderer(Method::Opaque)->render(g, s);
  const RenderResult b = makeRenderer(Method::Ppll)->render(g, s);
  const RenderResult c = makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s);
  EXPECT_EQ(a.depth_complexity, b.depth_complexity);
  size_t differ = 0;
  for (size_t i = 0; i < b.depth_complexity.size(); ++i)
    differ += b.depth_complexity[i] != c.depth_complexity[i];
  EXPECT_LT(differ, b.depth_complexity.size() / 200)
      << "pixels whose fragment count differs from Embree";
  EXPECT_EQ(a.stats.max_depth_complexity, b.stats.max_depth_complexity);
}

TEST(RasterRules, PixelsDeeperThanTheSortArrayStayExact) {
  // 150 stacked quads: more fragments per pixel than the resolve's private sort array holds, so
  // the exact selection walk runs; it must still match the reference.
  WorldGeometry g;
  for (int i = 0; i < 150; ++i)
    g.material_colors.push_back(
        {float(i % 7) / 7.0f, float(i % 5) / 5.0f, float(i % 3) / 3.0f, 0.03f});
  for (int i = 0; i < 150; ++i) {
    const float z = -float(i) * 0.01f;
    const float s = 1.0f - 0.002f * float(i);
    const uint32_t base = uint32_t(g.positions.size());
    g.positions.insert(g.positions.end(), {{-s, -s, z}, {s, -s, z}, {s, s, z}, {-s, s, z}});
    g.indices.insert(g.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
    g.triangle_material.insert(g.triangle_material.end(), 2, uint32_t(i));
    g.triangle_object.insert(g.triangle_object.end(), 2, 0u);
  }
  ASSERT_GT(150, ST_PPLL_SORT_CAPACITY);
  FrameSettings s;
  s.width = s.height = 48;
  s.camera = Camera::lookAt({0.3f, 0.2f, 4.0f}, {0.0f, 0.0f, -0.7f});
  const RenderResult a = makeRenderer(Method::Ppll)->render(g, s);
  EXPECT_EQ(a.stats.max_depth_complexity, 150u);
  test::expectImagesMatch(a.image, makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s).image,
                          "deep-selection-walk");
}

TEST(RasterRules, DegenerateAndNonFiniteTrianglesAreCulledAndCounted) {
  WorldGeometry g = singleMaterial();
  addTriangle(g, {-1, -1, 0}, {1, -1, 0}, {0, 1, 0});
  addTriangle(g, {-1, -1, 0}, {0, 0, 0}, {1, 1, 0});  // collinear: zero area
  addTriangle(g, {-1, -1, 0}, {NAN, 0, 0}, {1, 1, 0});
  FrameSettings s;
  s.width = s.height = 64;
  s.camera = Camera::lookAt({0, 0, 4}, {0, 0, 0});
  auto ppll = makeRenderer(Method::Ppll);
  RenderResult r = ppll->render(g, s);
  EXPECT_EQ(r.stats.culled_degenerate, 1u);
  EXPECT_EQ(r.stats.culled_nonfinite, 1u);
  EXPECT_GT(r.stats.fragments, 0u);
}

TEST(RasterRules, LinkedListPoolGrowsInsteadOfTruncating) {
  // Spheres stacked 16 deep at a size where the initial pool (2 nodes per pixel) cannot hold the
  // fragments: the frame must be re-run with a larger pool and match the reference.
  const auto [scene, g] = test::sceneAndGeometry("builtin:spheres:16");
  FrameSettings s = test::settingsFor(scene, 128, 0.0f, 0.0f);
  auto ppll = makeRenderer(Method::Ppll);
  RenderResult r = ppll->render(g, s);
  EXPECT_GE(r.stats.reruns, 1u);
  EXPECT_GT(r.stats.fragments, 2u * 128 * 128);
  auto embree = makeEmbreeRenderer(EmbreeMode::Transparency);
  test::expectImagesMatch(r.image, embree->render(g, s).image, "pool-growth");
}

}  // namespace
}  // namespace strata
