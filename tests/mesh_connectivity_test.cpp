// Half-edge connectivity through OpenMesh (preprocess/mesh_connectivity.h) and the coloured PLY
// export of convex cells (preprocess/cell_export.h, `strata prep --export`).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

// OpenMesh's properties append default-constructed (uninitialised) vectors, which GCC 12 warns
// about inside its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#pragma GCC diagnostic pop

#include "engine/cells/cell_order.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/cell_export.h"
#include "preprocess/convex_cells.h"
#include "preprocess/mesh_connectivity.h"
#include "preprocess/mesh_loader.h"
#include "preprocess/scene/world_geometry.h"
#include "test_meshes.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using namespace strata;
using test::loadMesh;
using test::unweld;
using test::view;

// A unit cube: 8 shared corners, 12 triangles wound outwards.
Mesh cube() {
  Mesh m;
  for (int i = 0; i < 8; ++i)
    m.positions.push_back({float(i & 1), float((i >> 1) & 1), float((i >> 2) & 1)});
  m.indices = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
               2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return m;
}

// The rule the decomposition grows cells by, written independently: for each slot, the slots of
// all triangles (not excluded, corners distinct after welding) having both its welded corners.
std::vector<std::vector<uint32_t>> vertexPairGroups(const Mesh& m,
                                                    const std::vector<uint8_t>& exclude) {
  using Key = std::array<float, 3>;
  auto key = [](const glm::vec3& p) {
    return Key{p.x + 0.0f, p.y + 0.0f, p.z + 0.0f};
  };  // -0 is +0
  std::map<std::pair<Key, Key>, std::vector<uint32_t>> by_pair;
  const size_t T = m.triangleCount();
  for (size_t t = 0; t < T; ++t) {
    if (!exclude.empty() && exclude[t]) continue;
    const Key p[3] = {key(m.positions[m.indices[3 * t]]), key(m.positions[m.indices[3 * t + 1]]),
                      key(m.positions[m.indices[3 * t + 2]])};
    if (p[0] == p[1] || p[1] == p[2] || p[0] == p[2]) continue;
    for (int k = 0; k < 3; ++k)
      by_pair[std::minmax(p[k], p[(k + 1) % 3])].push_back(uint32_t(3 * t + k));
  }
  std::vector<std::vector<uint32_t>> group(3 * T);
  for (const auto& [pair, slots] : by_pair)
    for (uint32_t s : slots) group[s] = slots;
  return group;
}

void expectGroupsMatchVertexPairs(const Mesh& m, const MeshConnectivity& c,
                                  const std::vector<uint8_t>& exclude = {}) {
  const std::vector<std::vector<uint32_t>> ref = vertexPairGroups(m, exclude);
  ASSERT_EQ(c.triangleCount(), m.triangleCount());
  size_t slots = 0;
  for (uint32_t e = 0; e < c.edgeCount(); ++e) {
    ASSERT_GT(c.edgeFaceCount(e), 0u);
    const SlotRange r = c.edgeSlots(e);
    ASSERT_TRUE(std::is_sorted(r.begin(), r.end()));
    slots += r.size();
  }
  size_t ref_slots = 0;
  for (uint32_t s = 0; s < 3 * m.triangleCount(); ++s) {
    ref_slots += !ref[s].empty();
    const uint32_t e = c.edgeOfSlot(s);
    if (ref[s].empty()) {
      ASSERT_EQ(e, MeshConnectivity::kNone) << "slot " << s;
      continue;
    }
    ASSERT_NE(e, MeshConnectivity::kNone) << "slot " << s;
    const SlotRange r = c.edgeSlots(e);
    ASSERT_EQ(std::vector<uint32_t>(r.begin(), r.end()), ref[s]) << "slot " << s;
  }
  EXPECT_EQ(slots, ref_slots);
}

using test::ScratchDir;

using ReadMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// Reads a PLY back with OpenMesh's reader, with its face and vertex colours.
ReadMesh readPly(const std::string& path, OpenMesh::IO::Options* got) {
  ReadMesh m;
  m.request_vertex_colors();
  m.request_face_colors();
  OpenMesh::IO::Options opt = OpenMesh::IO::Options::VertexColor | OpenMesh::IO::Options::FaceColor;
  EXPECT_TRUE(OpenMesh::IO::read_mesh(m, path, opt)) << path;
  *got = opt;
  return m;
}

// Checks an export of `cells` over `mesh` read back: face f is the f-th listed triangle (same
// corners, in some rotation), coloured by its cell on the face and its vertices; one colour per
// cell, different cells different colours.
void expectExportMatches(const std::string& path, const MeshView& mesh,
                         const std::vector<uint32_t>& cell_first,
                         const std::vector<uint32_t>& cell_triangles) {
  OpenMesh::IO::Options got;
  const ReadMesh r = readPly(path, &got);
  EXPECT_TRUE(got.face_has_color());
  EXPECT_TRUE(got.vertex_has_color());
  ASSERT_EQ(r.n_faces(), cell_triangles.size());
  ASSERT_EQ(cell_triangles.size(), cell_first.back());
  std::set<std::array<int, 3>> cell_colors;
  size_t f = 0;
  for (size_t c = 0; c + 1 < cell_first.size(); ++c) {
    std::set<std::array<int, 3>> colors;
    for (uint32_t i = cell_first[c]; i < cell_first[c + 1]; ++i, ++f) {
      const OpenMesh::FaceHandle fh{int(f)};
      const ReadMesh::Color fc = r.color(fh);
      colors.insert({fc[0], fc[1], fc[2]});
      const glm::u8vec3 want = cellColor(uint32_t(c));
      const std::array<int, 3> have_rgb{fc[0], fc[1], fc[2]}, want_rgb{want.r, want.g, want.b};
      EXPECT_EQ(have_rgb, want_rgb) << "face " << f;
      std::vector<glm::vec3> corners, expect;
      for (auto v : r.fv_range(fh)) {
        const ReadMesh::Color vc = r.color(v);
        EXPECT_TRUE(vc == fc) << "face " << f;
        const ReadMesh::Point p = r.point(v);
        corners.push_back({p[0], p[1], p[2]});
      }
      for (int k = 0; k < 3; ++k)
        expect.push_back(mesh.positions[mesh.indices[3 * size_t(cell_triangles[i]) + k]]);
      ASSERT_EQ(corners.size(), 3u);
      // The same corners in the same cyclic order (the winding is kept).
      bool rotation = false;
      for (int s = 0; s < 3; ++s)
        rotation = rotation || (corners[0] == expect[s] && corners[1] == expect[(s + 1) % 3] &&
                                corners[2] == expect[(s + 2) % 3]);
      EXPECT_TRUE(rotation) << "face " << f;
    }
    EXPECT_EQ(colors.size(), 1u) << "cell " << c;
    cell_colors.insert(*colors.begin());
  }
  EXPECT_EQ(cell_colors.size(), cell_first.size() - 1);
}

}  // namespace

TEST(MeshConnectivity, ClosedCube) {
  const Mesh m = cube();
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.counts().halfedge_faces, 12u);
  EXPECT_EQ(c.counts().nonmanifold_faces, 0u);
  EXPECT_EQ(c.counts().vertices, 8u);
  EXPECT_EQ(c.edgeCount(), 18u);
  EXPECT_TRUE(c.boundaryEdges().empty());
  EXPECT_TRUE(c.nonManifoldEdges().empty());
  EXPECT_EQ(c.counts().inconsistent_edges, 0u);
  for (uint32_t t = 0; t < 12; ++t) {
    EXPECT_EQ(c.faceKind(t), FaceKind::Manifold);
    EXPECT_EQ(c.faceNeighbours(t).size(), 3u) << "triangle " << t;
    for (int k = 0; k < 3; ++k) {
      const std::vector<uint32_t> n = c.neighbours(t, k);
      ASSERT_EQ(n.size(), 1u);
      // Symmetric: the neighbour sees t across the same edge.
      const uint32_t u = n[0];
      bool back = false;
      for (int j = 0; j < 3; ++j)
        back = back ||
               (c.edgeOf(u, j) == c.edgeOf(t, k) && c.neighbours(u, j) == std::vector<uint32_t>{t});
      EXPECT_TRUE(back);
    }
  }
  expectGroupsMatchVertexPairs(m, c);

  // As a soup: welding finds the same connectivity; without welding every edge is a boundary.
  const Mesh soup = unweld(m);
  const MeshConnectivity w(view(soup));
  EXPECT_EQ(w.edgeCount(), 18u);
  EXPECT_EQ(w.counts().boundary_edges, 0u);
  for (uint32_t t = 0; t < 12; ++t) EXPECT_EQ(w.faceNeighbours(t), c.faceNeighbours(t));
  ConnectivityOptions raw;
  raw.weld_positions = false;
  const MeshConnectivity r(view(soup), raw);
  EXPECT_EQ(r.edgeCount(), 36u);
  EXPECT_EQ(r.counts().boundary_edges, 36u);
  // makeBox's corners (split per face) weld to a closed box too.
  const MeshConnectivity b(view(makeBox({1.0f, 2.0f, 3.0f})));
  EXPECT_EQ(b.counts().boundary_edges, 0u);
  EXPECT_EQ(b.counts().vertices, 8u);
}

TEST(MeshConnectivity, OpenQuadStrip) {
  const uint32_t quads = 5;
  Mesh m;
  for (uint32_t i = 0; i <= quads; ++i) {
    m.positions.push_back({float(i), 0.0f, 0.0f});
    m.positions.push_back({float(i), 1.0f, 0.0f});
  }
  for (uint32_t i = 0; i < quads; ++i) {
    const uint32_t a = 2 * i, b = 2 * i + 1, c = 2 * i + 2, d = 2 * i + 3;
    m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
  }
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.counts().halfedge_faces, 2 * quads);
  EXPECT_EQ(c.edgeCount(), 4 * quads + 1);
  EXPECT_EQ(c.boundaryEdges().size(), 2 * quads + 2);
  EXPECT_EQ(c.counts().boundary_edges, 2 * quads + 2);
  EXPECT_TRUE(c.nonManifoldEdges().empty());
  for (uint32_t e : c.boundaryEdges()) EXPECT_EQ(c.edgeFaceCount(e), 1u);
  // Ends have one neighbour (their diagonal partner), inner triangles two.
  EXPECT_EQ(c.faceNeighbours(0).size(), 1u);
  EXPECT_EQ(c.faceNeighbours(2 * quads - 1).size(), 1u);
  for (uint32_t t = 1; t + 1 < 2 * quads; ++t) EXPECT_EQ(c.faceNeighbours(t).size(), 2u) << t;
  expectGroupsMatchVertexPairs(m, c);
}

// Three triangles on one edge: OpenMesh holds two, the third is refused, reported non-manifold
// and still adjacent to both.
TEST(MeshConnectivity, NonManifoldFan) {
  Mesh m;
  m.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0.5f}, {-1, 0.2f, 0.5f}, {0, 1, 0.5f}};
  m.indices = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.faceKind(0), FaceKind::Manifold);
  EXPECT_EQ(c.faceKind(1), FaceKind::Manifold);
  EXPECT_EQ(c.faceKind(2), FaceKind::NonManifold);
  EXPECT_EQ(c.nonManifoldFaces(), std::vector<uint32_t>{2});
  const std::vector<uint32_t> nm = c.nonManifoldEdges();
  ASSERT_EQ(nm.size(), 1u);
  EXPECT_EQ(c.edgeFaceCount(nm[0]), 3u);
  EXPECT_EQ(c.edgeOf(0, 0), nm[0]);
  EXPECT_EQ(c.neighbours(0, 0), (std::vector<uint32_t>{1, 2}));
  EXPECT_EQ(c.neighbours(1, 0), (std::vector<uint32_t>{0, 2}));
  EXPECT_EQ(c.neighbours(2, 0), (std::vector<uint32_t>{0, 1}));
  EXPECT_EQ(c.counts().boundary_edges, 6u);
  EXPECT_EQ(c.edgeCount(), 7u);
  expectGroupsMatchVertexPairs(m, c);

  // A five-page book: every page sees the other four across the spine.
  Mesh fan;
  fan.positions = {{0, 0, 0}, {0, 0, 1}};
  for (int i = 0; i < 5; ++i)
    fan.positions.push_back({std::cos(1.2f * i), std::sin(1.2f * i), 0.5f});
  for (uint32_t i = 0; i < 5; ++i)
    fan.indices.insert(fan.indices.end(), {i % 2 ? 1u : 0u, i % 2 ? 0u : 1u, 2 + i});
  const MeshConnectivity f(view(fan));
  EXPECT_EQ(f.counts().nonmanifold_faces, 3u);
  EXPECT_EQ(f.counts().nonmanifold_edges, 1u);
  for (uint32_t t = 0; t < 5; ++t) EXPECT_EQ(f.faceNeighbours(t).size(), 4u);
  expectGroupsMatchVertexPairs(fan, f);
}

TEST(MeshConnectivity, DuplicateFaces) {
  Mesh m = cube();
  const size_t n = m.triangleCount();
  m.indices.insert(m.indices.end(), {0, 2, 1});  // triangle 0 again
  m.indices.insert(m.indices.end(), {3, 2, 1});  // triangle 1 reversed
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.counts().halfedge_faces, n);
  EXPECT_EQ(c.nonManifoldFaces(), (std::vector<uint32_t>{uint32_t(n), uint32_t(n + 1)}));
  // The duplicate shares all three edges with its original.
  for (int k = 0; k < 3; ++k) {
    const std::vector<uint32_t> across = c.neighbours(uint32_t(n), k);
    EXPECT_TRUE(std::find(across.begin(), across.end(), 0u) != across.end()) << k;
  }
  EXPECT_EQ(c.edgeCount(), 18u);  // no new vertex pairs
  EXPECT_GT(c.counts().nonmanifold_edges, 0u);
  for (uint32_t t = 0; t < c.triangleCount(); ++t) EXPECT_GE(c.faceNeighbours(t).size(), 3u);
  expectGroupsMatchVertexPairs(m, c);

  // A lone triangle twice with one winding: a flipped-winding pair; with both windings: a closed
  // two-face pillow OpenMesh holds.
  Mesh tri;
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  tri.indices = {0, 1, 2, 0, 1, 2};
  const MeshConnectivity same(view(tri));
  EXPECT_EQ(same.faceKind(1), FaceKind::NonManifold);
  EXPECT_EQ(same.counts().inconsistent_edges, 3u);
  EXPECT_EQ(same.faceNeighbours(0), std::vector<uint32_t>{1});
  tri.indices = {0, 1, 2, 2, 1, 0};
  const MeshConnectivity pillow(view(tri));
  EXPECT_EQ(pillow.counts().halfedge_faces, 2u);
  EXPECT_EQ(pillow.counts().boundary_edges, 0u);
  EXPECT_EQ(pillow.counts().inconsistent_edges, 0u);
}

TEST(MeshConnectivity, FlippedWinding) {
  // A cube with one face turned over: OpenMesh refuses it (each edge already has a face on that
  // side); it keeps its three neighbours and its edges are reported inconsistent.
  Mesh m = cube();
  std::swap(m.indices[3 * 5 + 1], m.indices[3 * 5 + 2]);
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.nonManifoldFaces(), std::vector<uint32_t>{5});
  EXPECT_EQ(c.counts().inconsistent_edges, 3u);
  EXPECT_EQ(c.counts().nonmanifold_edges, 0u);
  EXPECT_EQ(c.counts().boundary_edges, 0u);
  for (uint32_t t = 0; t < 12; ++t) EXPECT_EQ(c.faceNeighbours(t).size(), 3u) << t;
  for (int k = 0; k < 3; ++k) EXPECT_TRUE(c.isInconsistentEdge(c.edgeOf(5, k)));
  const MeshConnectivity ref(view(cube()));
  for (uint32_t t = 0; t < 12; ++t) EXPECT_EQ(c.faceNeighbours(t), ref.faceNeighbours(t));
  expectGroupsMatchVertexPairs(m, c);

  // A soup with every other triangle flipped: same neighbours as the cube.
  Mesh soup = unweld(cube());
  for (size_t t = 0; t < 12; t += 2) std::swap(soup.indices[3 * t + 1], soup.indices[3 * t + 2]);
  const MeshConnectivity s(view(soup));
  for (uint32_t t = 0; t < 12; ++t) EXPECT_EQ(s.faceNeighbours(t), ref.faceNeighbours(t)) << t;
  EXPECT_EQ(s.counts().halfedge_faces + s.counts().nonmanifold_faces, 12u);
}

TEST(MeshConnectivity, DegenerateAndExcluded) {
  Mesh m = cube();
  const uint32_t mid = uint32_t(m.positions.size());
  m.positions.push_back({0.5f, 0.0f, 0.0f});       // on the edge 0-1
  m.indices.insert(m.indices.end(), {0, 1, mid});  // collinear: a face like any other
  m.indices.insert(m.indices.end(), {2, 2, 3});    // repeated corner
  m.positions.push_back(m.positions[3]);
  m.indices.insert(m.indices.end(),
                   {3, uint32_t(m.positions.size() - 1), 7});  // repeated after welding
  const MeshConnectivity c(view(m));
  EXPECT_EQ(c.faceKind(12), FaceKind::NonManifold);  // a third face on edge 0-1
  EXPECT_EQ(c.faceKind(13), FaceKind::Degenerate);
  EXPECT_EQ(c.faceKind(14), FaceKind::Degenerate);
  EXPECT_EQ(c.counts().degenerate_faces, 2u);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(c.edgeOf(13, k), MeshConnectivity::kNone);
  EXPECT_TRUE(c.faceNeighbours(13).empty());
  expectGroupsMatchVertexPairs(m, c);

  std::vector<uint8_t> exclude(m.triangleCount(), 0);
  exclude[12] = 1;
  ConnectivityOptions opt;
  opt.exclude = exclude.data();
  const MeshConnectivity x(view(m), opt);
  EXPECT_EQ(x.faceKind(12), FaceKind::Excluded);
  EXPECT_EQ(x.counts().excluded_faces, 1u);
  EXPECT_TRUE(x.faceNeighbours(12).empty());
  EXPECT_EQ(x.counts().nonmanifold_faces, 0u);
  EXPECT_EQ(x.counts().boundary_edges, 0u);
  expectGroupsMatchVertexPairs(m, x, exclude);
  EXPECT_STREQ(faceKindName(FaceKind::NonManifold), "non-manifold");
}

TEST(MeshConnectivity, BadInput) {
  Mesh m = cube();
  m.indices[7] = 99;
  try {
    const MeshConnectivity c(view(m));
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 2"), std::string::npos) << e.what();
  }
  const MeshConnectivity empty{MeshView{}};
  EXPECT_EQ(empty.edgeCount(), 0u);
  EXPECT_EQ(empty.triangleCount(), 0u);
}

// On every model, as loaded and as a soup with scattered flipped windings, every edge holds
// exactly the faces with both its corners (the vertex-pair rule the decomposition grows by).
TEST(MeshConnectivity, ModelsMatchVertexPairRule) {
  for (const char* name :
       {"teapot.obj", "horse.ply", "stanford-bunny.obj", "fandisk.obj", "rocker-arm.obj",
        "cheburashka.obj", "homer.obj", "cow.obj", "spot.obj"}) {
    SCOPED_TRACE(name);
    Mesh m = loadMesh(name);
    const MeshConnectivity c(view(m));
    EXPECT_EQ(
        c.counts().halfedge_faces + c.counts().nonmanifold_faces + c.counts().degenerate_faces,
        m.triangleCount());
    expectGroupsMatchVertexPairs(m, c);
    if (std::string(name) == "cow.obj" || std::string(name) == "teapot.obj") {
      Mesh soup = unweld(m);
      for (size_t t = 0; t < soup.triangleCount(); t += 3)
        std::swap(soup.indices[3 * t + 1], soup.indices[3 * t + 2]);
      const MeshConnectivity s(view(soup));
      expectGroupsMatchVertexPairs(soup, s);
    }
  }
}

TEST(CellExport, RoundTripThroughOpenMesh) {
  ScratchDir dir;
  // Two cubes apart (a cell each), a fan on a third cube's edge and a duplicate face: several
  // cells, and faces OpenMesh refuses with shared corners.
  Mesh m = cube();
  for (int copy = 1; copy < 3; ++copy) {
    const uint32_t base = uint32_t(m.positions.size());
    for (int i = 0; i < 8; ++i)
      m.positions.push_back(m.positions[i] + glm::vec3(2.0f * copy, 0, 0));
    for (int i = 0; i < 36; ++i) m.indices.push_back(base + m.indices[i]);
  }
  m.positions.push_back({4.5f, -1.0f, 0.5f});
  m.indices.insert(m.indices.end(), {16, 17, uint32_t(m.positions.size() - 1)});
  m.indices.insert(m.indices.end(), {m.indices[0], m.indices[1], m.indices[2]});
  m.indices.insert(m.indices.end(), {5, 5, 6});  // repeated corner
  const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
  ASSERT_GE(cells.cellCount(), 4u);
  const std::string path = (dir.path() / "cells.ply").string();
  exportCellsPly(path, view(m), cells);
  expectExportMatches(path, view(m), cells.cell_begin, cells.triangle_order);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"cells.ply"});  // no temporary left
  // Binary PLY with colours on faces and vertices.
  std::ifstream in(path, std::ios::binary);
  std::string header;
  for (std::string line; std::getline(in, line) && line != "end_header";) header += line + "\n";
  EXPECT_NE(header.find("format binary_little_endian"), std::string::npos) << header;
  EXPECT_NE(header.find("element face " + std::to_string(m.triangleCount())), std::string::npos)
      << header;
  const size_t face = header.find("element face");
  EXPECT_NE(header.find("property uchar red", face), std::string::npos) << header;
  EXPECT_NE(header.find("property uchar red"), header.rfind("property uchar red")) << header;
  // Exporting again replaces the file.
  exportCellsPly(path, view(m), cells);
  EXPECT_EQ(dir.entries(), std::vector<std::string>{"cells.ply"});
}

// What `strata prep --export` does: every instance of every mesh in world space.
TEST(CellExport, WorldSpaceScene) {
  ScratchDir dir;
  const auto [scene, g] = test::sceneAndGeometry("builtin:demo");
  const CellScene cells = CellScene::build(g, DecomposeOptions{}, (dir.path() / "cache").string());
  ASSERT_GT(cells.cellCount(), 1u);
  const MeshView world{g.positions.data(), g.positions.size(), g.indices.data(), g.triangleCount()};
  const std::string path = (dir.path() / "demo.ply").string();
  exportCellsPly(path, world, cells.cell_first.data(), cells.cellCount(),
                 cells.cell_triangles.data());
  EXPECT_EQ(cells.cell_triangles.size(), g.triangleCount());
  expectExportMatches(path, world, cells.cell_first, cells.cell_triangles);
}

TEST(CellExport, FailuresNameTheFileAndLeaveNoTemporary) {
  ScratchDir dir;
  const Mesh m = cube();
  const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
  auto expectError = [&](const std::string& path) {
    try {
      exportCellsPly(path, view(m), cells);
      ADD_FAILURE() << "no error for " << path;
    } catch (const Error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
  };
  expectError("/nonexistent-folder/cells.ply");
  // A folder that is a file.
  { std::ofstream(dir.path() / "file") << "x"; }
  expectError((dir.path() / "file" / "cells.ply").string());
  // The target is a folder: the rename fails and the temporary is removed.
  fs::create_directories(dir.path() / "taken.ply");
  expectError((dir.path() / "taken.ply").string());
  expectError((dir.path() / "cells.obj").string());  // not PLY
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"file", "taken.ply"}));
  // Cell data: a triangle listed again is written again (with corners of its own); a triangle
  // past the mesh is an error and writes nothing.
  const std::vector<uint32_t> first = {0, 13}, tris = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 0};
  const std::string again = (dir.path() / "again.ply").string();
  EXPECT_NO_THROW(exportCellsPly(again, view(m), first.data(), 1, tris.data()));
  expectExportMatches(again, view(m), first, tris);
  const std::vector<uint32_t> past = {0, 1};
  const uint32_t beyond = 12;
  EXPECT_THROW(exportCellsPly((dir.path() / "y.ply").string(), view(m), past.data(), 1, &beyond),
               Error);
  EXPECT_FALSE(fs::exists(dir.path() / "y.ply"));
}

TEST(CellExport, ColorsDistinct) {
  std::set<std::array<int, 3>> seen;
  for (uint32_t c = 0; c < 200000; ++c) {
    const glm::u8vec3 k = cellColor(c);
    EXPECT_GE(std::min({k.r, k.g, k.b}), 64);
    seen.insert({k.r, k.g, k.b});
  }
  EXPECT_EQ(seen.size(), 200000u);
}

// Report: a hash of the decomposition of every model (strict and paper) and of messy meshes, to
// compare the decomposition before and after a change to its adjacency; run with
// --gtest_also_run_disabled_tests.
TEST(MeshConnectivityReport, DISABLED_DecompositionHashes) {
  std::vector<std::pair<std::string, Mesh>> meshes;
  for (const char* name : {"teapot.obj", "horse.ply", "stanford-bunny.obj", "fandisk.obj",
                           "rocker-arm.obj", "cheburashka.obj", "homer.obj", "cow.obj", "spot.obj"})
    meshes.push_back({name, loadMesh(name)});
  Mesh soup = unweld(meshes.back().second);
  for (size_t t = 0; t < soup.triangleCount(); t += 3)
    std::swap(soup.indices[3 * t + 1], soup.indices[3 * t + 2]);
  meshes.push_back({"spot-soup-flipped", soup});
  Mesh fan;
  fan.positions = {{0, 0, 0}, {0, 0, 1}};
  for (int i = 0; i < 5; ++i)
    fan.positions.push_back({std::cos(1.2f * i), std::sin(1.2f * i), 0.5f});
  for (uint32_t i = 0; i < 5; ++i) fan.indices.insert(fan.indices.end(), {0, 1, 2 + i});
  meshes.push_back({"fan", fan});
  Mesh dup = meshes[0].second;
  for (size_t i = 0; i < 300; ++i) dup.indices.push_back(dup.indices[i]);
  meshes.push_back({"teapot-duplicates", dup});
  meshes.push_back({"uv-sphere-64x32", makeUvSphere(1.0f, 64, 32)});
  for (const auto& [name, mesh] : meshes) {
    for (DecomposeMode mode : {DecomposeMode::Strict, DecomposeMode::Paper}) {
      DecomposeOptions opt;
      opt.mode = mode;
      const auto t0 = std::chrono::steady_clock::now();
      const CellDecomposition cells = decomposeConvexCells(view(mesh), opt);
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      uint64_t h = 1469598103934665603ull;
      for (uint32_t v : cells.cell_begin) h = (h ^ v) * 1099511628211ull;
      for (uint32_t v : cells.triangle_order) h = (h ^ v) * 1099511628211ull;
      std::printf("%-20s %-6s tris %7zu cells %6u hash %016llx %.3f s\n", name.c_str(),
                  decomposeModeName(mode), mesh.triangleCount(), cells.cellCount(),
                  (unsigned long long)h, seconds);
    }
  }
}
