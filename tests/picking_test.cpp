// ID picking (engine/features/picking.h) against Embree ray picks (EmbreeRayPicker): the front-most object
// and triangle, and with all layers every fragment along the pixel's ray in order, on every shared
// model and on a crowd of a few hundred objects; ids above 2^24; pixels outside the image and on
// the background; the objects of a rectangle.
#include "engine/features/picking.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "engine/reference/embree_reference.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/scene/world_geometry.h"
#include "test_support.h"

namespace strata {
namespace {

constexpr uint32_t kNone = 0xFFFFFFFFu;

// A crowd of spheres and tori (alternating, tori tilted) on a cols x rows x layers grid, object
// ids first_id, first_id + 1, ... in instance order, transparent so every layer matters.
Scene crowdScene(int cols, int rows, int layers, uint32_t first_id) {
  Scene s;
  s.source = "test:crowd";
  Mesh sphere = makeUvSphere(0.42f, 16, 10);
  sphere.material = 0;
  Mesh torus = makeTorus(0.34f, 0.11f, 24, 10);
  torus.material = 1;
  s.meshes = {sphere, torus};
  Material a, b;
  a.name = "blue";
  a.color = {0.3f, 0.5f, 0.9f, 1.0f};
  a.opacity = 0.4f;
  b.name = "amber";
  b.color = {0.95f, 0.7f, 0.2f, 1.0f};
  b.opacity = 0.6f;
  s.materials = {a, b};
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> angle(0.0f, 6.2831853f);
  int k = 0;
  for (int z = 0; z < layers; ++z)
    for (int y = 0; y < rows; ++y)
      for (int x = 0; x < cols; ++x, ++k) {
        Instance inst;
        inst.mesh = uint32_t(k % 2);
        glm::mat4 m = glm::translate(glm::mat4(1.0f), {x - 0.5f * (cols - 1), y - 0.5f * (rows - 1),
                                                       0.9f * (z - 0.5f * (layers - 1))});
        m = glm::rotate(m, angle(rng), glm::normalize(glm::vec3(0.3f, 1.0f, 0.5f)));
        if (k % 2) m = glm::rotate(m, 1.0f + angle(rng) * 0.2f, glm::vec3(1.0f, 0.0f, 0.0f));
        inst.transform = m;
        inst.object_id = first_id + uint32_t(k);
        inst.name = (k % 2 ? "torus " : "sphere ") + std::to_string(k);
        s.instances.push_back(inst);
      }
  return s;
}

std::vector<glm::ivec2> randomPixels(int width, int height, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1);
  std::vector<glm::ivec2> out;
  for (int i = 0; i < count; ++i) out.emplace_back(x(rng), y(rng));
  return out;
}

// `count` random pixels on which an Embree ray finds something (so every one tests a pick).
std::vector<glm::ivec2> pixelsOnModel(const WorldGeometry& g, const FrameSettings& s, int count,
                                      unsigned seed, EmbreeRayPicker& reference) {
  std::vector<glm::ivec2> out;
  for (unsigned round = 0; int(out.size()) < count && round < 50; ++round) {
    const std::vector<glm::ivec2> candidates =
        randomPixels(s.width, s.height, 4 * count, seed + round);
    const auto hits = reference.pick(g, s, candidates, false);
    for (size_t i = 0; i < candidates.size() && int(out.size()) < count; ++i)
      if (!hits[i].empty()) out.push_back(candidates[i]);
  }
  EXPECT_EQ(int(out.size()), count) << "the model covers too few pixels";
  return out;
}

// Picks and ray picks may disagree only where the pixel centre lies on (within float error of)
// a triangle's edge: the rasterizer snaps vertices to 1/256 pixel and applies its fill rule,
// Embree's watertight test includes edges. Every disagreement seen on the test models lies
// within 1/512 pixel of an edge; the tests excuse a disagreement only within this distance, far
// inside the "within a pixel of a silhouette or shared edge" allowance.
constexpr float kEdgeRadius = 1.0f / 64.0f;

// Whether the centre of `pixel` lies within `radius` pixels of one of the triangle's projected
// edges (a silhouette or an edge shared with a neighbour); a triangle reaching behind the near
// plane counts as near (its projection is clipped).
bool nearEdge(const WorldGeometry& g, const FrameSettings& s, glm::ivec2 pixel, uint32_t tri,
              float radius = kEdgeRadius) {
  const glm::mat4 vp =
      s.camera.projectionMatrix(float(s.width) / float(s.height)) * s.camera.viewMatrix();
  glm::vec2 p[3];
  for (int k = 0; k < 3; ++k) {
    const glm::vec4 c = vp * glm::vec4(g.positions[g.indices[3 * size_t(tri) + k]], 1.0f);
    if (c.w <= s.camera.near_distance * 0.5f) return true;
    p[k] = {(c.x / c.w * 0.5f + 0.5f) * s.width, (0.5f - c.y / c.w * 0.5f) * s.height};
  }
  const glm::vec2 q(pixel.x + 0.5f, pixel.y + 0.5f);
  for (int k = 0; k < 3; ++k) {
    const glm::vec2 a = p[k], b = p[(k + 1) % 3];
    const glm::vec2 ab = b - a;
    const float len2 = glm::dot(ab, ab);
    const float t = len2 > 0.0f ? std::clamp(glm::dot(q - a, ab) / len2, 0.0f, 1.0f) : 0.0f;
    if (glm::length(q - (a + t * ab)) <= radius) return true;
  }
  return false;
}

struct Comparison {
  int pixels = 0;
  int hits = 0;             // pixels where Embree hits something
  int layers = 0;           // Embree hits over all pixels
  int front_differ = 0;     // front-most triangle differs
  int front_unexcused = 0;  // ... and no involved triangle has an edge within a pixel
  int layers_differ = 0;    // the hit lists differ
  int layers_unexcused = 0;
  double max_depth_error = 0.0;  // largest |depth - ray hit depth| / depth of matching fronts
  std::vector<std::string> details;
};

std::string listText(const std::vector<uint32_t>& v) {
  std::ostringstream o;
  for (size_t i = 0; i < v.size(); ++i) o << (i ? "," : "") << v[i];
  return o.str();
}

// Compares the picker with Embree ray picks at `pixels`. The front-most triangles may differ only
// where one of them has an edge through the pixel centre (nearEdge); the layer lists only by such
// triangles: removing those, the lists must be identical, order included.
Comparison compare(const std::string& name, const WorldGeometry& g, const FrameSettings& s,
                   const std::vector<glm::ivec2>& pixels, bool all_layers, IdPicker& picker,
                   EmbreeRayPicker& reference) {
  const PickResult got = picker.pick(g, s, pixels, all_layers);
  const auto want = reference.pick(g, s, pixels, all_layers);
  EXPECT_EQ(got.pixels.size(), pixels.size());
  Comparison c;
  c.pixels = int(pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) {
    const PickedPixel& p = got.pixels[i];
    const std::vector<EmbreeRayHit>& hits = want[i];
    EXPECT_EQ(p.pixel, pixels[i]);
    c.hits += hits.empty() ? 0 : 1;
    c.layers += int(hits.size());
    const uint32_t got_front = p.status == PickStatus::Hit ? p.front.triangle : kNone;
    const uint32_t want_front = hits.empty() ? kNone : hits[0].triangle;
    EXPECT_NE(p.status, PickStatus::OutsideImage);
    if (got_front != want_front) {
      ++c.front_differ;
      const bool excused = (got_front != kNone && nearEdge(g, s, pixels[i], got_front)) ||
                           (want_front != kNone && nearEdge(g, s, pixels[i], want_front));
      if (!excused) {
        ++c.front_unexcused;
        c.details.push_back(name + " front at " + std::to_string(pixels[i].x) + "," +
                            std::to_string(pixels[i].y) + ": picked " + std::to_string(got_front) +
                            ", embree " + std::to_string(want_front));
      }
    } else if (got_front != kNone) {
      // Same triangle: same object, and the depth and position of the ray's hit (up to the
      // rasterizer's vertex snapping to 1/256 pixel, which moves the depth of a triangle seen at
      // a grazing angle by up to about 1e-3 of the distance).
      const PickFragment& f = p.front;
      EXPECT_EQ(f.object, g.triangle_object[got_front]);
      EXPECT_NEAR(f.depth, hits[0].depth, 2e-3f * hits[0].depth) << name;
      c.max_depth_error =
          std::max(c.max_depth_error, std::abs(double(f.depth) - hits[0].depth) / hits[0].depth);
      glm::vec3 org, dir;
      s.camera.pixelRay(pixels[i].x, pixels[i].y, s.width, s.height, org, dir);
      const glm::vec3 hit = org + hits[0].t * dir;
      EXPECT_LE(glm::length(f.position - hit), 2e-3f * (hits[0].t + glm::length(org)) + 1e-5f)
          << name << " position at " << pixels[i].x << "," << pixels[i].y;
      EXPECT_NEAR(glm::length(f.normal), 1.0f, 1e-4f);
      EXPECT_EQ(f.front_facing, glm::dot(f.normal, dir) < 0.0f);
      EXPECT_EQ(f.transmittance, 1.0f);
    }
    if (!all_layers) {
      EXPECT_TRUE(p.layers.empty());
      continue;
    }
    std::vector<uint32_t> a, b;
    for (const PickFragment& f : p.layers) a.push_back(f.triangle);
    for (const EmbreeRayHit& h : hits) b.push_back(h.triangle);
    // The front of the layers is the front-most fragment; transmittance accumulates.
    if (!p.layers.empty()) {
      EXPECT_EQ(p.layers[0].triangle, got_front);
      float t = 1.0f;
      for (const PickFragment& f : p.layers) {
        EXPECT_FLOAT_EQ(f.transmittance, t);
        EXPECT_EQ(f.object, g.triangle_object[f.triangle]);
        t *= 1.0f - f.opacity;
      }
    } else {
      EXPECT_EQ(p.status, PickStatus::Background);
    }
    if (a == b) continue;
    ++c.layers_differ;
    std::vector<uint32_t> ka, kb;
    for (uint32_t t : a)
      if (!nearEdge(g, s, pixels[i], t)) ka.push_back(t);
    for (uint32_t t : b)
      if (!nearEdge(g, s, pixels[i], t)) kb.push_back(t);
    if (ka != kb) {
      ++c.layers_unexcused;
      c.details.push_back(name + " layers at " + std::to_string(pixels[i].x) + "," +
                          std::to_string(pixels[i].y) + ": picked [" + listText(a) + "], embree [" +
                          listText(b) + "]");
    }
  }
  return c;
}

// Front-most picks: all but 0.5% of the pixels agree, every disagreement on an edge.
void expectAgreement(const std::string& name, const Comparison& c, bool all_layers) {
  const double limit = 0.005 * c.pixels;
  std::printf(
      "[ picking  ] %-34s %4d pixels, %4d hit, %5d layers; front differs %d (%d off "
      "edges)%s; depth error <= %.1e\n",
      name.c_str(), c.pixels, c.hits, c.layers, c.front_differ, c.front_unexcused,
      all_layers ? (", layers differ " + std::to_string(c.layers_differ) + " (" +
                    std::to_string(c.layers_unexcused) + " off edges)")
                       .c_str()
                 : "",
      c.max_depth_error);
  EXPECT_EQ(c.front_unexcused, 0) << name;
  EXPECT_LE(c.front_differ, limit) << name;
  if (all_layers) {
    // Each fragment on the ray has its own chance of lying on an edge: at most 0.5% of the
    // fragments' rays may differ.
    EXPECT_EQ(c.layers_unexcused, 0) << name;
    EXPECT_LE(c.layers_differ, 0.005 * std::max(c.layers, c.pixels)) << name;
  }
  for (size_t i = 0; i < c.details.size() && i < 10; ++i) ADD_FAILURE() << c.details[i];
  EXPECT_GT(c.hits, c.pixels / 8) << name << ": too few pixels on the model to test anything";
}

IdPicker& sharedPicker() {
  static IdPicker picker;
  return picker;
}

EmbreeRayPicker& sharedReference() {
  static EmbreeRayPicker reference;
  return reference;
}

const char* const kModels[] = {"teapot.obj",  "horse.ply",      "stanford-bunny.obj",
                               "fandisk.obj", "rocker-arm.obj", "cheburashka.obj",
                               "homer.obj",   "cow.obj",        "spot.obj"};

TEST(Picking, ModelsMatchEmbreeRayPicks) {
  for (const char* model : kModels) {
    SCOPED_TRACE(model);
    const auto [scene, g] = test::sceneAndGeometry(test::modelPath(model));
    FrameSettings s = test::settingsFor(scene, 768, 30.0f, 20.0f);
    // 1000 pixels on the model, and 1000 anywhere (background and silhouettes too).
    const std::vector<glm::ivec2> on = pixelsOnModel(g, s, 1000, 11, sharedReference());
    const std::vector<glm::ivec2> anywhere = randomPixels(s.width, s.height, 1000, 12);
    expectAgreement(std::string(model) + " layers",
                    compare(model, g, s, on, true, sharedPicker(), sharedReference()), true);
    expectAgreement(std::string(model) + " layers, anywhere",
                    compare(model, g, s, anywhere, true, sharedPicker(), sharedReference()), true);
    // Front-most only (the visibility buffer alone), from another side, orthographic.
    OrbitView v;
    v.azimuth_deg = 200.0f;
    v.elevation_deg = -25.0f;
    s.camera = Camera::orbit(scene.boundingSphere(), v, Projection::Orthographic);
    const std::vector<glm::ivec2> on_ortho = pixelsOnModel(g, s, 1000, 13, sharedReference());
    expectAgreement(std::string(model) + " front, ortho",
                    compare(model, g, s, on_ortho, false, sharedPicker(), sharedReference()),
                    false);
  }
}

TEST(Picking, CrowdMatchesEmbreeRayPicks) {
  const Scene scene = crowdScene(12, 10, 3, 0);  // 360 objects
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  for (float az : {0.0f, 35.0f}) {
    FrameSettings s = test::settingsFor(scene, 512, az, 15.0f);
    OrbitView v{az, 15.0f, 1.45f, std::nullopt};  // close: the grid fills most of the image
    s.camera = Camera::orbit(scene.boundingSphere(), v);
    const std::vector<glm::ivec2> pixels =
        pixelsOnModel(g, s, 1000, 5 + unsigned(az), sharedReference());
    const std::string name = "crowd:360 az " + std::to_string(int(az));
    const Comparison c = compare(name, g, s, pixels, true, sharedPicker(), sharedReference());
    expectAgreement(name, c, true);
    EXPECT_GT(c.layers, 2 * c.hits) << "the crowd should be several layers deep";
  }
}

TEST(Picking, ObjectIdsAbove2To24) {
  const uint32_t first = (1u << 24) + 5;  // 16777221: not representable in a float
  const Scene scene = crowdScene(8, 6, 2, first);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const ObjectNames names = objectNames(scene);
  FrameSettings s = test::settingsFor(scene, 256, 10.0f, 10.0f);
  const std::vector<glm::ivec2> pixels = pixelsOnModel(g, s, 1000, 3, sharedReference());
  const Comparison c =
      compare("crowd ids from 2^24+5", g, s, pixels, true, sharedPicker(), sharedReference());
  expectAgreement("crowd ids from 2^24+5", c, true);

  const PickResult r = sharedPicker().pick(g, s, pixels, true, &names);
  std::set<uint32_t> seen;
  for (const PickedPixel& p : r.pixels) {
    if (p.status != PickStatus::Hit) continue;
    const uint32_t id = p.front.object;
    seen.insert(id);
    ASSERT_GE(id, first);
    ASSERT_LT(id, first + 96);
    const int k = int(id - first);
    EXPECT_EQ(p.front.name, (k % 2 ? "torus " : "sphere ") + std::to_string(k));
    for (const PickFragment& f : p.layers) EXPECT_EQ(f.name, names.at(f.object));
  }
  // Odd ids above 2^24 would be rounded by a float ID buffer: they must come back exact.
  EXPECT_TRUE(std::any_of(seen.begin(), seen.end(), [](uint32_t id) { return id % 2 == 1; }));
  EXPECT_GT(seen.size(), 20u);

  // The rectangle query names the same exact ids.
  sharedPicker().update(g, s, false);
  const std::vector<uint32_t> all = sharedPicker().objectsInRect({0, 0, s.width - 1, s.height - 1});
  ASSERT_FALSE(all.empty());
  for (uint32_t id : all) {
    EXPECT_GE(id, first);
    EXPECT_LT(id, first + 96);
  }
  for (uint32_t id : seen) EXPECT_TRUE(std::binary_search(all.begin(), all.end(), id)) << id;
}

TEST(Picking, OutsideAndBackgroundPixels) {
  const Scene scene = crowdScene(1, 1, 1, 0);  // one sphere: the centre sees it, the corners not
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  FrameSettings s = test::settingsFor(scene, 200, 0.0f, 0.0f);
  s.height = 150;
  const std::vector<glm::ivec2> pixels = {{-1, 10},       {10, -1}, {200, 10},  {10, 150},
                                          {-5000, 99999}, {0, 0},   {199, 149}, {100, 75}};
  for (bool layers : {false, true}) {
    const PickResult r = sharedPicker().pick(g, s, pixels, layers);
    ASSERT_EQ(r.pixels.size(), pixels.size());
    for (int i = 0; i < 5; ++i) {
      EXPECT_EQ(r.pixels[size_t(i)].status, PickStatus::OutsideImage) << i;
      EXPECT_TRUE(r.pixels[size_t(i)].layers.empty());
    }
    const auto want = sharedReference().pick(g, s, pixels, true);
    for (int i = 0; i < 5; ++i) EXPECT_TRUE(want[size_t(i)].empty());
    // Corners of this view are background for both; the centre sees an object.
    for (int i : {5, 6}) {
      EXPECT_TRUE(want[size_t(i)].empty());
      EXPECT_EQ(r.pixels[size_t(i)].status, PickStatus::Background);
      EXPECT_TRUE(r.pixels[size_t(i)].layers.empty());
    }
    EXPECT_EQ(r.pixels[7].status, PickStatus::Hit);
  }
  EXPECT_STREQ(pickStatusName(PickStatus::OutsideImage), "outside image");
  EXPECT_STREQ(pickStatusName(PickStatus::Background), "background");
  // An empty request, and rectangles that are not inside the image.
  EXPECT_TRUE(sharedPicker().pick({}).pixels.empty());
  EXPECT_THROW(sharedPicker().objectsInRect({-1, 0, 5, 5}), Error);
  EXPECT_THROW(sharedPicker().objectsInRect({0, 0, 200, 5}), Error);
  EXPECT_THROW(sharedPicker().objectsInRect({5, 5, 4, 6}), Error);
  EXPECT_TRUE(sharedPicker().objectsInRect({0, 0, 3, 3}).empty());  // background corner
  // No frame yet.
  IdPicker fresh;
  EXPECT_THROW(fresh.pick({glm::ivec2(1, 1)}), Error);
  EXPECT_THROW(fresh.objectsInRect({0, 0, 1, 1}), Error);
}

TEST(Picking, RectangleListsTheFrontMostObjects) {
  const Scene scene = crowdScene(12, 10, 3, 1000);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const FrameSettings s = test::settingsFor(scene, 320, 20.0f, 10.0f);
  IdPicker& picker = sharedPicker();
  for (bool layers : {false, true}) {
    picker.update(g, s, layers);
    for (const PickRect& rect : {PickRect{0, 0, 319, 319}, PickRect{100, 120, 180, 170},
                                 PickRect{160, 160, 160, 160}, PickRect{7, 30, 60, 300}}) {
      std::vector<glm::ivec2> pixels;
      for (int y = rect.y0; y <= rect.y1; ++y)
        for (int x = rect.x0; x <= rect.x1; ++x) pixels.emplace_back(x, y);
      std::set<uint32_t> want;
      for (const PickedPixel& p : picker.pick(pixels).pixels)
        if (p.status == PickStatus::Hit) want.insert(p.front.object);
      const std::vector<uint32_t> got = picker.objectsInRect(rect);
      EXPECT_EQ(got, std::vector<uint32_t>(want.begin(), want.end()))
          << rect.x0 << "," << rect.y0 << "," << rect.x1 << "," << rect.y1;
    }
    EXPECT_GT(picker.objectsInRect({0, 0, 319, 319}).size(), 100u);
  }
}

TEST(Picking, EmbreePickRayOneCall) {
  const Scene scene = crowdScene(2, 1, 1, 42);
  const WorldGeometry g = WorldGeometry::fromScene(scene);
  const FrameSettings s = test::settingsFor(scene, 64, 0.0f, 0.0f);
  const std::vector<EmbreeRayHit> all = embreePickRay(g, s, 16, 32, true);
  const std::vector<EmbreeRayHit> front = embreePickRay(g, s, 16, 32, false);
  ASSERT_GE(all.size(), 2u);  // through the sphere: in and out
  ASSERT_EQ(front.size(), 1u);
  EXPECT_EQ(front[0].triangle, all[0].triangle);
  for (size_t i = 1; i < all.size(); ++i) EXPECT_GE(all[i].t, all[i - 1].t);
  EXPECT_TRUE(embreePickRay(g, s, -1, 0, true).empty());
}

// Pick latency against the Embree ray pick, side by side in one run (a report, not a check):
//   ./strata_tests --gtest_also_run_disabled_tests --gtest_filter='*PickingLatency*'
// Median wall time of `reps` calls after a warm-up call.
double msOf(const std::function<void()>& f, int reps) {
  f();
  std::vector<double> ms;
  for (int i = 0; i < reps; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(ms.begin(), ms.end());
  return ms[ms.size() / 2];
}

TEST(Picking, DISABLED_PickingLatency) {
  struct Case {
    std::string name;
    Scene scene;
  };
  std::vector<Case> cases;
  cases.push_back({"horse.ply", loadScene(test::modelPath("horse.ply"))});
  cases.push_back({"crowd:1000", crowdScene(20, 10, 5, 0)});
  const int size = 1024;
  std::printf("%-12s %-6s %6s | %11s %11s %11s | %11s %11s | %9s %9s %9s\n", "scene", "layers",
              "points", "gpu_frame", "gpu_gather", "gpu_total", "embree_ray", "embree_bvh",
              "tot/ray", "gath/ray", "tot/cold");
  for (Case& c : cases) {
    const WorldGeometry g = WorldGeometry::fromScene(c.scene);
    const FrameSettings s = test::settingsFor(c.scene, size, 30.0f, 20.0f);
    IdPicker picker;
    EmbreeRayPicker reference;
    for (bool layers : {false, true}) {
      for (int n : {1, 100, 10000}) {
        const std::vector<glm::ivec2> pixels = randomPixels(size, size, n, 99);
        const int reps = 7;
        const double frame = msOf([&] { picker.update(g, s, layers); }, reps);
        const double gather = msOf([&] { picker.pick(pixels); }, reps);
        const double total = msOf([&] { picker.pick(g, s, pixels, layers); }, reps);
        const double ray = msOf([&] { reference.pick(g, s, pixels, layers); }, reps);
        const double cold = msOf(
            [&] {
              EmbreeRayPicker fresh;
              fresh.pick(g, s, pixels, layers);
            },
            3);
        std::printf(
            "%-12s %-6s %6d | %9.3fms %9.3fms %9.3fms | %9.3fms %9.3fms | %9.2f %9.3f %9.3f\n",
            c.name.c_str(), layers ? "all" : "front", n, frame, gather, total, ray, cold,
            total / ray, gather / ray, total / cold);
      }
    }
  }
  std::printf("device: %s; embree: %u threads\n", IdPicker().device().c_str(),
              std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace
}  // namespace strata
