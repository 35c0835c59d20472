// Mesh and scene loading: real models (shared test models, assimp's test files), malformed and
// hostile inputs, and small hand-made files under tests/data whose exact contents are known.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <unistd.h>

#include <glm/glm.hpp>

#include "preprocess/mesh_loader.h"
#include "preprocess/validate.h"
#include "test_support.h"

namespace {

using strata::test::assimpPath;
using strata::test::modelPath;
using strata::test::readBytes;
using strata::test::writeBytes;

namespace fs = std::filesystem;
using strata::Error;
using strata::loadSceneFile;
using strata::Mesh;
using strata::Scene;

// Hand-made inputs live beside the shared models (tests/data next to tests/models).
std::string dataPath(const std::string& name) {
  return std::string(STRATA_MODELS_DIR) + "/../data/" + name;
}

// A scratch folder for files written by the tests, removed at the end of each test.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("strata_loaders_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
             std::to_string(static_cast<unsigned long>(::getpid())));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

glm::vec3 corner(const Mesh& mesh, size_t triangle, int k) {
  return mesh.positions[mesh.indices[3 * triangle + static_cast<size_t>(k)]];
}

glm::vec3 faceNormal(const Mesh& mesh, size_t triangle) {
  const glm::vec3 a = corner(mesh, triangle, 0), b = corner(mesh, triangle, 1),
                  c = corner(mesh, triangle, 2);
  return glm::cross(b - a, c - a);
}

uint64_t droppedTotal(const Scene& scene) {
  return scene.report.dropped_nonfinite + scene.report.dropped_out_of_range +
         scene.report.dropped_degenerate;
}

// Loading must end in a scene or a strata::Error whose one-line message starts with the path.
// Returns the error message, or "" when the file loaded.
std::string loadOrError(const std::string& path) {
  return strata::test::errorOf([&] { loadSceneFile(path); });
}

void expectError(const std::string& path, const std::string& fragment) {
  strata::test::expectLoadError(path, loadOrError(path), fragment);
}

// Whatever a loaded scene is, it must be drawable: valid references, finite kept triangles.
void expectConsistent(const Scene& scene) {
  ASSERT_FALSE(scene.instances.empty());
  EXPECT_GT(scene.triangleCount(), 0u);
  uint64_t mesh_triangles = 0;
  for (const Mesh& mesh : scene.meshes) {
    ASSERT_EQ(mesh.indices.size() % 3, 0u);
    EXPECT_TRUE(mesh.texcoords.empty() || mesh.texcoords.size() == mesh.positions.size());
    EXPECT_LT(mesh.material, scene.materials.size());
    for (uint32_t i : mesh.indices) {
      ASSERT_LT(i, mesh.positions.size());
      const glm::vec3& p = mesh.positions[i];
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    }
    mesh_triangles += mesh.triangleCount();
  }
  EXPECT_EQ(scene.report.triangles_loaded, mesh_triangles);
  for (const strata::Instance& inst : scene.instances) EXPECT_LT(inst.mesh, scene.meshes.size());
}

// A file that may be malformed: it either loads consistently or fails with a proper Error.
void expectLoadOrCleanError(const std::string& path) {
  SCOPED_TRACE(path);
  try {
    expectConsistent(loadSceneFile(path));
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

// ---------------------------------------------------------------------------------------------
// Shared test models: counts from tests/models/README.md.

struct SharedModel {
  const char* file;
  uint64_t triangles;
};

// Readable parameter names in test listings.
inline void PrintTo(const SharedModel& m, std::ostream* os) { *os << m.file; }

class SharedModelTest : public ::testing::TestWithParam<SharedModel> {};

TEST_P(SharedModelTest, LoadsWithPublishedTriangleCount) {
  const SharedModel& m = GetParam();
  const Scene scene = loadSceneFile(modelPath(m.file));
  expectConsistent(scene);
  EXPECT_EQ(scene.triangleCount(), m.triangles);
  EXPECT_EQ(scene.report.triangles_loaded, m.triangles);
  EXPECT_EQ(droppedTotal(scene), 0u);
  EXPECT_EQ(scene.report.polygons_triangulated, 0u);

  ASSERT_EQ(scene.meshes.size(), 1u);
  ASSERT_EQ(scene.instances.size(), 1u);
  ASSERT_EQ(scene.materials.size(), 1u);
  const strata::Instance& inst = scene.instances[0];
  EXPECT_EQ(inst.name, fs::path(m.file).stem().string());
  EXPECT_EQ(inst.object_id, 0u);
  EXPECT_EQ(inst.transform, glm::mat4(1.0f));
  EXPECT_EQ(scene.materials[0].color, glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
  EXPECT_EQ(scene.materials[0].opacity, strata::kDefaultOpacity);
}

INSTANTIATE_TEST_SUITE_P(
    Models, SharedModelTest,
    ::testing::Values(SharedModel{"teapot.obj", 6320}, SharedModel{"horse.ply", 96966},
                      SharedModel{"stanford-bunny.obj", 69451}, SharedModel{"fandisk.obj", 12946},
                      SharedModel{"rocker-arm.obj", 20088}, SharedModel{"cheburashka.obj", 13334},
                      SharedModel{"homer.obj", 12000}, SharedModel{"cow.obj", 5804},
                      SharedModel{"spot.obj", 5856}),
    [](const ::testing::TestParamInfo<SharedModel>& info) {
      std::string name = fs::path(info.param.file).stem().string();
      std::replace(name.begin(), name.end(), '-', '_');
      return name;
    });

TEST(ObjTexcoords, SpotCornersKeepTheirFileUvs) {
  // spot.obj gives UVs per face corner (`f v/vt`); a position whose corners carry different UVs
  // (a seam) must become several vertices, each with its corner's UV. Compare every loaded
  // triangle with the file's face, read here independently.
  const std::string path = modelPath("spot.obj");
  std::vector<glm::vec3> v;
  std::vector<glm::vec2> vt;
  std::vector<std::array<std::pair<int, int>, 3>> faces;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "v") {
      glm::vec3 p;
      words >> p.x >> p.y >> p.z;
      v.push_back(p);
    } else if (key == "vt") {
      glm::vec2 t;
      words >> t.x >> t.y;
      vt.push_back(t);
    } else if (key == "f") {
      std::array<std::pair<int, int>, 3> f;
      for (auto& [vi, ti] : f) {
        std::string corner_text;
        words >> corner_text;
        ASSERT_EQ(std::sscanf(corner_text.c_str(), "%d/%d", &vi, &ti), 2) << corner_text;
      }
      faces.push_back(f);
    }
  }

  const Scene scene = loadSceneFile(path);
  const Mesh& mesh = scene.meshes.at(0);
  ASSERT_EQ(mesh.texcoords.size(), mesh.positions.size());
  EXPECT_GT(mesh.positions.size(), v.size());  // seams were split
  ASSERT_EQ(mesh.triangleCount(), faces.size());
  for (size_t t = 0; t < faces.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t loaded = mesh.indices[3 * t + static_cast<size_t>(k)];
      const auto [vi, ti] = faces[t][static_cast<size_t>(k)];
      ASSERT_EQ(mesh.positions[loaded], v.at(static_cast<size_t>(vi - 1))) << "face " << t;
      // OBJ's v points up; strata's texture coordinates start at the image's top row.
      const glm::vec2 file_uv = vt.at(static_cast<size_t>(ti - 1));
      ASSERT_EQ(mesh.texcoords[loaded], glm::vec2(file_uv.x, 1.0f - file_uv.y)) << "face " << t;
    }
  }
}

TEST(ObjLoading, ConcurrentLoadsAgree) {
  // OpenMesh's readers keep state in singletons; loads from several threads must not mix.
  std::vector<uint64_t> counts(4, 0);
  std::vector<std::thread> threads;
  const char* files[] = {"cow.obj", "teapot.obj", "cow.obj", "teapot.obj"};
  for (size_t i = 0; i < counts.size(); ++i)
    threads.emplace_back(
        [&, i] { counts[i] = loadSceneFile(modelPath(files[i])).triangleCount(); });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(counts[0], 5804u);
  EXPECT_EQ(counts[1], 6320u);
  EXPECT_EQ(counts[2], 5804u);
  EXPECT_EQ(counts[3], 6320u);
}

// ---------------------------------------------------------------------------------------------
// Real files from assimp's test set.

TEST(AssimpFiles, RealFilesInEveryFormatLoad) {
  const char* files[] = {
      "OBJ/box.obj",
      "OBJ/spider.obj",
      "OBJ/WusonOBJ.obj",
      "OBJ/concave_polygon.obj",
      "OBJ/regr01.obj",
      "OBJ/cube_usemtl.obj",
      "PLY/cube.ply",
      "PLY/cube_binary.ply",
      "PLY/Wuson.ply",
      "PLY/cube_uv.ply",
      "PLY/float-color.ply",
      "OFF/Cube.off",
      "OFF/Wuson.off",
      "STL/Spider_ascii.stl",
      "STL/Spider_binary.stl",
      "STL/Wuson.stl",
      "STL/3DSMaxExport.STL",
      "STL/sphereWithHole.stl",
      "glTF2/BoxTextured-glTF/BoxTextured.gltf",
      "glTF2/BoxTextured-glTF-Binary/BoxTextured.glb",
      "glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf",
      "glTF2/ClearCoat-glTF/ClearCoatTest.gltf",
      "glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
  };
  for (const char* rel : files) {
    SCOPED_TRACE(rel);
    const Scene scene = loadSceneFile(assimpPath(rel));
    expectConsistent(scene);
  }
}

TEST(AssimpFiles, SameModelAgreesAcrossFormats) {
  // Wuson is shipped as OBJ, binary-less ascii PLY, OFF and STL; all describe the same triangles.
  const uint64_t obj = loadSceneFile(assimpPath("OBJ/WusonOBJ.obj")).triangleCount();
  EXPECT_GT(obj, 0u);
  EXPECT_EQ(loadSceneFile(assimpPath("PLY/Wuson.ply")).triangleCount(), obj);
  EXPECT_EQ(loadSceneFile(assimpPath("OFF/Wuson.off")).triangleCount(), obj);
  EXPECT_EQ(loadSceneFile(assimpPath("STL/Wuson.stl")).triangleCount(), obj);

  // The spider as OBJ, ascii STL and binary STL: same kept and same dropped (zero-area) facets.
  const Scene spider_obj = loadSceneFile(assimpPath("OBJ/spider.obj"));
  const Scene spider_ascii = loadSceneFile(assimpPath("STL/Spider_ascii.stl"));
  const Scene spider_binary = loadSceneFile(assimpPath("STL/Spider_binary.stl"));
  EXPECT_EQ(spider_ascii.triangleCount(), spider_binary.triangleCount());
  EXPECT_EQ(spider_obj.triangleCount(), spider_binary.triangleCount());
  EXPECT_EQ(spider_ascii.report.dropped_degenerate, spider_binary.report.dropped_degenerate);
  EXPECT_GT(spider_binary.report.dropped_degenerate, 0u);
}

TEST(AssimpFiles, BoxQuadsAreTriangulated) {
  const Scene scene = loadSceneFile(assimpPath("OBJ/box.obj"));  // six quads
  EXPECT_EQ(scene.report.polygons_triangulated, 6u);
  EXPECT_EQ(scene.triangleCount(), 12u);
}

TEST(AssimpFiles, PolygonWithAHoleIsTriangulatedExactly) {
  // concave_polygon.obj is one planar 66-corner face: an outer loop and a hole joined by a
  // bridge edge whose two vertices appear twice. Its triangles must cover exactly the polygon:
  // same orientation everywhere, areas adding up to the polygon's (Newell) area.
  const std::string path = assimpPath("OBJ/concave_polygon.obj");
  std::vector<glm::dvec3> v;
  std::vector<size_t> face;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "v") {
      glm::dvec3 p;
      words >> p.x >> p.y >> p.z;
      v.push_back(p);
    } else if (key == "f") {
      for (std::string c; words >> c;) face.push_back(std::stoul(c.substr(0, c.find('/'))) - 1);
    }
  }
  ASSERT_GT(face.size(), 3u);
  glm::dvec3 newell(0.0);
  for (size_t i = 0; i < face.size(); ++i) {
    const glm::dvec3 a = v.at(face[i]), b = v.at(face[(i + 1) % face.size()]);
    newell +=
        glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }

  const Scene scene = loadSceneFile(path);
  const Mesh& mesh = scene.meshes.at(0);
  EXPECT_EQ(scene.report.polygons_triangulated, 1u);
  ASSERT_EQ(mesh.triangleCount(), face.size() - 2);
  double area = 0.0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const glm::dvec3 n(faceNormal(mesh, t));
    EXPECT_GT(glm::dot(n, newell), 0.0) << "triangle " << t << " is folded over";
    area += 0.5 * glm::length(n);
  }
  EXPECT_NEAR(area, 0.5 * glm::length(newell), 1e-6 * area);
}

TEST(AssimpFiles, FaceListingItsLoopManyTimesIsReadOnce) {
  // box_longline.obj's first face is "1 2 3 4" written out 234 times on one line.
  const Scene scene = loadSceneFile(assimpPath("OBJ/box_longline.obj"));
  EXPECT_EQ(scene.triangleCount(), 12u);
  EXPECT_EQ(droppedTotal(scene), 0u);
}

TEST(AssimpFiles, GltfBoxTexturedVariants) {
  struct Case {
    const char* rel;
    const char* texture;
  } cases[] = {
      {"glTF2/BoxTextured-glTF/BoxTextured.gltf", "CesiumLogoFlat.png"},
      {"glTF2/BoxTextured-glTF-Binary/BoxTextured.glb", "embedded:0"},     // bufferView image
      {"glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf", "embedded:0"},  // data: URI image
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.rel);
    const Scene scene = loadSceneFile(assimpPath(c.rel));
    expectConsistent(scene);
    EXPECT_EQ(scene.triangleCount(), 12u);
    ASSERT_EQ(scene.meshes.size(), 1u);
    EXPECT_EQ(scene.meshes[0].texcoords.size(), scene.meshes[0].positions.size());
    const strata::Material& mat = scene.materials.at(scene.meshes[0].material);
    EXPECT_EQ(mat.base_color_texture, c.texture);
    EXPECT_EQ(mat.opacity, strata::kDefaultOpacity);  // alphaMode OPAQUE
  }
}

TEST(AssimpFiles, GltfEngineInstancesAreTransformedAndShareMeshes) {
  const Scene scene =
      loadSceneFile(assimpPath("glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb"));
  expectConsistent(scene);
  EXPECT_GT(scene.instances.size(), 1u);
  // Several nodes draw the same glTF mesh: instances outnumber meshes.
  EXPECT_LT(scene.meshes.size(), scene.instances.size());
  size_t transformed = 0;
  for (const strata::Instance& inst : scene.instances) {
    if (inst.transform != glm::mat4(1.0f)) ++transformed;
    EXPECT_FALSE(inst.name.empty());
  }
  EXPECT_GT(transformed, 0u);
  // Instances of the same mesh at different places: the same local vertex lands elsewhere.
  bool placed_apart = false;
  for (size_t i = 0; i < scene.instances.size() && !placed_apart; ++i)
    for (size_t j = i + 1; j < scene.instances.size() && !placed_apart; ++j)
      placed_apart = scene.instances[i].mesh == scene.instances[j].mesh &&
                     scene.instances[i].transform != scene.instances[j].transform;
  EXPECT_TRUE(placed_apart);
  // Object ids are dense: 0 .. n-1, one per mesh-bearing node.
  uint32_t max_id = 0;
  for (const strata::Instance& inst : scene.instances) max_id = std::max(max_id, inst.object_id);
  std::vector<bool> seen(max_id + 1, false);
  for (const strata::Instance& inst : scene.instances) seen[inst.object_id] = true;
  EXPECT_TRUE(std::all_of(seen.begin(), seen.end(), [](bool b) { return b; }));
  const strata::Bounds b = scene.worldBounds();
  EXPECT_FALSE(b.empty());
}

TEST(AssimpFiles, GltfPrimitiveModesKeepWinding) {
  // glTF-Asset-Generator's Mesh_PrimitiveMode set: one quad facing +z drawn as a triangle strip
  // (04, 11), a fan (05, 12) and a triangle list (06, 13-15; u32, u8 and u16 indices).
  const char* files[] = {"04", "05", "06", "11", "12", "13", "14", "15"};
  for (const char* n : files) {
    const std::string rel =
        std::string("glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_") + n +
        ".gltf";
    SCOPED_TRACE(rel);
    const Scene scene = loadSceneFile(assimpPath(rel));
    ASSERT_EQ(scene.meshes.size(), 1u);
    const Mesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangleCount(), 2u);
    for (size_t t = 0; t < 2; ++t) EXPECT_GT(faceNormal(mesh, t).z, 0.0f) << "triangle " << t;
  }
}

TEST(AssimpFiles, GltfPointsAndLinesAreSkippedWithAWarning) {
  // Mode 0 (points) only: nothing to draw, and the error says why.
  expectError(
      assimpPath("glTF2/glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf"),
      "points or lines");
  // Triangles beside line primitives: the lines are reported, the triangles kept.
  const Scene scene = loadSceneFile(assimpPath("glTF2/IncorrectVertexArrays/Cube.gltf"));
  expectConsistent(scene);
  EXPECT_TRUE(std::any_of(
      scene.report.warnings.begin(), scene.report.warnings.end(),
      [](const std::string& w) { return w.find("points or lines") != std::string::npos; }));
}

TEST(AssimpFiles, GltfVersion1LoadsThroughItsOwnReader) {
  // assimp's glTF/ folder holds glTF 1.0 files; tinygltf reads 2.0, preprocess/gltf1_loader 1.0.
  const Scene truck = loadSceneFile(assimpPath("glTF/CesiumMilkTruck/CesiumMilkTruck.gltf"));
  expectConsistent(truck);
  EXPECT_EQ(truck.triangleCount(), 3624u);
  EXPECT_FALSE(truck.textures.empty());
  // The shipped binary 1.0 box lost 33 bytes somewhere: its header promises more than the file.
  expectError(assimpPath("glTF/BoxTextured-glTF-Binary/BoxTextured.glb"), "truncated");
}

// ---------------------------------------------------------------------------------------------
// Malformed files

TEST(MalformedFiles, GltfIndexOutOfRangeIsCountedOrRefused) {
  for (const char* rel : {"glTF2/IndexOutOfRange/IndexOutOfRange.gltf",
                          "glTF2/IndexOutOfRange/AllIndicesOutOfRange.gltf"}) {
    SCOPED_TRACE(rel);
    const std::string path = assimpPath(rel);
    try {
      const Scene scene = loadSceneFile(path);
      expectConsistent(scene);
      EXPECT_GT(scene.report.dropped_out_of_range, 0u);
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_EQ(msg.rfind(path + ": ", 0), 0u) << msg;
      EXPECT_NE(msg.find("out of range"), std::string::npos) << msg;
    }
  }
}

TEST(MalformedFiles, GltfMalformedFilesFailCleanly) {
  const char* files[] = {
      "glTF2/wrongTypes/badArray.gltf",
      "glTF2/wrongTypes/badExtension.gltf",
      "glTF2/wrongTypes/badNumber.gltf",
      "glTF2/wrongTypes/badObject.gltf",
      "glTF2/wrongTypes/badString.gltf",
      "glTF2/wrongTypes/badUint.gltf",
      "glTF2/MissingBin/BoxTextured.gltf",
      "glTF2/IncorrectVertexArrays/Cube.gltf",
      "glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
      "glTF2/SchemaFailures/sceneWrongType.gltf",
      "glTF2/RecursiveNodes/RecursiveNodes.gltf",
      "glTF2/TestNoRootNode/NoScene.gltf",
      "glTF2/TestNoRootNode/SceneWithoutNodes.gltf",
      "glTF2/draco/2CylinderEngine.gltf",
      "glTF/IncorrectVertexArrays/Cube_v1.gltf",
  };
  for (const char* rel : files) expectLoadOrCleanError(assimpPath(rel));
}

TEST(MalformedFiles, GltfSpecificDiagnoses) {
  expectError(assimpPath("glTF2/MissingBin/BoxTextured.gltf"), "BoxTextured0.bin");
  expectError(assimpPath("glTF2/RecursiveNodes/RecursiveNodes.gltf"), "cycle");
  // Every vertex is infinite: all triangles dropped and counted, so the file has none left.
  expectError(assimpPath("glTF2/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb"), "non-finite");
}

// JSON nested 100,000 deep (a 200 KB file) is refused with one line before it is parsed, in
// glTF 2.0 text and binary and in glTF 1.0: parsing and destroying it would run the stack out.
TEST(MalformedFiles, DeeplyNestedJsonIsRefused) {
  ScratchDir dir;
  const std::string deep = std::string(100000, '[') + std::string(100000, ']');
  auto write = [&](const std::string& name, const std::string& bytes) {
    std::ofstream(dir.file(name), std::ios::binary) << bytes;
    return dir.file(name);
  };
  const std::string v2 = "{\"asset\":{\"version\":\"2.0\"},\"extras\":" + deep + "}";
  const std::string v1 = "{\"asset\":{\"version\":\"1.0\"},\"extras\":" + deep + "}";
  expectError(write("deep.gltf", v2), "nests arrays and objects more than");
  expectError(write("deep1.gltf", v1), "nests arrays and objects more than");
  std::string chunk = v2;
  while (chunk.size() % 4) chunk += ' ';
  std::string glb = "glTF";
  auto word = [&](uint32_t v) { glb.append(reinterpret_cast<const char*>(&v), 4); };
  word(2);
  word(uint32_t(20 + chunk.size()));
  word(uint32_t(chunk.size()));
  word(0x4E4F534Au);  // "JSON"
  glb += chunk;
  expectError(write("deep.glb", glb), "nests arrays and objects more than");
  // A document nested within the bound still loads as far as its content allows.
  const std::string shallow = std::string(100, '[') + std::string(100, ']');
  const std::string message = loadOrError(
      write("shallow.gltf", "{\"asset\":{\"version\":\"2.0\"},\"extras\":" + shallow + "}"));
  EXPECT_EQ(message.find("nests"), std::string::npos) << message;
}

TEST(MalformedFiles, EveryFileInAssimpInvalidFolder) {
  size_t files = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(assimpPath("invalid"))) {
    if (!entry.is_regular_file()) continue;
    ++files;
    expectLoadOrCleanError(entry.path().string());
  }
  EXPECT_GT(files, 0u);
  expectError(assimpPath("invalid/empty.obj"), "empty");
  expectError(assimpPath("invalid/empty.ply"), "empty");
  expectError(assimpPath("invalid/empty.off"), "empty");
  expectError(assimpPath("invalid/OutOfMemory.off"), "OFF");
  expectError(assimpPath("invalid/empty.3ds"), ".3ds");

  // malformed.obj: faces with out-of-range vertex indices, counted.
  const Scene scene = loadSceneFile(assimpPath("invalid/malformed.obj"));
  expectConsistent(scene);
  EXPECT_GT(scene.report.dropped_out_of_range, 0u);
}

// Lines of separators only (vertical tabs, form feeds) are blank lines, in the header and among the
// faces alike (a face line of vertical tabs once read a first word that did not exist).
TEST(MalformedFiles, OffLinesOfVerticalTabsAreBlank) {
  ScratchDir dir;
  writeBytes(dir.file("vt.off"), "\v\f\nOFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n\v\v\v\n3 0 1 2\n");
  EXPECT_EQ(loadSceneFile(dir.file("vt.off")).report.triangles_loaded, 1u);
  writeBytes(dir.file("short.off"), "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n\v\v\v\n");
  expectError(dir.file("short.off"), "short.off");
}

// An element without properties holds no bytes, so nothing in the file bounds its count: such
// elements are skipped rather than walked (4 billion empty entries once took minutes), and
// vertices without properties are an error.
TEST(MalformedFiles, PlyElementsWithoutPropertiesAreSkippedNotWalked) {
  ScratchDir dir;
  const std::string triangle =
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\n";
  for (const char* encoding : {"ascii", "binary_little_endian"}) {
    std::string body = std::string("ply\nformat ") + encoding + " 1.0\n" + triangle;
    for (int i = 0; i < 8; ++i) body += "element tristrips 4294967295\n";
    body += "end_header\n";
    if (std::string(encoding) == "ascii") {
      body += "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    } else {
      const float corners[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
      body.append(reinterpret_cast<const char*>(corners), sizeof corners);
      const char face[] = {3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0};
      body.append(face, sizeof face);
    }
    const std::string name = std::string("empty_elements_") + encoding + ".ply";
    writeBytes(dir.file(name), body);
    EXPECT_EQ(loadSceneFile(dir.file(name)).report.triangles_loaded, 1u) << encoding;
  }
  writeBytes(dir.file("bare_vertices.ply"),
             "ply\nformat binary_little_endian 1.0\nelement vertex 4294967295\nend_header\n");
  expectError(dir.file("bare_vertices.ply"), "no properties");
}

TEST(MalformedFiles, TruncatedBinariesAndEmptyFilesAreErrors) {
  ScratchDir dir;
  const std::string stl = readBytes(assimpPath("STL/Spider_binary.stl"));
  writeBytes(dir.file("spider_cut.stl"), stl.substr(0, 84 + 50 * 10 + 17));
  expectError(dir.file("spider_cut.stl"), "truncated");
  writeBytes(dir.file("header_only.stl"), stl.substr(0, 40));
  expectError(dir.file("header_only.stl"), "truncated");

  const std::string horse = readBytes(modelPath("horse.ply"));
  writeBytes(dir.file("horse_cut.ply"), horse.substr(0, horse.size() / 2));
  expectError(dir.file("horse_cut.ply"), "truncated");
  writeBytes(dir.file("horse_faces_cut.ply"), horse.substr(0, horse.size() - 100));
  expectError(dir.file("horse_faces_cut.ply"), "truncated");
  writeBytes(dir.file("horse_header_cut.ply"), horse.substr(0, 60));
  expectError(dir.file("horse_header_cut.ply"), "horse_header_cut.ply");

  const std::string strips = readBytes(dataPath("tristrips_binary_le.ply"));
  writeBytes(dir.file("strips_cut.ply"), strips.substr(0, strips.size() - 6));
  expectError(dir.file("strips_cut.ply"), "truncated");

  const std::string glb = readBytes(assimpPath("glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"));
  writeBytes(dir.file("box_cut.glb"), glb.substr(0, glb.size() / 2));
  expectError(dir.file("box_cut.glb"), "box_cut.glb");

  const std::string off = readBytes(assimpPath("OFF/Wuson.off"));
  writeBytes(dir.file("wuson_cut.off"), off.substr(0, off.size() * 9 / 10));
  expectError(dir.file("wuson_cut.off"), "truncated");

  for (const char* name : {"empty.stl", "empty.glb", "empty.gltf"}) {
    writeBytes(dir.file(name), "");
    expectError(dir.file(name), "empty");
  }
}

TEST(MalformedFiles, CutAtManyPointsNeverCrashes) {
  // Every prefix length in steps: each must load consistently or fail with a proper Error.
  ScratchDir dir;
  const std::pair<std::string, std::string> sources[] = {
      {assimpPath("glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"), "cut.glb"},
      {assimpPath("PLY/cube_binary.ply"), "cut.ply"},
      {assimpPath("PLY/cube.ply"), "cut_ascii.ply"},
      {dataPath("tristrips_binary_be.ply"), "cut_strips.ply"},
      {assimpPath("OFF/Cube.off"), "cut.off"},
      {assimpPath("OBJ/box.obj"), "cut.obj"},
      {assimpPath("STL/triangle.stl"), "cut.stl"},
      {assimpPath("glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf"), "cut.gltf"},
  };
  for (const auto& [source, name] : sources) {
    const std::string bytes = readBytes(source);
    const size_t step = std::max<size_t>(1, bytes.size() / 60);
    for (size_t n = 1; n < bytes.size(); n += step) {
      writeBytes(dir.file(name), bytes.substr(0, n));
      expectLoadOrCleanError(dir.file(name));
    }
  }
}

TEST(LoaderErrors, MissingFileAndUnknownExtension) {
  expectError(dataPath("does_not_exist.obj"), "no such file");
  expectError(dataPath("polygons.fbx"), ".fbx");
  const std::string msg = loadOrError(dataPath("polygons.fbx"));
  EXPECT_NE(msg.find(".obj"), std::string::npos) << "supported formats not listed: " << msg;
  expectError(dataPath("no_extension"), "extension");
}

TEST(LoaderErrors, ExtensionIsCaseInsensitive) {
  ScratchDir dir;
  fs::copy_file(dataPath("polygons.obj"), dir.file("POLYGONS.OBJ"));
  EXPECT_EQ(loadSceneFile(dir.file("POLYGONS.OBJ")).triangleCount(), 12u);
}

// ---------------------------------------------------------------------------------------------
// Hand-made files (tests/data/README.md describes each)

TEST(PlyTriangleStrips, AllEncodingsGiveTheSameCorrectlyWoundTriangles) {
  // Strip A (6 vertices, z = 0) makes 4 triangles facing -z; after the -1 separator strip B
  // (4 vertices, z = 1) makes 2 facing +z. Alternate triangles are traversed backwards, and the
  // separator restarts that alternation.
  std::vector<uint32_t> reference;
  for (const char* file :
       {"tristrips_ascii.ply", "tristrips_binary_le.ply", "tristrips_binary_be.ply"}) {
    SCOPED_TRACE(file);
    const Scene scene = loadSceneFile(dataPath(file));
    expectConsistent(scene);
    ASSERT_EQ(scene.meshes.size(), 1u);
    const Mesh& mesh = scene.meshes[0];
    ASSERT_EQ(mesh.triangleCount(), 6u);
    EXPECT_EQ(droppedTotal(scene), 0u);
    for (size_t t = 0; t < 4; ++t) {
      EXPECT_LT(faceNormal(mesh, t).z, 0.0f) << "triangle " << t;
      EXPECT_EQ(corner(mesh, t, 0).z, 0.0f);
    }
    for (size_t t = 4; t < 6; ++t) {
      EXPECT_GT(faceNormal(mesh, t).z, 0.0f) << "triangle " << t;
      EXPECT_EQ(corner(mesh, t, 0).z, 1.0f);
    }
    if (reference.empty()) reference = mesh.indices;
    EXPECT_EQ(mesh.indices, reference);
  }
}

TEST(ObjPolygons, QuadPentagonAndConcaveOctagonAreTriangulated) {
  const Scene scene = loadSceneFile(dataPath("polygons.obj"));
  expectConsistent(scene);
  const Mesh& mesh = scene.meshes.at(0);
  EXPECT_EQ(scene.report.polygons_triangulated, 3u);
  // quad 2 + pentagon 3 + octagon 6 + triangle 1
  ASSERT_EQ(mesh.triangleCount(), 12u);
  EXPECT_EQ(droppedTotal(scene), 0u);
  // Every triangle keeps the polygons' counter-clockwise winding. A fan of the "U" octagon from
  // its first corner would fold triangles over (negative z) and cover some area twice, so the
  // unsigned areas would add up to more than the polygons' 1 + 2.5 + 5 + 0.5.
  double area = 0.0;
  for (size_t t = 0; t < mesh.triangleCount(); ++t) {
    const glm::vec3 n = faceNormal(mesh, t);
    EXPECT_GT(n.z, 0.0f) << "triangle " << t;
    area += 0.5 * std::abs(static_cast<double>(n.z));
  }
  EXPECT_NEAR(area, 9.0, 1e-9);
}

TEST(ObjValidation, NanVertexAndOutOfRangeIndexAreCounted) {
  const Scene scene = loadSceneFile(dataPath("bad_vertices.obj"));
  expectConsistent(scene);
  EXPECT_EQ(scene.report.dropped_nonfinite, 1u);
  EXPECT_EQ(scene.report.dropped_out_of_range, 1u);
  EXPECT_EQ(scene.report.dropped_degenerate, 1u);  // f 1 2 2
  EXPECT_EQ(scene.report.triangles_loaded, 2u);
  // The triangle after the nan vertex still uses the file's vertex 5 = (1, 1, 0): an unreadable
  // vertex line must not shift the vertices that follow it.
  const Mesh& mesh = scene.meshes.at(0);
  ASSERT_EQ(mesh.triangleCount(), 2u);
  EXPECT_EQ(corner(mesh, 1, 0), glm::vec3(1, 0, 0));
  EXPECT_EQ(corner(mesh, 1, 1), glm::vec3(1, 1, 0));
  EXPECT_EQ(corner(mesh, 1, 2), glm::vec3(0, 1, 0));
}

TEST(OffAndStl, BadCornersAreCountedNotMangled) {
  ScratchDir dir;
  // A nan coordinate, a repeated corner, an index past the vertex count, and a good quad.
  writeBytes(dir.file("bad.off"),
             "OFF\n5 4 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\nnan 0 0\n"
             "4 0 1 1 2\n3 0 2 99\n3 0 1 4\n4 0 1 2 3\n");
  const Scene off = loadSceneFile(dir.file("bad.off"));
  expectConsistent(off);
  EXPECT_EQ(off.report.dropped_nonfinite, 1u);
  EXPECT_EQ(off.report.dropped_out_of_range, 1u);
  EXPECT_EQ(off.report.dropped_degenerate, 1u);  // (0 1 1) of the first quad's fan
  EXPECT_EQ(off.report.polygons_triangulated, 2u);
  EXPECT_EQ(off.report.triangles_loaded, 3u);

  // Binary STL: the second facet has a nan corner. Its finite corners are shared with the first
  // facet, the nan corner must not be merged into any vertex.
  const float facets[4][3][3] = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},
                                 {{std::nanf(""), 0, 0}, {1, 0, 0}, {0, 1, 0}},
                                 {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}},
                                 {{5, 5, 5}, {6, 5, 5}, {5, 6, 5}}};
  std::string stl(80, ' ');
  const uint32_t count = 4;
  stl.append(reinterpret_cast<const char*>(&count), 4);  // the test machines are little-endian
  for (const auto& facet : facets) {
    stl.append(12, '\0');  // normal
    stl.append(reinterpret_cast<const char*>(facet), sizeof facet);
    stl.append(2, '\0');
  }
  writeBytes(dir.file("nan.stl"), stl);
  const Scene binary = loadSceneFile(dir.file("nan.stl"));
  expectConsistent(binary);
  EXPECT_EQ(binary.report.dropped_nonfinite, 1u);
  EXPECT_EQ(binary.report.triangles_loaded, 3u);
  EXPECT_EQ(binary.meshes.at(0).positions.size(), 3u + 1u + 3u + 3u);  // welded, nan apart

  writeBytes(dir.file("nan_ascii.stl"),
             "solid t\n"
             "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
             "endloop\nendfacet\n"
             "facet normal 0 0 1\nouter loop\nvertex nan 0 0\nvertex 1 0 0\nvertex 0 1 0\n"
             "endloop\nendfacet\n"
             "endsolid t\n");
  const Scene ascii = loadSceneFile(dir.file("nan_ascii.stl"));
  EXPECT_EQ(ascii.report.dropped_nonfinite, 1u);
  EXPECT_EQ(ascii.report.triangles_loaded, 1u);
}

// An ASCII STL's stray 'endfacet' (no 'facet' before it) and a facet never ended are each
// counted as what they are: no count wraps below zero.
TEST(OffAndStl, StrayAndMissingEndfacetAreCounted) {
  ScratchDir dir;
  const std::string facet =
      "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\n";
  writeBytes(dir.file("stray.stl"),
             "solid t\n" + facet + "endfacet\nendfacet\n" + facet + "endfacet\nendsolid t\n");
  const Scene stray = loadSceneFile(dir.file("stray.stl"));
  EXPECT_EQ(stray.report.triangles_loaded, 2u);
  ASSERT_EQ(stray.report.warnings.size(), 1u);
  EXPECT_EQ(stray.report.warnings[0], "1 'endfacet' without its 'facet'");
  writeBytes(dir.file("cut.stl"), "solid t\n" + facet + "endfacet\n" + facet);
  const Scene cut = loadSceneFile(dir.file("cut.stl"));
  EXPECT_EQ(cut.report.triangles_loaded, 1u);
  ASSERT_GE(cut.report.warnings.size(), 1u);
  EXPECT_EQ(cut.report.warnings[0], "1 facets without 'endfacet' (file cut short?) dropped");
}

// A long OFF face line that does not list its corners: the problem is stated before the quoted
// line, which is cut short.
TEST(OffAndStl, LongBadFaceLineStatesTheProblemFirst) {
  ScratchDir dir;
  std::string line = "100000";
  for (int i = 0; i < 5000; ++i) line += " 1";
  writeBytes(dir.file("long.off"), "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n" + line + "\n");
  const std::string message = loadOrError(dir.file("long.off"));
  EXPECT_NE(message.find("does not list the corners it declares"), std::string::npos) << message;
  EXPECT_LT(message.size(), 300u) << message;
}

TEST(GltfSecurity, UrisMustStayInsideTheAssetFolder) {
  expectError(dataPath("gltf/escape_buffer.gltf"), "../../../../../../../../../../etc/passwd");
  expectError(dataPath("gltf/absolute_buffer.gltf"), "/etc/passwd");
  // An image outside the folder is refused too, although tinygltf treats images as optional.
  expectError(dataPath("gltf/escape_image.gltf"), "../polygons.obj");
}

TEST(GltfSecurity, SymlinkOutOfTheFolderIsRefused) {
  ScratchDir dir;
  fs::create_directory(dir.file("asset"));
  const std::string uri = "../../../../../../../../../../etc/passwd";
  std::string gltf = readBytes(dataPath("gltf/escape_buffer.gltf"));
  gltf.replace(gltf.find(uri), uri.size(), "link.bin");
  writeBytes(dir.file("asset/linked.gltf"), gltf);
  // The buffer's 36 bytes exist, but outside the asset folder, reached through a link inside it.
  writeBytes(dir.file("outside.bin"), std::string(36, '\0'));
  fs::create_symlink(dir.file("outside.bin"), dir.file("asset/link.bin"));
  expectError(dir.file("asset/linked.gltf"), "link.bin");
}

// URIs are decoded as RFC 3986 says, as the glTF 1.0 reader does: a malformed escape ("%zz")
// and '+' are taken as written (tinygltf's own decoder would make them a NUL byte and a space);
// "%20" is a space.
TEST(GltfUris, DecodedAsWrittenWhereNotAValidEscape) {
  const std::string uri = "../../../../../../../../../../etc/passwd";
  const std::string gltf = readBytes(dataPath("gltf/escape_buffer.gltf"));
  const float corners[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::string buffer(reinterpret_cast<const char*>(corners), sizeof(corners));
  for (const auto& [written, file] :
       std::vector<std::pair<std::string, std::string>>{{"tri%zz.bin", "tri%zz.bin"},
                                                        {"a+b.bin", "a+b.bin"},
                                                        {"with%20space.bin", "with space.bin"},
                                                        {"100%.bin", "100%.bin"}}) {
    SCOPED_TRACE(written);
    ScratchDir dir;
    std::string text = gltf;
    text.replace(text.find(uri), uri.size(), written);
    writeBytes(dir.file("asset.gltf"), text);
    writeBytes(dir.file(file), buffer);
    const Scene scene = loadSceneFile(dir.file("asset.gltf"));
    expectConsistent(scene);
    EXPECT_EQ(scene.report.triangles_loaded, 1u);
  }
  // A real NUL escape is still refused, named as written.
  ScratchDir dir;
  std::string text = gltf;
  text.replace(text.find(uri), uri.size(), "tri%00.bin");
  writeBytes(dir.file("asset.gltf"), text);
  expectError(dir.file("asset.gltf"), "'tri%00.bin' holds a NUL");
}

TEST(GltfMaterials, BlendOpacityColourAndTextureUri) {
  // triangle.gltf names texture.png, which is not beside it: images are decoded, so a missing
  // one fails the load, naming it.
  expectError(dataPath("gltf/triangle.gltf"), "texture.png");
  // Beside an image of that name it loads. The primitive has no TEXCOORD_0, so the material
  // keeps the texture's name but is drawn untextured (with a warning).
  ScratchDir dir;
  fs::copy_file(dataPath("gltf/triangle.gltf"), dir.file("triangle.gltf"));
  fs::copy_file(assimpPath("glTF2/BoxTextured-glTF/CesiumLogoFlat.png"), dir.file("texture.png"));
  const Scene scene = loadSceneFile(dir.file("triangle.gltf"));
  expectConsistent(scene);
  ASSERT_EQ(scene.instances.size(), 1u);
  EXPECT_EQ(scene.instances[0].name, "triangle");
  const strata::Material& mat = scene.materials.at(scene.meshes.at(0).material);
  EXPECT_EQ(mat.color, glm::vec4(1.0f, 0.0f, 0.0f, 0.25f));
  EXPECT_EQ(mat.opacity, 0.25f);  // alphaMode BLEND takes the base colour's alpha
  EXPECT_EQ(mat.base_color_texture, "texture.png");
  EXPECT_EQ(mat.texture, -1);
  EXPECT_FALSE(scene.report.warnings.empty());
}

// ---------------------------------------------------------------------------------------------
// Validation on its own

TEST(Validation, DropsAndCountsEachKindOnce) {
  Mesh mesh;
  const float nan = std::nanf("");
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {nan, 0, 0}, {2, 0, 0}, {1e-3f, 1e-9f, 0}};
  mesh.indices = {0, 1, 2,  // kept
                  3, 1, 2,  // non-finite
                  0, 1, 9,  // out of range
                  3, 1, 9,  // out of range and non-finite: counted once, as out of range
                  0, 1, 1,  // repeated corner
                  0, 1, 4,  // collinear: exactly zero area
                  0, 4, 5,  // nearly collinear: sine of its flattest angle ~5e-10
                  2, 1};    // a partial triangle
  strata::LoadReport report;
  strata::validateMesh(mesh, report);
  EXPECT_EQ(mesh.indices, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_EQ(report.triangles_loaded, 1u);
  EXPECT_EQ(report.dropped_nonfinite, 1u);
  EXPECT_EQ(report.dropped_out_of_range, 3u);
  EXPECT_EQ(report.dropped_degenerate, 3u);
}

TEST(Validation, DegeneracyDoesNotDependOnScale) {
  for (float scale : {1e-20f, 1e-3f, 1.0f, 1e3f, 1e20f}) {
    SCOPED_TRACE(scale);
    Mesh mesh;
    mesh.positions = {glm::vec3(0, 0, 0) * scale, glm::vec3(1, 0, 0) * scale,
                      glm::vec3(0, 1e-3f, 0) * scale,   // thin but real
                      glm::vec3(2, 1e-9f, 0) * scale};  // flat to float precision
    mesh.indices = {0, 1, 2, 0, 1, 3};
    strata::LoadReport report;
    strata::validateMesh(mesh, report);
    EXPECT_EQ(report.triangles_loaded, 1u);
    EXPECT_EQ(report.dropped_degenerate, 1u);
  }
}

}  // namespace
