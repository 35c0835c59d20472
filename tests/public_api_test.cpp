// The public API's views, picking and outputs (include/strata/strata.h): a scene's own view, a
// look-at camera, every layer under a pixel and the objects of a rectangle, the statistics of a
// frame as fields, and saveImage writing whole files only.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "strata/strata.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

TEST(PublicApi, NaturalViewIsTheScenesOwn) {
  const Geometry spheres = Geometry::load("builtin:spheres:16");
  const View v = spheres.naturalView(64, 48);
  EXPECT_TRUE(v.orthographic);
  EXPECT_GT(v.ortho_height, 0.0f);
  EXPECT_EQ(v.width, 64);
  EXPECT_EQ(v.height, 48);
  Renderer ppll(Device::open(), "ppll");
  ppll.setGeometry(spheres);
  const Frame along = ppll.render(v);
  EXPECT_GE(along.max_depth_complexity, 16u);  // along the stack: every layer
  View across;
  across.width = 64;
  across.height = 48;
  EXPECT_LT(ppll.render(across).max_depth_complexity, 16u);
  // A mesh file has no view of its own: the orbit default, perspective.
  const View plain = Geometry::load("builtin:demo").naturalView();
  EXPECT_FALSE(plain.orthographic);
  EXPECT_EQ(plain.azimuth_deg, View{}.azimuth_deg);
  EXPECT_EQ(plain.elevation_deg, View{}.elevation_deg);
}

TEST(PublicApi, LookAtFollowsUp) {
  // A tall thin quad in the XZ plane, seen from -Y with +Z up, stands upright in the image.
  const float p[12] = {-0.1f, 0, -1, 0.1f, 0, -1, 0.1f, 0, 1, -0.1f, 0, 1};
  const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
  const Geometry quad = Geometry::fromArrays(p, 4, idx, 2, nullptr, 1.0f);
  RenderOptions o;
  o.checker_background = false;
  o.background_rgb[0] = o.background_rgb[1] = o.background_rgb[2] = 1.0f;
  Renderer opaque(Device::open(), "opaque", o);
  opaque.setGeometry(quad);
  auto extent = [&](const float up[3]) {
    const float eye[3] = {0, -4, 0}, target[3] = {0, 0, 0};
    const Frame f = opaque.render(View::lookAt(eye, target, up, 64, 64));
    int x0 = 64, x1 = -1, y0 = 64, y1 = -1;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)
        if (f.image.pixel(x, y)[0] < 200) {
          x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
        }
    return std::make_pair(x1 - x0, y1 - y0);
  };
  const float z_up[3] = {0, 0, 1}, x_up[3] = {1, 0, 0};
  const auto [w1, h1] = extent(z_up);
  EXPECT_GT(h1, 3 * w1);
  const auto [w2, h2] = extent(x_up);
  EXPECT_GT(w2, 3 * h2);
  const float eye[3] = {0, -4, 0}, target[3] = {0, 0, 0}, along[3] = {0, 1, 0};
  EXPECT_THROW(opaque.render(View::lookAt(eye, target, along, 8, 8)), Error);
  EXPECT_THROW(opaque.render(View::lookAt(eye, eye, z_up, 8, 8)), Error);
}

TEST(PublicApi, PickingEveryLayerAndRectangles) {
  Device device = Device::open();
  const Geometry spheres = Geometry::load("builtin:spheres:16");
  const View v = spheres.naturalView(64, 64);
  RenderOptions o;
  o.capture_depth_complexity = true;
  Renderer ppll(device, "ppll", o);
  ppll.setGeometry(spheres);
  const Frame f = ppll.render(v);
  const size_t deepest = size_t(
      std::max_element(f.depth_complexity.begin(), f.depth_complexity.end()) -
      f.depth_complexity.begin());
  const int x = int(deepest % 64), y = int(deepest / 64);
  Picker picker(device);
  picker.setGeometry(spheres);
  const std::vector<PickHit> hits = picker.pick(v, {{x, y}, {-1, 0}}, true);
  ASSERT_EQ(hits.size(), 2u);
  ASSERT_TRUE(hits[0].hit);
  EXPECT_FALSE(hits[1].hit);
  EXPECT_TRUE(hits[1].layers.empty());
  const std::vector<PickLayer>& layers = hits[0].layers;
  ASSERT_EQ(layers.size(), f.depth_complexity[deepest]);
  for (size_t i = 1; i < layers.size(); ++i) {
    EXPECT_LE(layers[i - 1].depth, layers[i].depth);
    EXPECT_LE(layers[i].transmittance, layers[i - 1].transmittance);
  }
  EXPECT_EQ(layers.front().object, hits[0].object);
  EXPECT_EQ(layers.front().depth, hits[0].depth);
  EXPECT_TRUE(picker.pick(v, {{x, y}})[0].layers.empty());  // the front only
  const std::vector<PickedObject> seen = picker.objectsInRect(v, 0, 0, 63, 63);
  ASSERT_FALSE(seen.empty());
  for (size_t i = 1; i < seen.size(); ++i) EXPECT_LT(seen[i - 1].object, seen[i].object);
  EXPECT_TRUE(std::any_of(seen.begin(), seen.end(),
                          [&](const PickedObject& o) { return o.object == hits[0].object; }));
  EXPECT_THROW(picker.objectsInRect(v, 10, 10, 5, 5), Error);
  EXPECT_THROW(picker.objectsInRect(v, 0, 0, 64, 10), Error);
}

TEST(PublicApi, FrameStatisticsAsFields) {
  RenderOptions o;
  o.frames = 3;
  Renderer cells(Device::open(), "cells", o);
  cells.setGeometry(Geometry::load("builtin:demo"));
  View v;
  v.width = v.height = 64;
  const Frame f = cells.render(v);
  EXPECT_GT(f.triangles, 0u);
  EXPECT_GE(f.triangles_read, f.triangles);
  EXPECT_GT(f.fragments, 0u);
  EXPECT_EQ(f.fragments_lost, 0u);
  EXPECT_GT(f.kernel_launches, 0u);
  EXPECT_LE(f.frame_ms_min, f.frame_ms);
  EXPECT_LE(f.frame_ms, f.frame_ms_max);
  EXPECT_FALSE(f.stage_ms.empty());
  EXPECT_NE(f.stats_json.find("\"fragments\":" + std::to_string(f.fragments)), std::string::npos);
}

TEST(PublicApi, SaveImageWritesWholeFilesOnly) {
  const fs::path dir = fs::path(STRATA_TEST_OUTPUT_DIR) / "public-api";
  fs::create_directories(dir);
  Image image(20, 10);
  for (size_t i = 0; i < image.rgba.size(); ++i) image.rgba[i] = uint8_t(i * 7);
  const std::string path = (dir / "saved.png").string();
  saveImage(path, image);
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 8u);
  EXPECT_EQ(bytes.substr(1, 3), "PNG");
  EXPECT_THROW(saveImage(path, Image()), Error);  // an empty image: the file is kept as it was
  std::ifstream again(path, std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(again)), std::istreambuf_iterator<char>()),
            bytes);
  EXPECT_THROW(saveImage((dir / "no-such-folder" / "x.png").string(), image), Error);
}

TEST(PublicApi, ContainersAndTypedOptions) {
  const std::vector<float> p{0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<uint32_t> idx{0, 1, 2, 1, 3, 2};
  const Geometry g = Geometry::fromArrays(p, idx, {1, 0, 0, 0.5f, 0, 0, 1, 0.5f});
  EXPECT_EQ(g.triangleCount(), 2u);
  EXPECT_THROW(Geometry::fromArrays(std::vector<float>{0, 0, 0, 1}, idx), Error);
  EXPECT_THROW(Geometry::fromArrays(p, std::vector<uint32_t>{0, 1}), Error);
  EXPECT_THROW(Geometry::fromArrays(p, idx, {1, 0, 0}), Error);
  // Every option's name goes there and back; an unknown one names itself.
  for (const char* n : {"none", "static", "instanced", "auto"})
    EXPECT_STREQ(optionName(parseBatch(n)), n);
  for (const char* n : {"none", "material", "depth", "gray", "key"})
    EXPECT_STREQ(optionName(parseDrawSort(n)), n);
  for (const char* n : {"off", "uniform", "packed"}) EXPECT_STREQ(optionName(parseAtlasChoice(n)), n);
  for (const char* n : {"strict", "paper"}) EXPECT_STREQ(optionName(parseDecomposeMode(n)), n);
  for (const char* n : {"auto", "group", "serial"}) EXPECT_STREQ(optionName(parseTileKernels(n)), n);
  try {
    parseDrawSort("grey");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'grey'"), std::string::npos);
  }
  // Typed options reach the frame: the statistics name them.
  RenderOptions o;
  o.batch = Batch::None;
  o.sort = DrawSort::Material;
  o.tile_kernels = TileKernels::Serial;
  Renderer ppll(Device::open(), "ppll", o);
  ppll.setGeometry(Geometry::load("builtin:crowd:20"));
  View v;
  v.width = v.height = 48;
  const std::string stats = ppll.render(v).stats_json;
  EXPECT_NE(stats.find("\"batch\":\"none\""), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"sort\":\"material\""), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"tile_kernels\":\"serial\""), std::string::npos) << stats;
}

}  // namespace
}  // namespace strata
