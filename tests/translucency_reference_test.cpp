// The Embree reference's translucency effect (the rule of strata_shared.h) against answers
// worked out by hand: Schlick reflection at each hit, Beer-Lambert absorption between a
// front-facing (entering) hit and the back-facing hit that leaves, and the rasterizer's facing
// convention (counter-clockwise seen from the viewer is front-facing).
#include "engine/reference/embree_reference.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/scene/world_geometry.h"
#include "test_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

using namespace test;  // test_geometry.h

constexpr int kSize = 64;
const glm::vec3 kBackground(0.9f, 0.8f, 0.7f);
const glm::vec3 kColor(0.2f, 0.5f, 0.1f);

// Looks down -z from z = 5; the view is 2 x 2 world units, so pixel centre x maps to world
// x = (x + 0.5) / 32 - 1 and row y to world y = 1 - (y + 0.5) / 32.
FrameSettings orthoSettings(float sigma) {
  FrameSettings s = test::orthoTopDown(kSize, kBackground);
  s.effect = Effect::Translucency;
  s.sigma = sigma;
  return s;
}

// Pixel (40, 28): world (0.265625, 0.109375), off every edge and face diagonal used below.
constexpr int kPx = 40, kPy = 28;

// Flat shading of a face whose normal is +-z, from the shared rule.
glm::vec3 faceShade(const FrameSettings& s, glm::vec3 color) {
  return color * st_diffuse_factor(glm::dot(glm::vec3(0, 0, 1), s.camera.lightDirection()));
}

uint8_t unorm8(double v) { return uint8_t(std::floor(std::clamp(v, 0.0, 1.0) * 255.0 + 0.5)); }

RenderResult render(const WorldGeometry& g, const FrameSettings& s,
                    EmbreeQuery query = EmbreeQuery::Auto) {
  EmbreeOptions o;
  o.query = query;
  return makeEmbreeRenderer(o)->render(g, s);
}

void expectPixel(const Image& im, int x, int y, glm::dvec3 expected, const char* what) {
  const uint8_t* p = im.pixel(x, y);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(int(p[c]), int(unorm8(expected[c])), 1)
        << what << " channel " << c << " expected " << expected[c] * 255.0;
}

// Head-on through a slab: front face, `thickness` of medium, back face, background.
glm::dvec3 slabPixel(const FrameSettings& s, double thickness) {
  const double r0 = ST_FRESNEL_F0;
  const glm::dvec3 shade(faceShade(s, kColor)), bg(kBackground);
  return r0 * shade +
         (1.0 - r0) * std::exp(-double(s.sigma) * thickness) * (r0 * shade + (1.0 - r0) * bg);
}

TEST(TranslucencyReference, SingleFrontFacingTriangleReflectsAndTransmits) {
  WorldGeometry g;
  const uint32_t m = addMaterial(g, kColor, 0.3f);
  // Counter-clockwise seen from +z: its winding normal points at the camera.
  g.positions = {{-0.6f, -0.5f, 0.0f}, {0.7f, -0.4f, 0.0f}, {0.1f, 0.6f, 0.0f}};
  addTriangle(g, 0, 1, 2, m);
  const FrameSettings s = orthoSettings(3.0f);
  const RenderResult r = render(g, s);
  const double r0 = st_schlick_reflectance(1.0f);
  EXPECT_FLOAT_EQ(float(r0), ST_FRESNEL_F0);
  const glm::dvec3 expected =
      r0 * glm::dvec3(faceShade(s, kColor)) + (1.0 - r0) * glm::dvec3(kBackground);
  expectPixel(r.image, 32, 32, expected, "triangle");
  expectPixel(r.image, 1, 1, glm::dvec3(kBackground), "background");
  EXPECT_EQ(r.image.pixel(1, 1)[3], 255);
  // Opacity does not enter translucency.
  WorldGeometry opaque = g;
  opaque.material_colors[0].a = 1.0f;
  EXPECT_EQ(render(opaque, s).image.rgba, r.image.rgba);
}

// The facing convention: a slab of two quads absorbs only when the near one is wound
// counter-clockwise towards the camera (entering) and the far one away from it (leaving).
TEST(TranslucencyReference, FacingFollowsTheRasterizerWinding) {
  const FrameSettings s = orthoSettings(2.0f);
  const double r0 = ST_FRESNEL_F0;
  const glm::dvec3 shade(faceShade(s, kColor)), bg(kBackground);
  const glm::dvec3 no_absorption = r0 * shade + (1.0 - r0) * (r0 * shade + (1.0 - r0) * bg);
  for (int near_flip = 0; near_flip < 2; ++near_flip) {
    for (int far_flip = 0; far_flip < 2; ++far_flip) {
      WorldGeometry g;
      const uint32_t m = addMaterial(g, kColor, 0.5f);
      addQuad(g, -0.53f, -0.45f, 0.47f, 0.55f, 0.4f, m, near_flip != 0);
      // The far quad faces away from the camera when wound counter-clockwise seen from -z.
      addQuad(g, -0.53f, -0.45f, 0.47f, 0.55f, -0.4f, m, far_flip == 0);
      const RenderResult r = render(g, s);
      // Inside only between an entering near quad and a far quad (of either facing: a
      // front-facing far quad enters again, with nothing behind it).
      const glm::dvec3 expected = near_flip ? no_absorption : slabPixel(s, 0.8);
      expectPixel(r.image, kPx, kPy, expected,
                  near_flip ? "near back-facing" : "near front-facing");
    }
  }
}

TEST(TranslucencyReference, ClosedBoxHeadOnAbsorbsAlongItsThickness) {
  std::vector<int> values;
  for (const double thickness : {0.5, 1.0, 1.5}) {
    for (const float sigma : {0.5f, 2.0f}) {
      WorldGeometry g;
      addBox(g, {-0.5f, -0.5f, -float(thickness) / 2}, {0.5f, 0.5f, float(thickness) / 2},
             addMaterial(g, kColor, 0.5f));
      const FrameSettings s = orthoSettings(sigma);
      const RenderResult r = render(g, s);
      expectPixel(r.image, kPx, kPy, slabPixel(s, thickness), "box");
      values.push_back(r.image.pixel(kPx, kPy)[0]);  // red: the background dominates it
    }
  }
  // values: (t 0.5, s 0.5), (0.5, 2), (1, 0.5), (1, 2), (1.5, 0.5), (1.5, 2).
  EXPECT_GT(values[0], values[1]);
  EXPECT_GT(values[2], values[3]);
  EXPECT_GT(values[4], values[5]);
  EXPECT_GT(values[0], values[2]);
  EXPECT_GT(values[2], values[4]);
  EXPECT_GT(values[1], values[3]);
  EXPECT_GT(values[3], values[5]);
}

// In perspective the path length is the distance along the (oblique) ray, not the view-depth
// difference, and the reflectance uses the ray's own angle with the face.
TEST(TranslucencyReference, PerspectivePathLengthIsAlongTheRay) {
  WorldGeometry g;
  const float h = 1.0f;
  addBox(g, {-4.0f, -4.0f, -h / 2}, {4.0f, 4.0f, h / 2}, addMaterial(g, kColor, 0.5f));
  FrameSettings s = orthoSettings(1.5f);
  s.camera.projection = Projection::Perspective;
  s.camera.fov_y_deg = 60.0f;
  const RenderResult r = render(g, s);
  for (const int px : {32, 50, 60}) {
    const int py = 9;
    glm::vec3 org, dir;
    s.camera.pixelRay(px, py, kSize, kSize, org, dir);
    const double c = std::abs(dir.z);
    const double refl = st_schlick_reflectance(float(c));
    const glm::dvec3 shade(faceShade(s, kColor)), bg(kBackground);
    const double path = h / c;
    const glm::dvec3 expected = refl * shade + (1.0 - refl) * std::exp(-double(s.sigma) * path) *
                                                   (refl * shade + (1.0 - refl) * bg);
    expectPixel(r.image, px, py, expected, "perspective");
  }
}

TEST(TranslucencyReference, ZeroSigmaDiffersFromTransparencyAndIsDeterministic) {
  WorldGeometry g;
  addSphere(g, {0.1f, -0.05f, 0.0f}, 0.7f, 24, 12, addMaterial(g, kColor, 0.5f));
  addBox(g, {-0.8f, -0.3f, -0.9f}, {0.2f, 0.4f, 0.3f}, addMaterial(g, {0.9f, 0.2f, 0.3f}, 0.4f));
  FrameSettings s = orthoSettings(0.0f);
  const RenderResult a = render(g, s);
  const RenderResult b = render(g, s);
  EXPECT_EQ(a.image.rgba, b.image.rgba);
  FrameSettings t = s;
  t.effect = Effect::Transparency;
  const RenderResult transparent = render(g, t);
  EXPECT_NE(a.image.rgba, transparent.image.rgba);
  EXPECT_EQ(a.stats.fragments, transparent.stats.fragments);
  // Every query kind gives the same image, with and without absorption.
  for (const float sigma : {0.0f, 1.7f}) {
    s.sigma = sigma;
    const RenderResult ref = render(g, s, EmbreeQuery::Single);
    for (const EmbreeQuery q :
         {EmbreeQuery::Packet4, EmbreeQuery::Packet8, EmbreeQuery::Packet16, EmbreeQuery::Stream}) {
      const RenderResult r = render(g, s, q);
      EXPECT_EQ(r.image.rgba, ref.image.rgba) << "query " << int(q) << " sigma " << sigma;
    }
  }
  // The opaque mode ignores the effect.
  EmbreeOptions o;
  o.mode = EmbreeMode::Opaque;
  FrameSettings opaque_t = t;
  EXPECT_EQ(makeEmbreeRenderer(o)->render(g, s).image.rgba,
            makeEmbreeRenderer(o)->render(g, opaque_t).image.rgba);
}

// Inward-wound box: the near face is back-facing (inside stays 0), the far face enters with
// nothing behind it, so nothing is absorbed whatever sigma is; no NaN anywhere.
TEST(TranslucencyReference, InwardWoundBoxAbsorbsNothing) {
  WorldGeometry g;
  addBox(g, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}, addMaterial(g, kColor, 0.5f), true);
  const double r0 = ST_FRESNEL_F0;
  for (const float sigma : {0.0f, 4.0f}) {
    const FrameSettings s = orthoSettings(sigma);
    const RenderResult r = render(g, s);
    const glm::dvec3 shade(faceShade(s, kColor)), bg(kBackground);
    expectPixel(r.image, kPx, kPy, r0 * shade + (1.0 - r0) * (r0 * shade + (1.0 - r0) * bg),
                "inward box");
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x) {
        const uint8_t* p = r.image.pixel(x, y);
        // A NaN would come out as 0 or garbage; every pixel lies between the darkest possible
        // value and the background.
        for (int c = 0; c < 3; ++c) EXPECT_GE(int(p[c]), 10) << x << "," << y;
      }
  }
  // A perspective view from inside the inward box and through a sphere: finite, deterministic.
  addSphere(g, {0.0f, 0.0f, -2.0f}, 0.6f, 16, 8, addMaterial(g, {0.3f, 0.3f, 0.9f}, 0.5f));
  FrameSettings s = orthoSettings(2.0f);
  s.camera = Camera::lookAt({0.0f, 0.1f, 0.2f}, {0.0f, 0.0f, -2.0f});
  const RenderResult a = render(g, s);
  EXPECT_EQ(a.image.rgba, render(g, s).image.rgba);
}

TEST(TranslucencyReference, BadSigmaThrows) {
  WorldGeometry g;
  addBox(g, {-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}, addMaterial(g, kColor, 0.5f));
  for (const float sigma : {-1.0f, std::nanf(""), INFINITY}) {
    FrameSettings s = orthoSettings(sigma);
    EXPECT_THROW(render(g, s), Error) << sigma;
    s.effect = Effect::Transparency;  // sigma is not read
    EXPECT_NO_THROW(render(g, s));
  }
}

}  // namespace
}  // namespace strata
