// The massive built-in scenes (preprocess/massive_scenes.h) and the mesh writer
// (preprocess/mesh_writer.h): sizes, determinism, the topology each scene promises, and a
// round trip through PLY and OBJ files and the loaders.
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <string>
#include <utility>

#include "preprocess/builtin_scenes.h"
#include "preprocess/massive_scenes.h"
#include "preprocess/mesh_loader.h"
#include "preprocess/mesh_writer.h"
#include "preprocess/scene/world_geometry.h"
#include "test_support.h"

namespace {

using namespace strata;

// How many faces use each undirected edge, by vertex position (vertices are not shared
// between faces in every scene).
std::map<int, size_t> edgeUseHistogram(const WorldGeometry& g) {
  auto key = [&](uint32_t v) {
    const glm::vec3& p = g.positions[v];
    return std::make_tuple(p.x, p.y, p.z);
  };
  std::map<std::pair<std::tuple<float, float, float>, std::tuple<float, float, float>>, int> uses;
  for (uint32_t t = 0; t < g.triangleCount(); ++t)
    for (int k = 0; k < 3; ++k) {
      auto a = key(g.indices[t * 3 + k]), b = key(g.indices[t * 3 + (k + 1) % 3]);
      if (b < a) std::swap(a, b);
      ++uses[{a, b}];
    }
  std::map<int, size_t> histogram;
  for (const auto& [edge, n] : uses) ++histogram[n];
  return histogram;
}

TEST(MassiveScenes, SizesAndDeterminism) {
  struct Case {
    const char* spec;
    uint64_t triangles;
  };
  for (const Case& c : {Case{"builtin:hairball:20", 20ull * 2400},
                        Case{"builtin:shells:3", 3ull * 65024}, Case{"builtin:soup:5000", 5000}}) {
    const Scene a = loadScene(c.spec), b = loadScene(c.spec);
    EXPECT_EQ(a.triangleCount(), c.triangles) << c.spec;
    const WorldGeometry ga = WorldGeometry::fromScene(a), gb = WorldGeometry::fromScene(b);
    ASSERT_EQ(ga.positions.size(), gb.positions.size()) << c.spec;
    EXPECT_EQ(0, std::memcmp(ga.positions.data(), gb.positions.data(),
                             ga.positions.size() * sizeof(glm::vec3)))
        << c.spec << " is not deterministic";
    EXPECT_EQ(ga.indices, gb.indices) << c.spec;
    for (const glm::vec3& p : ga.positions)
      ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << c.spec;
  }
  const Scene city = loadScene("builtin:city:4");
  EXPECT_GT(city.triangleCount(), 16u * 9 * 150);
  EXPECT_THROW(loadScene("builtin:hairball:0"), Error);
  EXPECT_THROW(loadScene("builtin:city:many"), Error);
  EXPECT_THROW(loadScene("builtin:shells:65"), Error);
}

TEST(MassiveScenes, TopologyIsWhatEachSceneStandsFor) {
  // Tubes and shells are closed: every edge has exactly two faces.
  for (const char* spec : {"builtin:hairball:6", "builtin:shells:2"}) {
    const std::map<int, size_t> h = edgeUseHistogram(WorldGeometry::fromScene(loadScene(spec)));
    ASSERT_EQ(h.size(), 1u) << spec;
    EXPECT_EQ(h.begin()->first, 2) << spec;
  }
  // The city has open edges (open walls, signs, grounds).
  EXPECT_GT(edgeUseHistogram(WorldGeometry::fromScene(loadScene("builtin:city:3"))).count(1), 0u);
  // The soup has edges of three or more faces, and exact duplicate faces.
  const WorldGeometry soup = WorldGeometry::fromScene(loadScene("builtin:soup:4000"));
  const std::map<int, size_t> h = edgeUseHistogram(soup);
  EXPECT_GT(h.rbegin()->first, 2);
  std::map<std::tuple<uint32_t, uint32_t, uint32_t>, int> faces;
  int duplicates = 0;
  for (uint32_t t = 0; t < soup.triangleCount(); ++t)
    duplicates +=
        faces[{soup.indices[t * 3], soup.indices[t * 3 + 1], soup.indices[t * 3 + 2]}]++ > 0;
  EXPECT_GT(duplicates, 100);
}

TEST(MeshWriter, PlyAndObjRoundTripThroughTheLoaders) {
  const test::ScratchDir dir;
  const WorldGeometry g = WorldGeometry::fromScene(loadScene("builtin:city:2"));
  const MeshView view{g.positions.data(), g.positions.size(), g.indices.data(), g.triangleCount()};
  for (const char* name : {"city.ply", "city.obj"}) {
    const std::string path = (dir.path() / name).string();
    writeMeshFile(path, view);
    const WorldGeometry back = WorldGeometry::fromScene(loadSceneFile(path));
    ASSERT_EQ(back.triangleCount(), g.triangleCount()) << name;
    for (uint32_t t = 0; t < g.triangleCount(); ++t)
      for (int k = 0; k < 3; ++k)
        ASSERT_EQ(back.positions[back.indices[t * 3 + k]], g.positions[g.indices[t * 3 + k]])
            << name << " triangle " << t;
  }
  EXPECT_THROW(writeMeshFile((dir.path() / "city.stl").string(), view), Error);
  EXPECT_THROW(writeMeshFile("/nonexistent-folder/city.ply", view), Error);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"city.obj", "city.ply"}));
}

}  // namespace
