// The Embree reference renderer against answers worked out by hand: compositing of known layers,
// hit counts of closed meshes, nearest-hit selection, the near plane, and its error handling.
#include "engine/reference/embree_reference.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <string>
#include <vector>

#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/scene/world_geometry.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

// ---- Views --------------------------------------------------------------------------------------

constexpr int kSize = kStackSize;

// Looks down -z from z = 5; the view is 2 x 2 world units, so pixel centre x maps to world
// x = (x + 0.5) / 32 - 1 and row y to world y = 1 - (y + 0.5) / 32.
FrameSettings orthoSettings(glm::vec3 background = {0.1f, 0.2f, 0.3f}) {
  return test::orthoTopDown(kSize, background);
}

double worldX(int x) { return (x + 0.5) / (kSize / 2) - 1.0; }
double worldY(int y) { return 1.0 - (y + 0.5) / (kSize / 2); }

// The rectangles below avoid pixel centres on their edges and on their diagonals.
constexpr float kX0 = kStackX0, kY0 = kStackY0, kX1 = kStackX1, kY1 = kStackY1;
bool insideRect(int x, int y) {
  return worldX(x) > kX0 && worldX(x) < kX1 && worldY(y) > kY0 && worldY(y) < kY1;
}

// Flat shading of a face whose normal is +-z, from the shared rule.
double faceShade(const FrameSettings& s) {
  return st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
}

RenderResult render(const WorldGeometry& g, const FrameSettings& s,
                    EmbreeMode mode = EmbreeMode::Transparency) {
  return makeEmbreeRenderer(mode)->render(g, s);
}

// With black materials of opacity 1/2 over a white background, a pixel with k hits has the
// value 255 / 2^k, so the image tells each pixel's hit count (up to 7).
int hitsFromValue(int v) {
  for (int k = 0; k < 8; ++k)
    if (v == int(st_to_unorm8(std::ldexp(1.0f, -k)))) return k;
  return -1;
}

// The pixels of a closed mesh's image (black, opacity 1/2, over white) that show 2 hits; fails
// the test at a pixel showing any other count but 0.
uint64_t pixelsHitTwice(const Image& image) {
  uint64_t covered = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const int hits = hitsFromValue(image.pixel(x, y)[0]);
      EXPECT_TRUE(hits == 0 || hits == 2) << "pixel " << x << "," << y << ": " << hits << " hits";
      covered += hits == 2;
    }
  return covered;
}

// ---- Compositing
// ----------------------------------------------------------------------------------

TEST(EmbreeReference, HalfTransparentQuadOverSolidBackground) {
  WorldGeometry g;
  const glm::vec3 color(0.2f, 0.6f, 0.9f);
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, addMaterial(g, color, 0.5f));
  const FrameSettings s = orthoSettings();
  const RenderResult r = render(g, s);
  ASSERT_EQ(r.image.width, kSize);
  ASSERT_EQ(r.image.height, kSize);
  const double k = faceShade(s);
  int covered = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const bool in = insideRect(x, y);
      covered += in;
      const uint8_t* p = r.image.pixel(x, y);
      for (int c = 0; c < 3; ++c) {
        const double bg = s.background.color[c];
        const double expected = in ? 0.5 * k * color[c] + 0.5 * bg : bg;
        ASSERT_EQ(int(p[c]), int(unorm8(expected)))
            << "pixel " << x << "," << y << " channel " << c;
      }
      ASSERT_EQ(p[3], 255);
    }
  EXPECT_EQ(covered, 32 * 32);
  EXPECT_EQ(r.stats.fragments, uint64_t(covered));
  EXPECT_EQ(r.stats.max_depth_complexity, 1u);
  EXPECT_EQ(r.stats.triangles, 2u);
  EXPECT_EQ(r.stats.method, "embree");
  EXPECT_EQ(r.stats.device.rfind("Embree 3.", 0), 0u) << r.stats.device;
  EXPECT_EQ(r.stats.kernel_launches, 0u);
  EXPECT_EQ(r.stats.triangles_read, 0u);
  EXPECT_GT(r.stats.device_bytes, r.stats.fragment_bytes);
  EXPECT_EQ(r.stats.stage_ms.count("bvh_build"), 1u);
  EXPECT_EQ(r.stats.stage_ms.count("trace"), 1u);
}

TEST(EmbreeReference, StackedQuadsCompositeFrontToBackAndOrderMatters) {
  const glm::vec3 red(0.9f, 0.2f, 0.1f), blue(0.1f, 0.3f, 0.9f);
  const float a_red = 0.6f, a_blue = 0.3f;
  WorldGeometry g;
  addQuad(g, kX0, kY0, kX1, kY1, 0.5f, addMaterial(g, red, a_red));    // triangles 0, 1
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, addMaterial(g, blue, a_blue));  // triangles 2, 3
  const FrameSettings s = orthoSettings();
  const double k = faceShade(s);
  const auto expected = [&](glm::vec3 c1, float a1, glm::vec3 c2, float a2, int ch) {
    const double bg = s.background.color[ch];
    return unorm8(a1 * k * c1[ch] + (1 - a1) * a2 * k * c2[ch] + (1 - a1) * (1 - a2) * bg);
  };
  const int px = 30, py = 33;
  ASSERT_TRUE(insideRect(px, py));

  const RenderResult red_front = render(g, s);
  for (int c = 0; c < 3; ++c)
    EXPECT_EQ(int(red_front.image.pixel(px, py)[c]), int(expected(red, a_red, blue, a_blue, c)));
  EXPECT_EQ(red_front.stats.max_depth_complexity, 2u);

  // Swap the depths: blue is now in front, and the result changes.
  for (glm::vec3& p : g.positions) p.z = p.z == 0.5f ? 0.0f : 0.5f;
  const RenderResult blue_front = render(g, s);
  for (int c = 0; c < 3; ++c)
    EXPECT_EQ(int(blue_front.image.pixel(px, py)[c]), int(expected(blue, a_blue, red, a_red, c)));
  EXPECT_NE(red_front.image.rgba, blue_front.image.rgba);
  // Outside the quads both show the background.
  EXPECT_EQ(red_front.image.pixel(2, 2)[0], unorm8(s.background.color[0]));
  EXPECT_EQ(blue_front.image.pixel(2, 2)[0], unorm8(s.background.color[0]));
}

TEST(EmbreeReference, EqualDepthsCompositeInTriangleIdOrder) {
  // Two coincident quads: the one with the smaller triangle ids is composited first.
  const glm::vec3 red(0.9f, 0.2f, 0.1f), blue(0.1f, 0.3f, 0.9f);
  WorldGeometry g;
  const uint32_t m_red = addMaterial(g, red, 0.7f), m_blue = addMaterial(g, blue, 0.7f);
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, m_red);
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, m_blue);
  const FrameSettings s = orthoSettings();
  const RenderResult first = render(g, s);
  const RenderResult first_opaque = render(g, s, EmbreeMode::Opaque);
  std::swap(g.triangle_material[0], g.triangle_material[2]);
  std::swap(g.triangle_material[1], g.triangle_material[3]);
  const RenderResult second = render(g, s);
  const RenderResult second_opaque = render(g, s, EmbreeMode::Opaque);
  const double k = faceShade(s);
  const int px = 40, py = 20;
  ASSERT_TRUE(insideRect(px, py));
  for (int c = 0; c < 3; ++c) {
    const double bg = s.background.color[c];
    EXPECT_EQ(first.image.pixel(px, py)[c],
              unorm8(0.7 * k * red[c] + 0.3 * 0.7 * k * blue[c] + 0.09 * bg));
    EXPECT_EQ(second.image.pixel(px, py)[c],
              unorm8(0.7 * k * blue[c] + 0.3 * 0.7 * k * red[c] + 0.09 * bg));
    EXPECT_EQ(first_opaque.image.pixel(px, py)[c], unorm8(k * red[c]));
    EXPECT_EQ(second_opaque.image.pixel(px, py)[c], unorm8(k * blue[c]));
  }
}

TEST(EmbreeReference, OpaqueModeShowsTheNearestSurface) {
  const glm::vec3 red(0.9f, 0.2f, 0.1f), blue(0.1f, 0.3f, 0.9f);
  WorldGeometry g;
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, addMaterial(g, blue, 0.3f));  // behind, lower ids
  addQuad(g, kX0, kY0, kX1, kY1, 0.5f, addMaterial(g, red, 0.3f));   // in front
  const FrameSettings s = orthoSettings();
  const RenderResult r = render(g, s, EmbreeMode::Opaque);
  const double k = faceShade(s);
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(r.image.pixel(x, y)[c],
                  unorm8(insideRect(x, y) ? k * red[c] : s.background.color[c]))
            << x << "," << y;
  EXPECT_EQ(r.stats.method, "embree-opaque");
  EXPECT_EQ(r.stats.fragments, 32u * 32u);
  EXPECT_EQ(r.stats.max_depth_complexity, 1u);

  for (glm::vec3& p : g.positions) p.z = -p.z + 0.5f;  // now blue is in front
  const RenderResult swapped = render(g, s, EmbreeMode::Opaque);
  EXPECT_EQ(swapped.image.pixel(30, 30)[2], unorm8(k * blue[2]));
}

// ---- Hit counts of closed meshes
// ------------------------------------------------------------------

TEST(EmbreeReference, BoxViewedHeadOnHasTwoHitsPerCoveredPixel) {
  WorldGeometry g;
  addBox(g, {kX0, kY0, -0.4f}, {kX1, kY1, 0.3f}, addMaterial(g, glm::vec3(0.0f), 0.5f));
  const FrameSettings s = orthoSettings(glm::vec3(1.0f));
  const RenderResult r = render(g, s);
  uint64_t covered = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x) {
      const int hits = hitsFromValue(r.image.pixel(x, y)[0]);
      ASSERT_EQ(hits, insideRect(x, y) ? 2 : 0) << "pixel " << x << "," << y;
      covered += insideRect(x, y);
    }
  EXPECT_EQ(covered, 32u * 32u);
  EXPECT_EQ(r.stats.fragments, 2 * covered);
  EXPECT_EQ(r.stats.max_depth_complexity, 2u);
}

TEST(EmbreeReference, ClosedMeshesHaveEvenHitCountsInPerspective) {
  WorldGeometry g;
  const uint32_t black = addMaterial(g, glm::vec3(0.0f), 0.5f);
  glm::mat4 m = glm::translate(glm::mat4(1.0f), glm::vec3(0.13f, -0.07f, 0.05f));
  m = glm::rotate(m, 0.7f, glm::normalize(glm::vec3(1.0f, 0.4f, 0.2f)));
  addSphere(g, glm::scale(m, glm::vec3(0.8f)), 40, 23, black);
  addBox(g, {-1.7f, -0.2f, -0.3f}, {-1.1f, 0.5f, 0.2f}, black);  // beside the sphere
  FrameSettings s;
  s.width = 96;
  s.height = 70;
  s.camera = Camera::lookAt({0.9f, 1.1f, 4.2f}, {-0.2f, 0.05f, 0.0f});
  s.camera.fov_y_deg = 45.0f;
  s.background.checker = false;
  s.background.color = glm::vec3(1.0f);
  const RenderResult r = render(g, s);
  const uint64_t covered = pixelsHitTwice(r.image);
  EXPECT_GT(covered, uint64_t(s.width * s.height) / 10);
  EXPECT_EQ(r.stats.fragments, 2 * covered);
  EXPECT_EQ(r.stats.max_depth_complexity, 2u);
}

TEST(EmbreeReference, RaysThroughSharedEdgesAndVerticesCountOnce) {
  // A centred square: its diagonal passes exactly through the pixel centres with x + y = 63,
  // where Embree's watertight test reports both triangles; a rasterizer's fill rule covers
  // those pixels once, and so must the reference.
  WorldGeometry quad;
  addQuad(quad, -0.5f, -0.5f, 0.5f, 0.5f, 0.0f, addMaterial(quad, glm::vec3(0.0f), 0.5f));
  const RenderResult q = render(quad, orthoSettings(glm::vec3(1.0f)));
  EXPECT_EQ(q.stats.fragments, 32u * 32u);
  EXPECT_EQ(q.stats.max_depth_complexity, 1u);
  EXPECT_EQ(hitsFromValue(q.image.pixel(20, 43)[0]), 1);

  // A UV sphere seen along its axis: the centre pixel's ray goes through both poles (a fan of
  // 40 triangles each) and the centre row and column run along meridian edges.
  WorldGeometry sphere;
  addSphere(sphere, glm::mat4(1.0f), 40, 16, addMaterial(sphere, glm::vec3(0.0f), 0.5f));
  FrameSettings s;
  s.width = s.height = 33;
  s.camera = Camera::lookAt({0.0f, 5.0f, 0.0f}, {0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f});
  s.camera.projection = Projection::Orthographic;
  s.camera.ortho_height = 2.5f;
  s.camera.near_distance = 1.0f;
  s.background.checker = false;
  s.background.color = glm::vec3(1.0f);
  const RenderResult r = render(sphere, s);
  EXPECT_EQ(hitsFromValue(r.image.pixel(16, 16)[0]), 2);
  EXPECT_EQ(r.stats.max_depth_complexity, 2u);
  const uint64_t covered = pixelsHitTwice(r.image);
  EXPECT_EQ(r.stats.fragments, 2 * covered);
}

// Counts, by brute force in double precision, the triangles whose xy projection contains each
// pixel centre of an orthographic view along -z (orthoSettings): the exact fragment count.
void bruteForceCounts(const WorldGeometry& g, uint64_t& fragments, uint64_t& max_depth) {
  std::vector<int> count(size_t(kSize) * kSize, 0);
  for (uint32_t t = 0; t < g.triangleCount(); ++t) {
    glm::dvec2 p[3];
    for (int k = 0; k < 3; ++k) p[k] = glm::dvec2(g.positions[g.indices[3 * t + k]]);
    const auto edge = [](glm::dvec2 a, glm::dvec2 b, glm::dvec2 c) {
      return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    };
    const double area = edge(p[0], p[1], p[2]);
    if (area == 0.0) continue;
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const glm::dvec2 c(worldX(x), worldY(y));
        const double e0 = edge(p[0], p[1], c) / area, e1 = edge(p[1], p[2], c) / area,
                     e2 = edge(p[2], p[0], c) / area;
        if (e0 >= 0 && e1 >= 0 && e2 >= 0) ++count[size_t(y) * kSize + x];
      }
  }
  fragments = max_depth = 0;
  for (int c : count) {
    fragments += uint64_t(c);
    max_depth = std::max(max_depth, uint64_t(c));
  }
}

TEST(EmbreeReference, FragmentsMatchABruteForceCountWithAndWithoutSpatialSplits) {
  // Thousands of overlapping random triangles. Without the robust flag Embree 3.13 builds a
  // spatial-split BVH and reports about 1 in 300 hits twice (same triangle, same distance):
  // the reference must count each once.
  WorldGeometry g;
  const uint32_t m = addMaterial(g, glm::vec3(0.5f), 0.2f);
  uint32_t state = 12345u;
  const auto uniform = [&state](float lo, float hi) {
    state = state * 1664525u + 1013904223u;
    return lo + (hi - lo) * float(state >> 8) / float(1u << 24);
  };
  for (int i = 0; i < 5000; ++i) {
    const glm::vec3 a(uniform(-0.9f, 0.9f), uniform(-0.9f, 0.9f), uniform(-1.0f, 1.0f));
    const uint32_t base = uint32_t(g.positions.size());
    g.positions.push_back(a);
    for (int k = 0; k < 2; ++k)
      g.positions.push_back(a + 0.2f * glm::vec3(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1)));
    addTriangle(g, base, base + 1, base + 2, m);
  }
  uint64_t expected_fragments = 0, expected_max = 0;
  bruteForceCounts(g, expected_fragments, expected_max);
  ASSERT_GT(expected_fragments, 20000u);
  for (bool robust : {true, false}) {
    EmbreeOptions o;
    o.robust = robust;
    const RenderResult r = makeEmbreeRenderer(o)->render(g, orthoSettings());
    EXPECT_EQ(r.stats.fragments, expected_fragments) << "robust " << robust;
    EXPECT_EQ(r.stats.max_depth_complexity, expected_max) << "robust " << robust;
  }
}

TEST(EmbreeReference, DeepPixelsAreNotTruncated) {
  // 40 layers: deeper than any fixed per-pixel array one might guess.
  const int layers = 40;
  WorldGeometry g;
  const uint32_t black = addMaterial(g, glm::vec3(0.0f), 0.1f);
  for (int i = 0; i < layers; ++i) addQuad(g, kX0, kY0, kX1, kY1, -1.0f + 0.05f * float(i), black);
  const FrameSettings s = orthoSettings(glm::vec3(1.0f));
  const RenderResult r = render(g, s);
  EXPECT_EQ(r.stats.max_depth_complexity, uint64_t(layers));
  EXPECT_EQ(r.stats.fragments, uint64_t(layers) * 32u * 32u);
  EXPECT_NEAR(r.image.pixel(31, 31)[0], 255.0 * std::pow(0.9, layers), 1.0);
  EXPECT_EQ(r.image.pixel(0, 0)[0], 255);
}

// ---- Camera
// ----------------------------------------------------------------------------------------

TEST(EmbreeReference, NearPlaneClipsByViewDistanceNotRayLength) {
  // A plane 4.5 in front of a perspective eye filling the view: with the near plane at 4.4 every
  // pixel sees it, at 4.6 none does (even in the corners, where the ray to it is longer).
  WorldGeometry g;
  addQuad(g, -20.0f, -20.0f, 20.0f, 20.0f, 0.5f, addMaterial(g, glm::vec3(0.0f), 0.5f));
  FrameSettings s;
  s.width = 40;
  s.height = 30;
  s.camera = Camera::lookAt({0.0f, 0.0f, 5.0f}, {0.0f, 0.0f, 0.0f});
  s.camera.fov_y_deg = 60.0f;
  s.background.checker = false;
  s.background.color = glm::vec3(1.0f);
  s.camera.near_distance = 4.4f;
  const RenderResult seen = render(g, s);
  EXPECT_EQ(seen.stats.fragments, uint64_t(40 * 30));
  s.camera.near_distance = 4.6f;
  const RenderResult clipped = render(g, s);
  EXPECT_EQ(clipped.stats.fragments, 0u);
  EXPECT_EQ(clipped.image.pixel(0, 0)[0], 255);
}

TEST(EmbreeReference, CheckerBackgroundMatchesTheSharedRule) {
  WorldGeometry g;  // nothing at all
  FrameSettings s = orthoSettings();
  s.background.checker = true;
  s.width = 50;
  s.height = 40;
  const RenderResult r = render(g, s);
  const StViewConstants v = [&] {
    StViewConstants c{};
    for (int i = 0; i < 3; ++i) {
      c.background[i] = s.background.color[i];
      c.background2[i] = s.background.color2[i];
    }
    c.background_kind = ST_BACKGROUND_CHECKER;
    return c;
  }();
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(r.image.pixel(x, y)[c], st_to_unorm8(st_background_channel(&v, x, y, c)));
  EXPECT_EQ(r.stats.fragments, 0u);
}

// ---- Queries, caching, errors
// ---------------------------------------------------------------------

TEST(EmbreeReference, EveryQueryKindGivesTheSameImage) {
  WorldGeometry g;
  const uint32_t m1 = addMaterial(g, glm::vec3(0.8f, 0.3f, 0.2f), 0.4f);
  const uint32_t m2 = addMaterial(g, glm::vec3(0.2f, 0.7f, 0.3f), 0.6f);
  addSphere(g, glm::scale(glm::mat4(1.0f), glm::vec3(0.7f)), 30, 17, m1);
  addSphere(
      g, glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0.4f, 0.2f, 0.3f)), glm::vec3(0.5f)),
      25, 13, m2);
  FrameSettings s;
  s.width = 77;  // not a multiple of the tile or packet sizes
  s.height = 45;
  s.camera = Camera::lookAt({0.5f, 0.8f, 3.0f}, {0.0f, 0.0f, 0.0f});
  for (EmbreeMode mode : {EmbreeMode::Transparency, EmbreeMode::Opaque}) {
    EmbreeOptions base;
    base.mode = mode;
    base.query = EmbreeQuery::Single;
    const RenderResult reference = makeEmbreeRenderer(base)->render(g, s);
    for (EmbreeQuery q : {EmbreeQuery::Auto, EmbreeQuery::Packet4, EmbreeQuery::Packet8,
                          EmbreeQuery::Packet16, EmbreeQuery::Stream}) {
      for (int threads : {1, 3}) {
        EmbreeOptions o = base;
        o.query = q;
        o.threads = threads;
        const RenderResult r = makeEmbreeRenderer(o)->render(g, s);
        EXPECT_EQ(r.image.rgba, reference.image.rgba) << "query " << int(q);
        EXPECT_EQ(r.stats.fragments, reference.stats.fragments) << "query " << int(q);
        EXPECT_EQ(r.stats.max_depth_complexity, reference.stats.max_depth_complexity);
      }
    }
  }
}

TEST(EmbreeReference, ChangedGeometryIsNeverTracedWithAStaleBvh) {
  WorldGeometry g;
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, addMaterial(g, glm::vec3(0.0f), 0.5f));
  FrameSettings s = orthoSettings(glm::vec3(1.0f));
  s.frames = 3;
  auto renderer = makeEmbreeRenderer();
  const RenderResult first = renderer->render(g, s);
  EXPECT_EQ(first.stats.frame_ms.runs, 3);
  const RenderResult again = renderer->render(g, s);  // same triangles: the cached BVH
  EXPECT_EQ(again.image.rgba, first.image.rgba);
  // Move the quad in place (same object, same triangle count): the image must follow.
  for (glm::vec3& p : g.positions) p.x += 0.5f;
  const RenderResult moved = renderer->render(g, s);
  EXPECT_EQ(moved.image.pixel(20, 30)[0], 255);  // uncovered now
  EXPECT_EQ(moved.image.pixel(60, 30)[0], 128);  // covered now
  EXPECT_EQ(moved.stats.fragments, first.stats.fragments);
}

TEST(EmbreeReference, BadInputThrowsError) {
  WorldGeometry g;
  addQuad(g, kX0, kY0, kX1, kY1, 0.0f, addMaterial(g, glm::vec3(0.5f), 0.5f));
  FrameSettings s = orthoSettings();
  auto renderer = makeEmbreeRenderer();
  s.width = 0;
  EXPECT_THROW(renderer->render(g, s), Error);
  s = orthoSettings();

  WorldGeometry bad_index = g;
  bad_index.indices[4] = 99;
  try {
    renderer->render(bad_index, s);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 99"), std::string::npos) << e.what();
  }
  WorldGeometry bad_material = g;
  bad_material.triangle_material[1] = 7;
  EXPECT_THROW(renderer->render(bad_material, s), Error);
  // The renderer still works afterwards.
  EXPECT_EQ(renderer->render(g, s).stats.fragments, 32u * 32u);
}

}  // namespace
}  // namespace strata
