// glTF 1.0 loading (preprocess/gltf1_loader.h): assimp's glTF 1.0 test files, a binary glTF 1.0
// built from one of them, small hand-made files whose contents are known, and malformed copies
// written under the test output folder.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include <glm/glm.hpp>
#include <nlohmann/json.hpp>

#include "engine/renderer.h"
#include "preprocess/gltf1_loader.h"
#include "preprocess/image_io.h"
#include "preprocess/scene/camera.h"
#include "preprocess/scene/world_geometry.h"
#include "test_support.h"

namespace {

using strata::test::readBytes;
using strata::test::writeBytes;

namespace fs = std::filesystem;
using json = nlohmann::json;
using strata::Error;
using strata::Mesh;
using strata::Scene;
using strata::loader::isGltf1File;
using strata::loader::loadGltf1;

using strata::test::assimpPath;

// A fresh folder per test, for the malformed copies.
std::string outDir() { return strata::test::freshTestDir("gltf1").string(); }

const std::string kTruck = "glTF/CesiumMilkTruck/CesiumMilkTruck.gltf";

json readJson(const std::string& path) { return json::parse(readBytes(path)); }

std::string loadOrError(const std::string& path) {
  return strata::test::errorOf([&] { loadGltf1(path); });
}

void expectError(const std::string& path, const std::string& fragment) {
  strata::test::expectLoadError(path, loadOrError(path), fragment);
}

// Whatever a loaded scene is, it must be drawable: valid references, finite kept triangles.
void expectConsistent(const Scene& scene) {
  ASSERT_FALSE(scene.instances.empty());
  EXPECT_GT(scene.triangleCount(), 0u);
  for (const Mesh& mesh : scene.meshes) {
    EXPECT_EQ(mesh.indices.size() % 3, 0u);
    EXPECT_LT(mesh.material, scene.materials.size());
    EXPECT_TRUE(mesh.texcoords.empty() || mesh.texcoords.size() == mesh.positions.size());
    for (uint32_t i : mesh.indices) {
      ASSERT_LT(i, mesh.positions.size());
      EXPECT_TRUE(std::isfinite(mesh.positions[i].x) && std::isfinite(mesh.positions[i].y) &&
                  std::isfinite(mesh.positions[i].z));
    }
  }
  for (const auto& m : scene.materials) {
    EXPECT_GE(m.texture, -1);
    EXPECT_LT(m.texture, static_cast<int32_t>(scene.textures.size()));
  }
  for (const auto& t : scene.textures) {
    ASSERT_TRUE(t.image);
    EXPECT_EQ(t.image->texels.size(), size_t(t.image->width) * size_t(t.image->height));
  }
  for (const auto& inst : scene.instances) EXPECT_LT(inst.mesh, scene.meshes.size());
}

void expectLoadOrCleanError(const std::string& path) {
  SCOPED_TRACE(path);
  try {
    expectConsistent(loadGltf1(path));
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

bool hasWarning(const Scene& scene, const std::string& fragment) {
  return std::any_of(scene.report.warnings.begin(), scene.report.warnings.end(),
                     [&](const std::string& w) { return w.find(fragment) != std::string::npos; });
}

// Copies the files of an assimp glTF 1.0 folder into `dir`, the .gltf replaced by `doc`.
void copyAsset(const std::string& rel_gltf, const std::string& dir, const json& doc,
               const std::vector<std::string>& skip = {}) {
  const fs::path src = fs::path(assimpPath(rel_gltf));
  for (const auto& entry : fs::directory_iterator(src.parent_path())) {
    const std::string name = entry.path().filename().string();
    if (name == src.filename().string() || std::find(skip.begin(), skip.end(), name) != skip.end())
      continue;
    fs::copy_file(entry.path(), fs::path(dir) / name, fs::copy_options::overwrite_existing);
  }
  writeBytes((fs::path(dir) / src.filename()).string(), doc.dump(1));
}

// The milk truck with `edit` applied to its JSON, copied into `dir`: loading it must fail with a
// message naming `fragment`.
void expectTruckError(const std::string& dir, const std::function<void(json&)>& edit,
                      const std::string& fragment) {
  json doc = readJson(assimpPath(kTruck));
  edit(doc);
  copyAsset(kTruck, dir, doc);
  expectError(dir + "/CesiumMilkTruck.gltf", fragment);
}

std::string base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8 |
                       uint8_t(bytes[i + 2]);
    for (int s = 18; s >= 0; s -= 6) out.push_back(kAlphabet[(v >> s) & 63]);
  }
  if (i < bytes.size()) {
    uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    out.push_back(kAlphabet[(v >> 18) & 63]);
    out.push_back(kAlphabet[(v >> 12) & 63]);
    out.push_back(i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=');
    out.push_back('=');
  }
  return out;
}

template <typename T>
std::string rawBytes(const std::vector<T>& values) {
  return std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
}

// A one-mesh glTF 1.0 document with its buffer in a data URI: positions (float VEC3), then
// 16-bit indices when given, drawn in `mode` by node "n" of scene "s".
json smallDoc(const std::vector<float>& xyz, const std::vector<uint16_t>& indices, int mode) {
  const std::string pos = rawBytes(xyz), idx = rawBytes(indices);
  json doc = {
      {"asset", {{"version", "1.0"}}},
      {"buffers",
       {{"b",
         {{"byteLength", pos.size() + idx.size()},
          {"uri", "data:application/octet-stream;base64," + base64(pos + idx)}}}}},
      {"bufferViews", {{"vp", {{"buffer", "b"}, {"byteOffset", 0}, {"byteLength", pos.size()}}}}},
      {"accessors",
       {{"p",
         {{"bufferView", "vp"},
          {"byteOffset", 0},
          {"componentType", 5126},
          {"count", xyz.size() / 3},
          {"type", "VEC3"}}}}},
      {"materials", {{"m", {{"values", {{"diffuse", {0.25, 0.5, 0.75, 1.0}}}}}}}},
      {"meshes",
       {{"mesh",
         {{"primitives",
           json::array(
               {{{"attributes", {{"POSITION", "p"}}}, {"material", "m"}, {"mode", mode}}})}}}}},
      {"nodes", {{"n", {{"meshes", {"mesh"}}, {"name", "small"}}}}},
      {"scene", "s"},
      {"scenes", {{"s", {{"nodes", {"n"}}}}}}};
  if (!indices.empty()) {
    doc["bufferViews"]["vi"] = {
        {"buffer", "b"}, {"byteOffset", pos.size()}, {"byteLength", idx.size()}};
    doc["accessors"]["i"] = {{"bufferView", "vi"},
                             {"byteOffset", 0},
                             {"componentType", 5123},
                             {"count", indices.size()},
                             {"type", "SCALAR"}};
    doc["meshes"]["mesh"]["primitives"][0]["indices"] = "i";
  }
  return doc;
}

std::string writeDoc(const std::string& dir, const std::string& name, const json& doc) {
  const std::string path = (fs::path(dir) / name).string();
  writeBytes(path, doc.dump());
  return path;
}

void putU32(std::string& s, size_t at, uint32_t v) {
  for (int i = 0; i < 4; ++i) s[at + size_t(i)] = static_cast<char>((v >> (8 * i)) & 0xFF);
}

// A binary glTF 1.0 (KHR_binary_glTF) of assimp's BoxTextured-glTF: the .bin and the PNG in the
// binary body, the image referenced through a bufferView.
std::string buildBoxGlb() {
  const std::string dir = assimpPath("glTF/BoxTextured-glTF/");
  json doc = readJson(dir + "BoxTextured.gltf");
  const std::string bin = readBytes(dir + "BoxTextured.bin");
  const std::string png = readBytes(dir + "CesiumLogoFlat.png");
  std::string body = bin;
  while (body.size() % 4) body.push_back('\0');
  const size_t png_offset = body.size();
  body += png;
  doc["buffers"] = {
      {"binary_glTF", {{"byteLength", body.size()}, {"type", "arraybuffer"}, {"uri", "data:,"}}}};
  for (auto& view : doc["bufferViews"]) view["buffer"] = "binary_glTF";
  doc["bufferViews"]["png"] = {
      {"buffer", "binary_glTF"}, {"byteOffset", png_offset}, {"byteLength", png.size()}};
  doc["images"]["Image0001"] = {
      {"uri", "data:,"},
      {"extensions", {{"KHR_binary_glTF", {{"bufferView", "png"}, {"mimeType", "image/png"}}}}}};
  doc["extensionsUsed"] = {"KHR_binary_glTF"};
  std::string content = doc.dump();
  while ((20 + content.size()) % 4) content.push_back(' ');
  std::string glb(20, '\0');
  std::memcpy(glb.data(), "glTF", 4);
  putU32(glb, 4, 1);
  putU32(glb, 8, uint32_t(20 + content.size() + body.size()));
  putU32(glb, 12, uint32_t(content.size()));
  putU32(glb, 16, 0);
  return glb + content + body;
}

strata::Bounds instanceBounds(const Scene& scene, const strata::Instance& inst) {
  strata::Bounds b;
  for (const glm::vec3& p : scene.meshes[inst.mesh].positions)
    b.extend(glm::vec3(inst.transform * glm::vec4(p, 1.0f)));
  return b;
}

// ---------------------------------------------------------------------------------------------
// Detection

TEST(Gltf1Detect, TellsGltf1FromGltf2AndOthers) {
  // The truck writes its version as the number 1; the others as "1.0".
  for (const char* rel :
       {"glTF/CesiumMilkTruck/CesiumMilkTruck.gltf", "glTF/BoxTextured-glTF/BoxTextured.gltf",
        "glTF/BoxTextured-glTF-Embedded/BoxTextured.gltf",
        "glTF/BoxTextured-glTF-MaterialsCommon/BoxTextured.gltf",
        "glTF/BoxTextured-glTF-Binary/BoxTextured.glb", "glTF/TwoBoxes/TwoBoxes.gltf",
        "glTF/IncorrectVertexArrays/Cube_v1.gltf"})
    EXPECT_TRUE(isGltf1File(assimpPath(rel))) << rel;
  for (const char* rel :
       {"glTF2/BoxTextured-glTF/BoxTextured.gltf", "glTF2/BoxTextured-glTF-Binary/BoxTextured.glb",
        "glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf", "OBJ/box.obj"})
    EXPECT_FALSE(isGltf1File(assimpPath(rel))) << rel;

  const std::string dir = outDir();
  EXPECT_FALSE(isGltf1File(dir + "/missing.gltf"));
  writeBytes(dir + "/empty.gltf", "");
  EXPECT_FALSE(isGltf1File(dir + "/empty.gltf"));
  json doc = smallDoc({0, 0, 0, 1, 0, 0, 0, 1, 0}, {}, 4);
  doc.erase("asset");  // no version: the dictionaries tell
  EXPECT_TRUE(isGltf1File(writeDoc(dir, "noasset.gltf", doc)));
  doc["asset"] = {{"version", "2.0"}};
  EXPECT_FALSE(isGltf1File(writeDoc(dir, "v2.gltf", doc)));
  doc["asset"] = {{"version", "1.0.1"}};
  EXPECT_TRUE(isGltf1File(writeDoc(dir, "v101.gltf", doc)));
  // A cut 1.0 file is still recognised by its beginning, so its error comes from this loader.
  const std::string truck = readBytes(assimpPath(kTruck));
  writeBytes(dir + "/cut.gltf", truck.substr(0, truck.size() / 2));
  EXPECT_TRUE(isGltf1File(dir + "/cut.gltf"));
}

// ---------------------------------------------------------------------------------------------
// CesiumMilkTruck

TEST(Gltf1Truck, GeometryMaterialsTextureAndTransforms) {
  const std::string path = assimpPath(kTruck);
  const Scene scene = loadGltf1(path);
  expectConsistent(scene);

  // Expected triangles, independently from the JSON: each mesh's index counts / 3, times the
  // nodes drawing it (the wheel mesh is drawn by two nodes).
  const json doc = readJson(path);
  uint64_t expected = 0;
  for (const auto& node : doc["nodes"]) {
    if (!node.contains("meshes")) continue;
    for (const auto& m : node["meshes"])
      for (const auto& prim : doc["meshes"][m.get<std::string>()]["primitives"])
        expected +=
            doc["accessors"][prim["indices"].get<std::string>()]["count"].get<uint64_t>() / 3;
  }
  EXPECT_EQ(expected, (5232u + 168u + 864u) / 3 + 2 * 2304u / 3);
  EXPECT_EQ(scene.triangleCount() + scene.report.dropped_degenerate, expected);
  EXPECT_EQ(scene.report.dropped_out_of_range + scene.report.dropped_nonfinite, 0u);
  EXPECT_LT(scene.report.dropped_degenerate, expected / 100);

  // Four primitives, each its own mesh; five instances (3 truck primitives + 2 wheels) of three
  // nodes, one object id per node.
  EXPECT_EQ(scene.meshes.size(), 4u);
  EXPECT_EQ(scene.instances.size(), 5u);
  std::set<uint32_t> ids;
  std::map<std::string, int> names;
  for (const auto& inst : scene.instances) {
    ids.insert(inst.object_id);
    ++names[inst.name];
  }
  EXPECT_EQ(ids, (std::set<uint32_t>{0, 1, 2}));
  EXPECT_EQ(names, (std::map<std::string, int>{
                       {"Cesium_Milk_Truck", 3}, {"Wheels", 1}, {"Wheels__2_", 1}}));
  for (const Mesh& mesh : scene.meshes)
    EXPECT_EQ(mesh.texcoords.size(), mesh.positions.size()) << mesh.name;

  // Materials: truck and wheels textured with the one 2048x2048 PNG, glass and trim coloured.
  ASSERT_EQ(scene.textures.size(), 1u);
  ASSERT_TRUE(scene.textures[0].image);
  EXPECT_EQ(scene.textures[0].image->width, 2048);
  EXPECT_EQ(scene.textures[0].image->height, 2048);
  EXPECT_EQ(scene.textures[0].name, "CesiumMilkTruck.png");
  std::map<std::string, const strata::Material*> mats;
  for (const auto& m : scene.materials) mats[m.name] = &m;
  ASSERT_EQ(mats.size(), 4u);
  for (const char* textured : {"truck", "wheels"}) {
    ASSERT_TRUE(mats.count(textured)) << textured;
    const strata::Material& m = *mats[textured];
    EXPECT_EQ(m.texture, 0);
    EXPECT_EQ(m.color, glm::vec4(1.0f));
    EXPECT_EQ(m.base_color_texture, "CesiumMilkTruck.png");
    EXPECT_EQ(m.sampler.wrap_s, strata::Wrap::Repeat);
    EXPECT_EQ(m.sampler.wrap_t, strata::Wrap::Repeat);
    EXPECT_EQ(m.sampler.filter, strata::Filter::Trilinear);  // LINEAR_MIPMAP_LINEAR
    EXPECT_EQ(m.opacity, strata::kDefaultOpacity);
  }
  ASSERT_TRUE(mats.count("glass") && mats.count("window_trim"));
  EXPECT_EQ(mats["glass"]->texture, -1);
  EXPECT_NEAR(mats["glass"]->color.g, 0.0405063f, 1e-6f);
  EXPECT_NEAR(mats["window_trim"]->color.r, 0.064f, 1e-6f);
  EXPECT_EQ(mats["window_trim"]->opacity, strata::kDefaultOpacity);

  // Transforms: the wheel mesh is centred on its axis (|x|, |y| <= 0.4278); its nodes place it
  // at x = 1.43267 and -1.35233, y = 0.427722, so the wheels stand on y = 0 below the body
  // (whose lowest point is 0.2668).
  std::vector<float> wheel_x;
  for (const auto& inst : scene.instances) {
    if (inst.name.rfind("Wheels", 0) != 0) continue;
    const strata::Bounds b = instanceBounds(scene, inst);
    wheel_x.push_back(b.center().x);
    EXPECT_NEAR(b.center().y, 0.427722f, 0.01f);
    EXPECT_NEAR(b.min.y, 0.0f, 0.01f);
  }
  std::sort(wheel_x.begin(), wheel_x.end());
  ASSERT_EQ(wheel_x.size(), 2u);
  EXPECT_NEAR(wheel_x[0], -1.35233f, 0.01f);
  EXPECT_NEAR(wheel_x[1], 1.43267f, 0.01f);
  const strata::Bounds world = scene.worldBounds();
  EXPECT_NEAR(world.min.y, 0.0f, 0.01f);
  EXPECT_NEAR(world.max.y, 2.58437f, 1e-4f);
  EXPECT_NEAR(world.min.x, -2.43091f, 1e-4f);
  EXPECT_NEAR(world.max.x, 2.438f, 1e-4f);
  EXPECT_NEAR(world.max.z, 1.396f, 1e-4f);
}

// The texture-coordinate convention, checked against the image: (0, 0) is the image's top-left
// corner. The wheels' caps map onto the tyre drawn in the top-right quarter of the atlas (dark);
// read with v flipped they would land largely on white parts of the truck's side.
TEST(Gltf1Truck, TextureCoordinatesHitTheWheelInTheAtlas) {
  const Scene scene = loadGltf1(assimpPath(kTruck));
  const Mesh* wheels = nullptr;
  for (const auto& inst : scene.instances)
    if (inst.name == "Wheels") wheels = &scene.meshes[inst.mesh];
  ASSERT_NE(wheels, nullptr);
  const strata::TextureImage& image = *scene.textures.at(0).image;
  auto texel = [&](glm::vec2 uv) {
    const int x = std::clamp(int(uv.x * float(image.width)), 0, image.width - 1);
    const int y = std::clamp(int(uv.y * float(image.height)), 0, image.height - 1);
    return image.texels[size_t(y) * size_t(image.width) + size_t(x)];
  };
  auto whiteFraction = [&](bool flip) {
    size_t white = 0, n = wheels->triangleCount();
    for (size_t t = 0; t < n; ++t) {
      glm::vec2 uv(0.0f);
      for (int k = 0; k < 3; ++k)
        uv += wheels->texcoords[wheels->indices[3 * t + size_t(k)]] / 3.0f;
      if (flip) uv.y = 1.0f - uv.y;
      const glm::vec4 c = texel(uv);
      if (c.r > 0.85f && c.g > 0.85f && c.b > 0.85f) ++white;
    }
    return double(white) / double(n);
  };
  EXPECT_LT(whiteFraction(false), 0.02);
  EXPECT_GT(whiteFraction(true), 0.2);  // the check tells the two conventions apart
}

// End to end with the CPU reference: the side of the truck, opaque, shows the Cesium logo of the
// texture (sky blue and green). Writes gltf1/<test>/truck.png for a look.
TEST(Gltf1Truck, RendersTexturedWithTheReference) {
  const std::string dir = outDir();
  const Scene scene = loadGltf1(assimpPath(kTruck));
  const strata::WorldGeometry geo = strata::WorldGeometry::fromScene(scene, 1.0f);
  ASSERT_TRUE(geo.textured());
  strata::FrameSettings settings;
  settings.width = settings.height = 256;
  strata::OrbitView view;
  view.azimuth_deg = 0.0f;  // looking along -z at the truck's +z side
  view.elevation_deg = 10.0f;
  settings.camera = strata::Camera::orbit(scene.boundingSphere(), view);
  settings.background.checker = false;
  settings.background.color = glm::vec3(1.0f);
  const strata::RenderResult result =
      strata::makeRenderer(strata::Method::Embree)->render(geo, settings);
  strata::writeImage(result.image, dir + "/truck.png");
  size_t blue = 0, green = 0;
  for (int y = 0; y < result.image.height; ++y) {
    for (int x = 0; x < result.image.width; ++x) {
      const uint8_t* p = result.image.pixel(x, y);
      const int r = p[0], g = p[1], b = p[2];
      if (b > r + 50 && b > g + 15) ++blue;
      if (g > r + 15 && g > b + 40) ++green;
    }
  }
  const size_t pixels = size_t(settings.width) * size_t(settings.height);
  std::printf("truck: %llu triangles, %zu blue and %zu green logo pixels of %zu\n",
              static_cast<unsigned long long>(scene.triangleCount()), blue, green, pixels);
  EXPECT_GT(blue, pixels / 200);
  EXPECT_GT(green, pixels / 200);
}

// ---------------------------------------------------------------------------------------------
// assimp's other glTF 1.0 files

TEST(Gltf1Files, EveryAssimpGltf1FileLoadsOrFailsCleanly) {
  std::map<std::string, std::string> outcome;  // relative path -> "" (loaded) or the message
  const fs::path root = assimpPath("glTF");
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".gltf" && ext != ".glb") continue;
    const std::string path = entry.path().string();
    if (!isGltf1File(path)) continue;
    expectLoadOrCleanError(path);
    outcome[fs::relative(entry.path(), root).string()] = loadOrError(path);
  }
  // What each does (the list is fixed by Debian's assimp-testmodels).
  for (const char* ok :
       {"CesiumMilkTruck/CesiumMilkTruck.gltf", "BoxTextured-glTF/BoxTextured.gltf",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
        "BoxTextured-glTF-MaterialsCommon/BoxTextured.gltf", "TwoBoxes/TwoBoxes.gltf",
        "IncorrectVertexArrays/Cube_v1.gltf"}) {
    ASSERT_TRUE(outcome.count(ok)) << ok;
    EXPECT_EQ(outcome[ok], "") << ok;
  }
  // The binary one is damaged as shipped: its header declares 17754 bytes, the file has 17721
  // (33 bytes of its embedded shaders lost, so its image's bufferView points past the data).
  const std::string glb = "BoxTextured-glTF-Binary/BoxTextured.glb";
  ASSERT_TRUE(outcome.count(glb));
  EXPECT_NE(outcome[glb].find("declares 17754 bytes but the file has 17721"), std::string::npos)
      << outcome[glb];
}

TEST(Gltf1Files, BoxTexturedVariantsAgree) {
  const std::pair<const char*, const char*> variants[] = {
      {"glTF/BoxTextured-glTF/BoxTextured.gltf", "CesiumLogoFlat.png"},
      {"glTF/BoxTextured-glTF-Embedded/BoxTextured.gltf", "embedded:Image0001"},  // data: URIs
      {"glTF/BoxTextured-glTF-MaterialsCommon/BoxTextured.gltf", "CesiumLogoFlat.png"}};
  const Scene reference = loadGltf1(assimpPath(variants[0].first));
  for (const auto& [rel, texture] : variants) {
    SCOPED_TRACE(rel);
    const Scene scene = loadGltf1(assimpPath(rel));
    expectConsistent(scene);
    EXPECT_EQ(scene.triangleCount(), 12u);
    ASSERT_EQ(scene.materials.size(), 1u);
    EXPECT_EQ(scene.materials[0].name, "Texture");
    EXPECT_EQ(scene.materials[0].texture, 0);
    EXPECT_EQ(scene.materials[0].base_color_texture, texture);
    ASSERT_EQ(scene.textures.size(), 1u);
    EXPECT_EQ(scene.textures[0].image->width, 211);
    EXPECT_EQ(scene.textures[0].image->height, 211);
    EXPECT_EQ(scene.textures[0].image->texels, reference.textures[0].image->texels);
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_EQ(scene.meshes[0].positions, reference.meshes[0].positions);
    EXPECT_EQ(scene.meshes[0].texcoords, reference.meshes[0].texcoords);
    // The Y_UP_Transform node turns the box's z up into y up.
    ASSERT_EQ(scene.instances.size(), 1u);
    EXPECT_EQ(scene.instances[0].transform * glm::vec4(0, 0, 1, 0), glm::vec4(0, 1, 0, 0));
  }
}

TEST(Gltf1Files, TwoBoxesShareOneMesh) {
  const Scene scene = loadGltf1(assimpPath("glTF/TwoBoxes/TwoBoxes.gltf"));
  expectConsistent(scene);
  EXPECT_EQ(scene.meshes.size(), 1u);
  ASSERT_EQ(scene.instances.size(), 2u);
  EXPECT_NE(scene.instances[0].object_id, scene.instances[1].object_id);
  EXPECT_EQ(scene.triangleCount(), 24u);
  ASSERT_EQ(scene.materials.size(), 1u);
  EXPECT_EQ(scene.materials[0].color, glm::vec4(0.8f, 0.0f, 0.0f, 1.0f));
  EXPECT_EQ(scene.materials[0].texture, -1);
  EXPECT_TRUE(scene.textures.empty());
  // TopBox: half size, lifted by 1 along z, then z up turned into y up.
  const auto& top = scene.instances[0].name == "TopBox" ? scene.instances[0] : scene.instances[1];
  EXPECT_EQ(top.name, "TopBox");
  const glm::vec4 origin = top.transform * glm::vec4(0, 0, 0, 1);
  EXPECT_NEAR(origin.y, 1.0f, 1e-6f);
  EXPECT_NEAR(glm::length(glm::vec3(top.transform[0])), 0.5f, 1e-6f);
}

TEST(Gltf1Files, IncorrectVertexArraysKeepsTheTriangles) {
  // Eight meshes: whole and truncated cubes (with and without indices) and four line sets.
  const Scene scene = loadGltf1(assimpPath("glTF/IncorrectVertexArrays/Cube_v1.gltf"));
  expectConsistent(scene);
  EXPECT_EQ(scene.triangleCount(), 12u + 11u + 12u + 11u);
  EXPECT_TRUE(hasWarning(scene, "points or lines"));
  EXPECT_TRUE(hasWarning(scene, "trailing indices"));
}

// ---------------------------------------------------------------------------------------------
// Binary glTF 1.0

TEST(Gltf1Binary, KhrBinaryGltfLoadsLikeTheTextFile) {
  const std::string dir = outDir();
  const std::string path = dir + "/box.glb";
  writeBytes(path, buildBoxGlb());
  ASSERT_TRUE(isGltf1File(path));
  const Scene scene = loadGltf1(path);
  expectConsistent(scene);
  const Scene text = loadGltf1(assimpPath("glTF/BoxTextured-glTF/BoxTextured.gltf"));
  EXPECT_EQ(scene.triangleCount(), 12u);
  ASSERT_EQ(scene.meshes.size(), 1u);
  EXPECT_EQ(scene.meshes[0].positions, text.meshes[0].positions);
  EXPECT_EQ(scene.meshes[0].indices, text.meshes[0].indices);
  ASSERT_EQ(scene.textures.size(), 1u);
  EXPECT_EQ(scene.textures[0].name, "embedded:Image0001");
  EXPECT_EQ(scene.textures[0].image->texels, text.textures[0].image->texels);
  EXPECT_EQ(scene.materials.at(0).texture, 0);

  // A .gltf extension does not matter: the content tells.
  writeBytes(dir + "/box_glb.gltf", buildBoxGlb());
  EXPECT_EQ(loadGltf1(dir + "/box_glb.gltf").triangleCount(), 12u);
}

TEST(Gltf1Binary, DamagedHeadersAreRefused) {
  const std::string dir = outDir();
  const std::string glb = buildBoxGlb();
  writeBytes(dir + "/cut.glb", glb.substr(0, glb.size() - 100));
  expectError(dir + "/cut.glb", "truncated or altered");
  writeBytes(dir + "/header.glb", glb.substr(0, 12));
  expectError(dir + "/header.glb", "header truncated");
  std::string v2 = glb;
  putU32(v2, 4, 2);
  writeBytes(dir + "/v2.glb", v2);
  expectError(dir + "/v2.glb", "version 2");
  std::string content = glb;
  putU32(content, 12, uint32_t(glb.size()));
  writeBytes(dir + "/content.glb", content);
  expectError(dir + "/content.glb", "extends past the end");
  std::string format = glb;
  putU32(format, 16, 1);
  writeBytes(dir + "/format.glb", format);
  expectError(dir + "/format.glb", "content format 1");
}

TEST(Gltf1Binary, CutAtManyPointsNeverCrashes) {
  const std::string dir = outDir();
  const std::pair<std::string, std::string> sources[] = {
      {buildBoxGlb(), "cut.glb"},
      {readBytes(assimpPath(kTruck)), "CesiumMilkTruck.gltf"},
      {readBytes(assimpPath("glTF/BoxTextured-glTF-Embedded/BoxTextured.gltf")),
       "cut_embedded.gltf"}};
  fs::copy_file(assimpPath("glTF/CesiumMilkTruck/CesiumMilkTruck.bin"),
                dir + "/CesiumMilkTruck.bin");
  fs::copy_file(assimpPath("glTF/CesiumMilkTruck/CesiumMilkTruck.png"),
                dir + "/CesiumMilkTruck.png");
  for (const auto& [bytes, name] : sources) {
    const size_t step = std::max<size_t>(1, bytes.size() / 40);
    for (size_t n = 1; n < bytes.size(); n += step) {
      writeBytes(dir + "/" + name, bytes.substr(0, n));
      expectLoadOrCleanError(dir + "/" + name);
    }
  }
}

// Every leaf of the box's JSON replaced in turn by hostile values (huge, negative, fractional,
// wrong type): each copy loads consistently or fails with a proper Error.
TEST(Gltf1Errors, HostileValuesEverywhereNeverCrash) {
  const std::string dir = outDir();
  const std::string src = assimpPath("glTF/BoxTextured-glTF/");
  fs::copy_file(src + "BoxTextured.bin", dir + "/BoxTextured.bin");
  fs::copy_file(src + "CesiumLogoFlat.png", dir + "/CesiumLogoFlat.png");
  const json original = readJson(src + "BoxTextured.gltf");
  std::vector<json::json_pointer> leaves;
  const json flat = original.flatten();
  for (auto it = flat.begin(); it != flat.end(); ++it) {
    const std::string key = it.key();
    if (key.rfind("/shaders", 0) == 0 || key.rfind("/programs", 0) == 0 ||
        key.rfind("/animations", 0) == 0 || key.rfind("/techniques", 0) == 0 ||
        key.rfind("/skins", 0) == 0)
      continue;
    leaves.emplace_back(key);
  }
  ASSERT_GT(leaves.size(), 50u);
  const json hostile[] = {-1,  0,   3,       4294967295.0,  1e300,
                          2.5, "x", nullptr, json::array(), json::object()};
  for (const auto& leaf : leaves) {
    for (const json& value : hostile) {
      json doc = original;
      doc[leaf] = value;
      const std::string path = writeDoc(dir, "box.gltf", doc);
      SCOPED_TRACE(leaf.to_string() + " = " + value.dump());
      expectLoadOrCleanError(path);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Malformed copies of the truck

TEST(Gltf1Errors, BrokenJson) {
  const std::string dir = outDir();
  const std::string text = readBytes(assimpPath(kTruck));
  writeBytes(dir + "/cut.gltf", text.substr(0, text.size() / 3));
  expectError(dir + "/cut.gltf", "cannot parse JSON");
  writeBytes(dir + "/garbage.gltf", "{\"asset\": {\"version\": \"1.0\"}, \"nodes\": {,,}}");
  expectError(dir + "/garbage.gltf", "cannot parse JSON");
  writeBytes(dir + "/array.gltf", "[1, 2, 3]");
  expectError(dir + "/array.gltf", "not an object");
  writeBytes(dir + "/empty.gltf", "");
  expectError(dir + "/empty.gltf", "empty");
  expectError(dir + "/missing.gltf", "no such file");
}

TEST(Gltf1Errors, AccessorsAndViewsOutOfRange) {
  const std::string dir = outDir();
  json doc = readJson(assimpPath(kTruck));
  doc["accessors"]["accessor_71"]["count"] = 100000;  // the truck's positions
  copyAsset(kTruck, dir, doc);
  expectError(dir + "/CesiumMilkTruck.gltf", "accessor 'accessor_71'");
  expectError(dir + "/CesiumMilkTruck.gltf", "do not fit");

  expectTruckError(
      dir, [](json& d) { d["bufferViews"]["bufferView_105"]["byteLength"] = 200000; },
      "extends past its buffer's 113052 bytes");

  expectTruckError(
      dir, [](json& d) { d["accessors"]["accessor_71"]["byteStride"] = 4; }, "byteStride 4");

  expectTruckError(
      dir, [](json& d) { d["accessors"]["accessor_71"]["componentType"] = 5123; },
      "unsupported componentType 5123");

  expectTruckError(
      dir, [](json& d) { d["accessors"]["accessor_71"]["type"] = "VEC2"; }, "type VEC2");
}

TEST(Gltf1Errors, MissingOrShortFiles) {
  const std::string dir = outDir();
  const json doc = readJson(assimpPath(kTruck));
  copyAsset(kTruck, dir, doc, {"CesiumMilkTruck.bin"});
  expectError(dir + "/CesiumMilkTruck.gltf", "'CesiumMilkTruck.bin' not found");

  const std::string bin = readBytes(assimpPath("glTF/CesiumMilkTruck/CesiumMilkTruck.bin"));
  writeBytes(dir + "/CesiumMilkTruck.bin", bin.substr(0, 1000));
  expectError(dir + "/CesiumMilkTruck.gltf", "byteLength 113052 but only 1000 bytes");

  fs::remove(dir + "/CesiumMilkTruck.png");
  copyAsset(kTruck, dir, doc, {"CesiumMilkTruck.png"});
  expectError(dir + "/CesiumMilkTruck.gltf", "CesiumMilkTruck.png");
  writeBytes(dir + "/CesiumMilkTruck.png", "not a png");
  expectError(dir + "/CesiumMilkTruck.gltf", "image 'Image0001'");
}

TEST(Gltf1Errors, DanglingIds) {
  const std::string dir = outDir();
  const std::string gltf = dir + "/CesiumMilkTruck.gltf";
  json doc = readJson(assimpPath(kTruck));
  doc["meshes"]["Geometry-mesh001"]["primitives"][0]["indices"] = "accessor_999";
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "accessor 'accessor_999' does not exist");

  doc = readJson(assimpPath(kTruck));
  doc["meshes"]["Geometry-mesh001"]["primitives"][0]["material"] = "nope";
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "material 'nope' does not exist");

  doc = readJson(assimpPath(kTruck));
  doc["nodes"]["Geometry-mesh002Node"]["children"].push_back("ghost");
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "node 'Geometry-mesh002Node' children: node 'ghost' does not exist");

  doc = readJson(assimpPath(kTruck));
  doc["scene"] = "elsewhere";
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "scene 'elsewhere' does not exist");

  doc = readJson(assimpPath(kTruck));
  doc["materials"]["Effect-truck"]["values"]["diffuse"] = "texture_missing";
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "texture 'texture_missing' does not exist");

  doc = readJson(assimpPath(kTruck));
  doc["nodes"]["Geometry-mesh001Node"]["children"] = {"Geometry-mesh002Node"};
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "cycle");

  doc = readJson(assimpPath(kTruck));
  doc["nodes"]["Geometry-mesh001Node"]["rotation"] = {0, 0, 1};
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "'rotation' must be an array of 4 numbers");

  doc = readJson(assimpPath(kTruck));
  doc["accessors"]["accessor_71"]["count"] = -5;
  copyAsset(kTruck, dir, doc);
  expectError(gltf, "'count' must be a non-negative integer");
}

TEST(Gltf1Errors, Gltf2LayoutIsRefused) {
  const std::string dir = outDir();
  expectTruckError(
      dir, [](json& d) { d["meshes"] = json::array(); }, "an array is glTF 2.0");
  // A real glTF 2.0 file handed to this reader.
  const std::string v2 = assimpPath("glTF2/BoxTextured-glTF/BoxTextured.gltf");
  expectError(v2, "is not glTF 1.0");
}

TEST(Gltf1Errors, UrisMustStayInsideTheAssetFolder) {
  const std::string dir = outDir();
  fs::create_directories(dir + "/asset");
  const std::string gltf = dir + "/asset/CesiumMilkTruck.gltf";
  for (const auto& [uri, fragment] : std::vector<std::pair<std::string, std::string>>{
           {"../CesiumMilkTruck.bin", "resolves outside"},
           {"%2e%2e/CesiumMilkTruck.bin", "resolves outside"},
           {"/etc/passwd", "is absolute"},
           {"file:///etc/passwd", "is absolute"},
           {"http://example.com/x.bin", "is absolute"}}) {
    SCOPED_TRACE(uri);
    json doc = readJson(assimpPath(kTruck));
    doc["buffers"]["CesiumMilkTruck"]["uri"] = uri;
    copyAsset(kTruck, dir + "/asset", doc);
    fs::copy_file(dir + "/asset/CesiumMilkTruck.bin", dir + "/CesiumMilkTruck.bin",
                  fs::copy_options::overwrite_existing);
    expectError(gltf, fragment);
    expectError(gltf, uri);
  }
  // Images too.
  json doc = readJson(assimpPath(kTruck));
  doc["images"]["Image0001"]["uri"] = "../CesiumMilkTruck.png";
  copyAsset(kTruck, dir + "/asset", doc);
  fs::copy_file(dir + "/asset/CesiumMilkTruck.png", dir + "/CesiumMilkTruck.png",
                fs::copy_options::overwrite_existing);
  expectError(gltf, "'../CesiumMilkTruck.png' resolves outside");
  // A link inside the folder that leads out of it.
  doc = readJson(assimpPath(kTruck));
  doc["buffers"]["CesiumMilkTruck"]["uri"] = "link.bin";
  copyAsset(kTruck, dir + "/asset", doc);
  fs::remove(dir + "/asset/link.bin");
  fs::create_symlink(dir + "/CesiumMilkTruck.bin", dir + "/asset/link.bin");
  expectError(gltf, "'link.bin' resolves outside");
  // Escaped characters of a URI inside the folder are decoded.
  doc["buffers"]["CesiumMilkTruck"]["uri"] = "Cesium%4DilkTruck.bin";
  copyAsset(kTruck, dir + "/asset", doc);
  EXPECT_GT(loadGltf1(gltf).triangleCount(), 0u);
}

// ---------------------------------------------------------------------------------------------
// Small hand-made files

TEST(Gltf1Small, IndicesOutOfRangeAreCountedOrRefused) {
  const std::string dir = outDir();
  const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  const Scene scene = loadGltf1(writeDoc(dir, "some.gltf", smallDoc(quad, {0, 1, 2, 0, 2, 9}, 4)));
  EXPECT_EQ(scene.triangleCount(), 1u);
  EXPECT_EQ(scene.report.dropped_out_of_range, 1u);
  expectError(writeDoc(dir, "all.gltf", smallDoc(quad, {7, 8, 9}, 4)), "no triangles");
}

TEST(Gltf1Small, StripsAndFansKeepWindingPointsAndLinesAreSkipped) {
  const std::string dir = outDir();
  // A quad facing +z: as a strip (0 1 3 2 zig-zag) and as a fan (0 1 2 3 around).
  const std::vector<float> quad = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
  for (const auto& [name, indices, mode] :
       std::vector<std::tuple<std::string, std::vector<uint16_t>, int>>{
           {"strip", {0, 1, 3, 2}, 5},
           {"fan", {0, 1, 2, 3}, 6},
           {"triangles", {0, 1, 2, 0, 2, 3}, 4}}) {
    SCOPED_TRACE(name);
    const Scene scene = loadGltf1(writeDoc(dir, name + ".gltf", smallDoc(quad, indices, mode)));
    ASSERT_EQ(scene.triangleCount(), 2u);
    const Mesh& mesh = scene.meshes[0];
    for (size_t t = 0; t < 2; ++t) {
      const glm::vec3 a = mesh.positions[mesh.indices[3 * t]],
                      b = mesh.positions[mesh.indices[3 * t + 1]],
                      c = mesh.positions[mesh.indices[3 * t + 2]];
      EXPECT_GT(glm::cross(b - a, c - a).z, 0.0f) << "triangle " << t;
    }
    EXPECT_EQ(scene.materials[0].color, glm::vec4(0.25f, 0.5f, 0.75f, 1.0f));
    EXPECT_EQ(scene.instances[0].name, "small");
  }
  // Non-indexed triangles.
  EXPECT_EQ(loadGltf1(writeDoc(dir, "plain.gltf", smallDoc({0, 0, 0, 1, 0, 0, 0, 1, 0}, {}, 4)))
                .triangleCount(),
            1u);
  // Lines only: nothing to draw, and the message says why.
  json lines = smallDoc(quad, {0, 1, 1, 2}, 1);
  expectError(writeDoc(dir, "lines.gltf", lines), "no triangles");
  // Lines beside triangles: a warning.
  json both = smallDoc(quad, {0, 1, 2}, 4);
  both["meshes"]["mesh"]["primitives"].push_back(
      {{"attributes", {{"POSITION", "p"}}}, {"mode", 0}});
  const Scene scene = loadGltf1(writeDoc(dir, "both.gltf", both));
  EXPECT_EQ(scene.triangleCount(), 1u);
  EXPECT_TRUE(hasWarning(scene, "points or lines"));
}

TEST(Gltf1Small, MaterialSources) {
  const std::string dir = outDir();
  const std::vector<float> tri = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  auto colour = [&](const json& doc, const std::string& name) {
    return loadGltf1(writeDoc(dir, name, doc)).materials.at(0).color;
  };
  // KHR_materials_common, with an RGB diffuse.
  json doc = smallDoc(tri, {}, 4);
  doc["materials"]["m"] = {
      {"extensions",
       {{"KHR_materials_common",
         {{"technique", "LAMBERT"}, {"values", {{"diffuse", {0.1, 0.2, 0.3}}}}}}}}};
  EXPECT_EQ(colour(doc, "common.gltf"), glm::vec4(0.1f, 0.2f, 0.3f, 1.0f));
  // KHR_materials_common's CONSTANT technique: the emission.
  doc["materials"]["m"] = {
      {"extensions",
       {{"KHR_materials_common",
         {{"technique", "CONSTANT"}, {"values", {{"emission", {0.5, 0.5, 0.0, 1.0}}}}}}}}};
  EXPECT_EQ(colour(doc, "constant.gltf"), glm::vec4(0.5f, 0.5f, 0.0f, 1.0f));
  // The technique's parameter default when the material sets none; out-of-range values clamp.
  doc["materials"]["m"] = {{"technique", "t"}, {"values", json::object()}};
  doc["techniques"] = {
      {"t", {{"parameters", {{"diffuse", {{"type", 35666}, {"value", {2.0, 0.5, -1.0, 1.0}}}}}}}}};
  EXPECT_EQ(colour(doc, "technique.gltf"), glm::vec4(1.0f, 0.5f, 0.0f, 1.0f));
  // No diffuse at all: the default material colour.
  doc["materials"]["m"] = json::object();
  EXPECT_EQ(colour(doc, "none.gltf"), strata::Material{}.color);
  // No material: the default one.
  doc["meshes"]["mesh"]["primitives"][0].erase("material");
  const Scene scene = loadGltf1(writeDoc(dir, "nomaterial.gltf", doc));
  EXPECT_EQ(scene.materials.at(0).name, "default");
}

TEST(Gltf1Small, SamplerModes) {
  const std::string dir = outDir();
  json doc = readJson(assimpPath("glTF/BoxTextured-glTF/BoxTextured.gltf"));
  fs::copy_file(assimpPath("glTF/BoxTextured-glTF/BoxTextured.bin"), dir + "/BoxTextured.bin");
  fs::copy_file(assimpPath("glTF/BoxTextured-glTF/CesiumLogoFlat.png"),
                dir + "/CesiumLogoFlat.png");
  auto sampler = [&](const json& s) {
    doc["samplers"]["sampler_0"] = s;
    return loadGltf1(writeDoc(dir, "box.gltf", doc)).materials.at(0).sampler;
  };
  strata::Sampler s =
      sampler({{"magFilter", 9728}, {"minFilter", 9987}, {"wrapS", 33071}, {"wrapT", 33648}});
  EXPECT_EQ(s.filter, strata::Filter::Nearest);
  EXPECT_EQ(s.wrap_s, strata::Wrap::Clamp);
  EXPECT_EQ(s.wrap_t, strata::Wrap::MirroredRepeat);
  s = sampler({{"magFilter", 9729}, {"minFilter", 9729}});
  EXPECT_EQ(s.filter, strata::Filter::Bilinear);
  EXPECT_EQ(s.wrap_s, strata::Wrap::Repeat);
  s = sampler(json::object());  // glTF 1.0's default minFilter is NEAREST_MIPMAP_LINEAR
  EXPECT_EQ(s.filter, strata::Filter::Trilinear);
}

TEST(Gltf1Small, NoSceneDrawsEveryRootNode) {
  const std::string dir = outDir();
  json doc = smallDoc({0, 0, 0, 1, 0, 0, 0, 1, 0}, {}, 4);
  doc.erase("scene");
  doc.erase("scenes");
  doc["nodes"]["parent"] = {{"children", {"n"}}, {"translation", {0, 0, 5}}};
  doc["nodes"]["other"] = {{"meshes", {"mesh"}},
                           {"matrix", {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3, 0, 0, 1}}};
  const Scene scene = loadGltf1(writeDoc(dir, "noscene.gltf", doc));
  ASSERT_EQ(scene.instances.size(), 2u);
  std::set<float> offsets;
  for (const auto& inst : scene.instances)
    offsets.insert(inst.transform[3].x + inst.transform[3].z);
  EXPECT_EQ(offsets, (std::set<float>{3.0f, 5.0f}));
}

}  // namespace
