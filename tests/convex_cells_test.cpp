// Convex cells (preprocess/convex_cells.h): the seed-growing decomposition (strict and paper
// tests), the grid and pair separation, and the cache file.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <unistd.h>

#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "preprocess/builtin_scenes.h"
#include "preprocess/convex_cells.h"
#include "preprocess/mesh_loader.h"
#include "test_meshes.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using namespace strata;
using test::concat;
using test::loadMesh;
using test::translated;
using test::unweld;
using test::view;

double tolerance(const Mesh& m) {
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const glm::vec3& p : m.positions) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  if (lo.x > hi.x) return 0.0;
  // The decomposition's rule (cellTolerance): 1e-6 of the diagonal plus the rounding of the
  // largest coordinate.
  const glm::dvec3 far = glm::max(glm::abs(lo), glm::abs(hi));
  return 1e-6 * glm::length(hi - lo) + 5e-7 * std::max(far.x, std::max(far.y, far.z));
}

const char* const kModels[] = {"teapot.obj",  "horse.ply",      "stanford-bunny.obj",
                               "fandisk.obj", "rocker-arm.obj", "cheburashka.obj",
                               "homer.obj",   "cow.obj",        "spot.obj"};

// Checks that the decomposition is a partition: offsets from 0 to the triangle count, no empty
// cell, every triangle exactly once.
void expectPartition(const CellDecomposition& cells, size_t triangles) {
  ASSERT_FALSE(cells.cell_begin.empty());
  EXPECT_EQ(cells.cell_begin.front(), 0u);
  EXPECT_EQ(cells.cell_begin.back(), triangles);
  for (uint32_t c = 0; c < cells.cellCount(); ++c)
    EXPECT_LT(cells.cell_begin[c], cells.cell_begin[c + 1]);
  ASSERT_EQ(cells.triangle_order.size(), triangles);
  std::vector<int> seen(triangles, 0);
  for (uint32_t t : cells.triangle_order) {
    ASSERT_LT(t, triangles);
    ++seen[t];
  }
  for (size_t t = 0; t < triangles; ++t) ASSERT_EQ(seen[t], 1) << "triangle " << t;
}

// Cells that fail the strict test (with the tolerance the decomposition uses).
size_t nonConvexCells(const Mesh& m, const CellDecomposition& cells) {
  const float tol = float(tolerance(m) * 1.0001);
  size_t bad = 0;
  for (uint32_t c = 0; c < cells.cellCount(); ++c)
    bad += !cellIsStrictlyConvex(view(m), &cells.triangle_order[cells.cell_begin[c]],
                                 cells.cell_begin[c + 1] - cells.cell_begin[c], tol);
  return bad;
}

// The cell of each triangle.
std::vector<uint32_t> cellOf(const CellDecomposition& cells) {
  std::vector<uint32_t> of(cells.triangle_order.size());
  for (uint32_t c = 0; c < cells.cellCount(); ++c)
    for (uint32_t i = cells.cell_begin[c]; i < cells.cell_begin[c + 1]; ++i)
      of[cells.triangle_order[i]] = c;
  return of;
}

// Every reported plane separates its pair (unit normal; a's vertices on or below within the
// tolerance, b's on or above) and the pairs are sorted and unique with a < b.
// The separable and inseparable pairs of `m`'s cells (findCellPairs, its grid dropped).
std::vector<CellPair> pairsOf(const Mesh& m, const CellDecomposition& cells) {
  CellGrid grid;
  std::vector<CellPair> pairs;
  findCellPairs(view(m), cells, &grid, &pairs);
  return pairs;
}

void expectPairsValid(const Mesh& m, const CellDecomposition& cells,
                      const std::vector<CellPair>& pairs) {
  const double tol = tolerance(m) * (1.0 + 1e-9);
  for (size_t i = 0; i < pairs.size(); ++i) {
    const CellPair& p = pairs[i];
    ASSERT_LT(p.a, p.b);
    ASSERT_LT(p.b, cells.cellCount());
    if (i > 0) {
      ASSERT_TRUE(pairs[i - 1].a < p.a || (pairs[i - 1].a == p.a && pairs[i - 1].b < p.b));
    }
    if (!p.separable) continue;
    EXPECT_NEAR(glm::length(p.plane.n), 1.0f, 1e-5f);
    const glm::dvec3 n(p.plane.n);
    for (int side = 0; side < 2; ++side) {
      const uint32_t c = side == 0 ? p.a : p.b;
      for (uint32_t k = cells.cell_begin[c]; k < cells.cell_begin[c + 1]; ++k)
        for (int j = 0; j < 3; ++j) {
          const glm::dvec3 x(m.positions[m.indices[3 * size_t(cells.triangle_order[k]) + j]]);
          const double e = glm::dot(n, x) + double(p.plane.d);
          if (side == 0) {
            ASSERT_LE(e, tol) << "pair " << p.a << "," << p.b;
          } else {
            ASSERT_GE(e, -tol) << "pair " << p.a << "," << p.b;
          }
        }
    }
  }
}

using test::ScratchDir;

bool sameCells(const CellPreprocess& x, const CellPreprocess& y) {
  if (x.cells.cell_begin != y.cells.cell_begin ||
      x.cells.triangle_order != y.cells.triangle_order || x.cells.mode != y.cells.mode ||
      x.cells.cell_leader != y.cells.cell_leader || x.unpaired != y.unpaired ||
      x.grid.dims != y.grid.dims || x.grid.origin != y.grid.origin ||
      x.grid.cell_size != y.grid.cell_size || x.pairs.size() != y.pairs.size())
    return false;
  for (size_t i = 0; i < x.pairs.size(); ++i) {
    const CellPair &p = x.pairs[i], &q = y.pairs[i];
    if (p.a != q.a || p.b != q.b || p.separable != q.separable || p.plane.n != q.plane.n ||
        p.plane.d != q.plane.d)
      return false;
  }
  return true;
}

}  // namespace

TEST(ConvexCells, ModeNames) {
  EXPECT_EQ(parseDecomposeMode("strict"), DecomposeMode::Strict);
  EXPECT_EQ(parseDecomposeMode("paper"), DecomposeMode::Paper);
  EXPECT_STREQ(decomposeModeName(DecomposeMode::Strict), "strict");
  EXPECT_STREQ(decomposeModeName(DecomposeMode::Paper), "paper");
  test::expectErrorContaining([] { parseDecomposeMode("convex"); }, "'convex'");
}

// The strict test on every test model: a partition into cells that all pass the strict check.
TEST(ConvexCells, StrictCellsOnAllModels) {
  for (const char* name : kModels) {
    SCOPED_TRACE(name);
    const Mesh m = loadMesh(name);
    const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
    EXPECT_EQ(cells.mode, DecomposeMode::Strict);
    expectPartition(cells, m.triangleCount());
    EXPECT_EQ(nonConvexCells(m, cells), 0u);
    // Real merging: on average several triangles a cell.
    EXPECT_LT(cells.cellCount() * 2, m.triangleCount());
    uint32_t largest = 0;
    for (uint32_t c = 0; c < cells.cellCount(); ++c)
      largest = std::max(largest, cells.cell_begin[c + 1] - cells.cell_begin[c]);
    EXPECT_LE(largest, 1024u);
  }
}

TEST(ConvexCells, Deterministic) {
  const Mesh m = loadMesh("cow.obj");
  for (DecomposeMode mode : {DecomposeMode::Strict, DecomposeMode::Paper}) {
    DecomposeOptions o;
    o.mode = mode;
    const CellDecomposition a = decomposeConvexCells(view(m), o),
                            b = decomposeConvexCells(view(m), o);
    EXPECT_EQ(a.cell_begin, b.cell_begin);
    EXPECT_EQ(a.triangle_order, b.triangle_order);
    CellGrid ga, gb;
    std::vector<CellPair> pa, pb;
    findCellPairs(view(m), a, &ga, &pa);
    findCellPairs(view(m), b, &gb, &pb);
    ASSERT_EQ(pa.size(), pb.size());
    for (size_t i = 0; i < pa.size(); ++i) {
      EXPECT_EQ(pa[i].separable, pb[i].separable);
      EXPECT_EQ(pa[i].plane.n, pb[i].plane.n);
      EXPECT_EQ(pa[i].plane.d, pb[i].plane.d);
    }
  }
}

TEST(ConvexCells, ConvexMeshesGiveFewCells) {
  // The 12 triangles of a cube: one cell.
  const Mesh box = makeBox({1.0f, 2.0f, 0.5f});
  const CellDecomposition cube = decomposeConvexCells(view(box), DecomposeOptions{});
  EXPECT_EQ(cube.cellCount(), 1u);
  expectPartition(cube, 12);
  // A sphere: a closed convex surface is one cell when the cap allows, else few.
  const Mesh small = makeUvSphere(1.0f, 48, 24);
  DecomposeOptions big;
  big.max_cell_triangles = 4096;
  EXPECT_EQ(decomposeConvexCells(view(small), big).cellCount(), 1u);
  // A mesh convex as a whole stays one cell whatever the cap (the paper's one polyhedron per
  // sphere), found by the whole-mesh test rather than by growing.
  const Mesh sphere = makeUvSphere(1.0f, 200, 100);
  const CellDecomposition cells = decomposeConvexCells(view(sphere), DecomposeOptions{});
  expectPartition(cells, sphere.triangleCount());
  EXPECT_EQ(cells.cellCount(), 1u);
  // Grown cells respect the cap: two spheres in one mesh are not convex as a whole.
  Mesh two = small;
  for (const glm::vec3& p : small.positions)
    two.positions.push_back(p + glm::vec3(3.0f, 0.0f, 0.0f));
  for (uint32_t i : small.indices) two.indices.push_back(i + uint32_t(small.positions.size()));
  DecomposeOptions capped;
  capped.max_cell_triangles = 100;
  const CellDecomposition c100 = decomposeConvexCells(view(two), capped);
  expectPartition(c100, two.triangleCount());
  EXPECT_GT(c100.cellCount(), 2u);
  for (uint32_t c = 0; c < c100.cellCount(); ++c)
    EXPECT_LE(c100.cell_begin[c + 1] - c100.cell_begin[c], 100u);
  EXPECT_EQ(nonConvexCells(two, c100), 0u);
  // The inside of a box (every face turned inwards) is the boundary of a convex body too.
  Mesh inside = box;
  for (size_t t = 0; t < inside.triangleCount(); ++t)
    std::swap(inside.indices[3 * t + 1], inside.indices[3 * t + 2]);
  EXPECT_EQ(decomposeConvexCells(view(inside), DecomposeOptions{}).cellCount(), 1u);
}

// Per-face vertices (STL, glTF), flipped windings: the same cells as the welded, consistent mesh.
TEST(ConvexCells, SoupAndFlippedWindings) {
  const Mesh m = loadMesh("cow.obj");
  const CellDecomposition ref = decomposeConvexCells(view(m), DecomposeOptions{});
  const Mesh soup = unweld(m);
  const CellDecomposition s = decomposeConvexCells(view(soup), DecomposeOptions{});
  EXPECT_EQ(s.cell_begin, ref.cell_begin);
  EXPECT_EQ(s.triangle_order, ref.triangle_order);
  Mesh flipped = soup;
  for (size_t t = 0; t < flipped.triangleCount(); t += 3)
    std::swap(flipped.indices[3 * t + 1], flipped.indices[3 * t + 2]);
  const CellDecomposition f = decomposeConvexCells(view(flipped), DecomposeOptions{});
  expectPartition(f, m.triangleCount());
  EXPECT_EQ(nonConvexCells(flipped, f), 0u);
  EXPECT_EQ(cellOf(f), cellOf(ref));
  // A box as a soup with half its faces flipped: still one cell.
  Mesh box = unweld(makeBox({1.0f, 1.0f, 1.0f}));
  for (size_t t = 0; t < box.triangleCount(); t += 2)
    std::swap(box.indices[3 * t + 1], box.indices[3 * t + 2]);
  EXPECT_EQ(decomposeConvexCells(view(box), DecomposeOptions{}).cellCount(), 1u);
}

// Duplicated faces and faces folded back onto their neighbour's plane never share a cell.
TEST(ConvexCells, DuplicateAndFoldedFaces) {
  Mesh box = makeBox({1.0f, 1.0f, 1.0f});
  const size_t n = box.indices.size();
  for (size_t i = 0; i < 6; ++i) box.indices.push_back(box.indices[i]);  // two faces again
  box.indices.insert(box.indices.end(),
                     {box.indices[6], box.indices[8], box.indices[7]});  // reversed
  const CellDecomposition cells = decomposeConvexCells(view(box), DecomposeOptions{});
  expectPartition(cells, box.triangleCount());
  EXPECT_EQ(nonConvexCells(box, cells), 0u);
  const std::vector<uint32_t> of = cellOf(cells);
  EXPECT_NE(of[0], of[n / 3]);
  EXPECT_NE(of[1], of[n / 3 + 1]);
  EXPECT_NE(of[2], of[n / 3 + 2]);
  EXPECT_NE(of[n / 3 + 2], of[2]);

  // Folded: the second triangle lies on the first one's plane, over it.
  Mesh fold;
  fold.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.5f, 0.5f, 0}, {0.3f, -1, 0}};
  fold.indices = {0, 1, 2, 1, 0, 3, 0, 4, 1};  // the third one is beside the first: may join
  const CellDecomposition fc = decomposeConvexCells(view(fold), DecomposeOptions{});
  expectPartition(fc, 3);
  const std::vector<uint32_t> fo = cellOf(fc);
  EXPECT_NE(fo[0], fo[1]);
  EXPECT_EQ(fo[0], fo[2]);
  EXPECT_EQ(nonConvexCells(fold, fc), 0u);
  const uint32_t both[2] = {0, 1};
  EXPECT_FALSE(cellIsStrictlyConvex(view(fold), both, 2, 1e-6f));
  const uint32_t side[2] = {0, 2};
  EXPECT_TRUE(cellIsStrictlyConvex(view(fold), side, 2, 1e-6f));
}

// A face repeated many times (in every corner order and both windings), as CAD exports and
// merged scans have: the copies are one-triangle cells right after the lowest one, in triangle
// order, and take no part in the pairs, which stay those of the mesh without them (not the
// quadratic number among the copies). Two coincident faces (solids touching) stay in their cells.
TEST(ConvexCells, CoincidentCopiesAreGroupedNotPaired) {
  const Mesh base = loadMesh("cow.obj");
  const CellDecomposition plain = decomposeConvexCells(view(base), DecomposeOptions{});
  CellGrid grid;
  std::vector<CellPair> plain_pairs;
  findCellPairs(view(base), plain, &grid, &plain_pairs);
  EXPECT_TRUE(plain.cell_leader.empty());

  Mesh m = base;
  const uint32_t T = uint32_t(base.triangleCount());
  const uint32_t face = 1234, other = 777;
  const uint32_t* c = &base.indices[3 * face];
  const uint32_t corners[6][3] = {{c[0], c[1], c[2]}, {c[1], c[2], c[0]}, {c[2], c[0], c[1]},
                                  {c[0], c[2], c[1]}, {c[2], c[1], c[0]}, {c[1], c[0], c[2]}};
  for (int k = 0; k < 3000; ++k)
    m.indices.insert(m.indices.end(), corners[k % 6], corners[k % 6] + 3);
  // A second class of three whose lowest triangle comes after another class's copies.
  for (int k = 0; k < 2; ++k)
    m.indices.insert(m.indices.end(), &base.indices[3 * other], &base.indices[3 * other] + 3);
  const auto t0 = std::chrono::steady_clock::now();
  const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
  std::vector<CellPair> pairs;
  findCellPairs(view(m), cells, &grid, &pairs);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  expectPartition(cells, m.triangleCount());
  EXPECT_EQ(nonConvexCells(m, cells), 0u);
  ASSERT_EQ(cells.cell_leader.size(), cells.cellCount());
  const std::vector<uint32_t> of = cellOf(cells);
  // The class of `face`: its own cell, then the 3000 copies in triangle order.
  const uint32_t lead = of[face];
  EXPECT_EQ(cells.cell_begin[lead + 1] - cells.cell_begin[lead], 1u);
  EXPECT_EQ(cells.cell_leader[lead], lead);
  for (uint32_t k = 0; k < 3000; ++k) {
    EXPECT_EQ(of[T + k], lead + 1 + k);
    EXPECT_EQ(cells.cell_leader[lead + 1 + k], lead);
    EXPECT_TRUE(cells.isCopy(lead + 1 + k));
  }
  EXPECT_EQ(of[T + 3000], of[other] + 1);
  EXPECT_EQ(of[T + 3001], of[other] + 2);
  uint32_t copies = 0;
  for (uint32_t i = 0; i < cells.cellCount(); ++i) copies += cells.isCopy(i);
  EXPECT_EQ(copies, 3002u);
  for (const CellPair& p : pairs) EXPECT_FALSE(cells.isCopy(p.a) || cells.isCopy(p.b));
  // Two faces split out of their cells: a few more cells and pairs, nothing like 3000^2 / 2.
  EXPECT_LT(pairs.size(), plain_pairs.size() + 100);
  EXPECT_LT(cells.cellCount(), plain.cellCount() + 3002 + 10);
  std::printf("3,002 copies: %u cells, %zu pairs (%zu without), %.2f s\n", cells.cellCount(),
              pairs.size(), plain_pairs.size(), seconds);

  // A face twice (two boxes sharing one): no class, the boxes stay one cell each.
  const Mesh box = makeBox({1.0f, 1.0f, 1.0f});
  Mesh twice = box;
  twice.indices.insert(twice.indices.end(), box.indices.begin(), box.indices.begin() + 3);
  const CellDecomposition tc = decomposeConvexCells(view(twice), DecomposeOptions{});
  EXPECT_TRUE(tc.cell_leader.empty());
  // The paper's test groups them the same way.
  DecomposeOptions paper;
  paper.mode = DecomposeMode::Paper;
  const CellDecomposition pc = decomposeConvexCells(view(m), paper);
  expectPartition(pc, m.triangleCount());
  const std::vector<uint32_t> pof = cellOf(pc);
  for (uint32_t k = 0; k < 3000; ++k) EXPECT_EQ(pof[T + k], pof[face] + 1 + k);
}

// More pairs than the bound: none kept (no quadratic list, no large cache file), and the cache
// remembers it.
TEST(ConvexCellsPairs, PairBound) {
  ScratchDir dir;
  const Mesh cow = loadMesh("cow.obj");
  const CellDecomposition cells = decomposeConvexCells(view(cow), DecomposeOptions{});
  CellGrid grid;
  std::vector<CellPair> pairs;
  ASSERT_TRUE(findCellPairs(view(cow), cells, &grid, &pairs));
  const size_t all = pairs.size();
  ASSERT_GT(all, 100u);
  EXPECT_TRUE(findCellPairs(view(cow), cells, &grid, &pairs, all));
  EXPECT_EQ(pairs.size(), all);
  EXPECT_FALSE(findCellPairs(view(cow), cells, &grid, &pairs, all - 1));
  EXPECT_TRUE(pairs.empty());
  EXPECT_EQ(cellPairBound(1000), 64000u + (1u << 20));
  // Large triangles all crossing one another: 2,000 cells, about 2 million overlapping boxes.
  Mesh soup;
  test::SignedUniform next(11);
  for (uint32_t t = 0; t < 2000; ++t) {
    for (int k = 0; k < 3; ++k) soup.positions.push_back({next(), next(), next()});
    soup.indices.insert(soup.indices.end(), {3 * t, 3 * t + 1, 3 * t + 2});
  }
  bool cached = true;
  const CellPreprocess built = loadOrBuildCells(view(soup), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_TRUE(built.unpaired);
  EXPECT_TRUE(built.pairs.empty());
  EXPECT_LT(fs::file_size(cellCachePath(view(soup), DecomposeOptions{}, dir.str())), 100000u);
  const CellPreprocess again = loadOrBuildCells(view(soup), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_TRUE(cached);
  EXPECT_TRUE(again.unpaired);
}

// Edges shared by more than two faces still give adjacency; every cell stays convex.
TEST(ConvexCells, NonManifoldFan) {
  Mesh fan;
  fan.positions = {{0, 0, 0}, {0, 0, 1}};
  const float angles[] = {0.0f, 1.2f, 2.9f, 4.4f, 5.5f};
  for (float a : angles) fan.positions.push_back({std::cos(a), std::sin(a), 0.5f});
  for (uint32_t i = 0; i < 5; ++i) fan.indices.insert(fan.indices.end(), {0, 1, 2 + i});
  const CellDecomposition cells = decomposeConvexCells(view(fan), DecomposeOptions{});
  expectPartition(cells, 5);
  EXPECT_EQ(nonConvexCells(fan, cells), 0u);
  EXPECT_LT(cells.cellCount(), 5u);  // two pages at a convex angle join across the shared edge
  // No cell holds three pages of the book (they cannot lie on one convex surface).
  for (uint32_t c = 0; c < cells.cellCount(); ++c)
    EXPECT_LE(cells.cell_begin[c + 1] - cells.cell_begin[c], 2u);
}

// Zero-area and non-finite triangles are cells of their own and harm nothing else.
TEST(ConvexCells, DegenerateTriangles) {
  Mesh m = makeBox({1.0f, 1.0f, 1.0f});
  const uint32_t nan = uint32_t(m.positions.size());
  m.positions.push_back({std::nanf(""), 0.0f, 0.0f});
  const uint32_t mid = uint32_t(m.positions.size());
  m.positions.push_back({0.0f, -1.0f, -1.0f});     // on the edge between corners 0 and 1
  m.indices.insert(m.indices.end(), {0, 1, mid});  // collinear
  m.indices.insert(m.indices.end(), {2, 2, 3});    // repeated corner
  m.indices.insert(m.indices.end(), {0, 1, nan});  // non-finite
  m.indices.insert(m.indices.end(), {4, 5, 5});
  const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
  expectPartition(cells, m.triangleCount());
  const std::vector<uint32_t> of = cellOf(cells);
  for (uint32_t t = 12; t < 16; ++t) {
    const uint32_t c = of[t];
    EXPECT_EQ(cells.cell_begin[c + 1] - cells.cell_begin[c], 1u) << "triangle " << t;
  }
  for (uint32_t t = 1; t < 12; ++t) EXPECT_EQ(of[t], of[0]);
  // Pairs: the non-finite cell takes no part; every plane still separates.
  const std::vector<CellPair> pairs = pairsOf(m, cells);
  for (const CellPair& p : pairs) EXPECT_TRUE(p.a != of[14] && p.b != of[14]);
  expectPairsValid(m, cells, pairs);
  // Every cell of only a zero-area triangle passes the check trivially.
  const uint32_t one = 13;
  EXPECT_TRUE(cellIsStrictlyConvex(view(m), &one, 1, 1e-6f));
}

TEST(ConvexCells, BadInput) {
  Mesh m = makeBox({1.0f, 1.0f, 1.0f});
  m.indices[5] = 99;
  EXPECT_THROW(decomposeConvexCells(view(m), DecomposeOptions{}), Error);
  const Mesh box = makeBox({1.0f, 1.0f, 1.0f});
  DecomposeOptions zero;
  zero.max_cell_triangles = 0;
  EXPECT_THROW(decomposeConvexCells(view(box), zero), Error);
  // Empty mesh: no cells, no pairs.
  const CellDecomposition none = decomposeConvexCells(MeshView{}, DecomposeOptions{});
  EXPECT_EQ(none.cellCount(), 0u);
  CellGrid grid;
  std::vector<CellPair> pairs;
  findCellPairs(MeshView{}, none, &grid, &pairs);
  EXPECT_TRUE(pairs.empty());
}

// The checker itself: it rejects a surface with a concave fold.
TEST(ConvexCells, CheckerRejectsConcave) {
  Mesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0.5f}, {0, 2, 0}};
  m.indices = {0, 1, 2, 1, 3, 2, 2, 3, 4};
  const uint32_t convex[2] = {0, 1};  // folds down: convex
  EXPECT_TRUE(cellIsStrictlyConvex(view(m), convex, 2, 1e-6f));
  const uint32_t all[3] = {0, 1, 2};  // then up again: a saddle
  EXPECT_FALSE(cellIsStrictlyConvex(view(m), all, 3, 1e-6f));
  const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
  EXPECT_EQ(nonConvexCells(m, cells), 0u);
  EXPECT_EQ(cells.cellCount(), 2u);
}

// The paper's local test: fewer (or as many) cells, and some of them not convex.
TEST(ConvexCells, PaperModeIsLocal) {
  for (const char* name : {"horse.ply", "cow.obj", "fandisk.obj"}) {
    SCOPED_TRACE(name);
    const Mesh m = loadMesh(name);
    DecomposeOptions paper;
    paper.mode = DecomposeMode::Paper;
    const CellDecomposition p = decomposeConvexCells(view(m), paper);
    const CellDecomposition s = decomposeConvexCells(view(m), DecomposeOptions{});
    EXPECT_EQ(p.mode, DecomposeMode::Paper);
    expectPartition(p, m.triangleCount());
    EXPECT_LE(p.cellCount(), s.cellCount());
    EXPECT_GT(nonConvexCells(m, p), 0u);
  }
}

TEST(ConvexCellsPairs, PlanesSeparateAndOverlapsAreComplete) {
  for (const char* name : {"cow.obj", "fandisk.obj", "teapot.obj"}) {
    for (DecomposeMode mode : {DecomposeMode::Strict, DecomposeMode::Paper}) {
      SCOPED_TRACE(std::string(name) + " " + decomposeModeName(mode));
      const Mesh m = loadMesh(name);
      DecomposeOptions o;
      o.mode = mode;
      const CellDecomposition cells = decomposeConvexCells(view(m), o);
      CellGrid grid;
      std::vector<CellPair> pairs;
      findCellPairs(view(m), cells, &grid, &pairs);
      expectPairsValid(m, cells, pairs);
      size_t separable = 0;
      for (const CellPair& p : pairs) separable += p.separable;
      EXPECT_GT(separable, pairs.size() / 2);
      // The grid: each dimension 1 .. 128, covering the mesh.
      for (int k = 0; k < 3; ++k) {
        EXPECT_GE(grid.dims[k], 1);
        EXPECT_LE(grid.dims[k], 128);
        EXPECT_GT(grid.cell_size[k], 0.0f);
      }
      // Brute force: exactly the pairs whose tolerance-inflated boxes overlap.
      const double tol = tolerance(m);
      const uint32_t C = cells.cellCount();
      std::vector<glm::dvec3> lo(C, glm::dvec3(1e300)), hi(C, glm::dvec3(-1e300));
      for (uint32_t c = 0; c < C; ++c)
        for (uint32_t i = cells.cell_begin[c]; i < cells.cell_begin[c + 1]; ++i)
          for (int j = 0; j < 3; ++j) {
            const glm::dvec3 x(m.positions[m.indices[3 * size_t(cells.triangle_order[i]) + j]]);
            lo[c] = glm::min(lo[c], x);
            hi[c] = glm::max(hi[c], x);
            EXPECT_TRUE(glm::all(glm::greaterThanEqual(glm::vec3(x), grid.origin)));
            EXPECT_TRUE(glm::all(glm::lessThanEqual(
                glm::vec3(x), grid.origin + glm::vec3(grid.dims) * grid.cell_size * 1.0001f)));
          }
      std::vector<std::pair<uint32_t, uint32_t>> expected, got;
      for (uint32_t a = 0; a < C; ++a)
        for (uint32_t b = a + 1; b < C; ++b) {
          bool overlap = true;
          for (int k = 0; k < 3 && overlap; ++k)
            overlap = lo[a][k] - tol <= hi[b][k] + tol && lo[b][k] - tol <= hi[a][k] + tol;
          if (overlap) expected.push_back({a, b});
        }
      for (const CellPair& p : pairs) got.push_back({p.a, p.b});
      EXPECT_EQ(got, expected);
    }
  }
}

TEST(ConvexCellsPairs, BoxesTouchingNestedApart) {
  const Mesh box = makeBox({1.0f, 1.0f, 1.0f});
  // Two cubes sharing the face x = 1: one cell each, separated by that plane.
  {
    const Mesh m = concat(box, translated(box, {2.0f, 0.0f, 0.0f}));
    const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
    ASSERT_EQ(cells.cellCount(), 2u);
    const std::vector<CellPair> pairs = pairsOf(m, cells);
    ASSERT_EQ(pairs.size(), 1u);
    EXPECT_TRUE(pairs[0].separable);
    expectPairsValid(m, cells, pairs);
    const float sign = cells.triangle_order[0] < 12 ? 1.0f : -1.0f;  // cell 0 is the first cube
    EXPECT_NEAR(pairs[0].plane.n.x, sign, 1e-6f);
    EXPECT_NEAR(pairs[0].plane.d, -sign, 1e-5f);
  }
  // A cube touching the other along an edge, and one touching at a corner only.
  for (glm::vec3 d : {glm::vec3(2.0f, 2.0f, 0.0f), glm::vec3(2.0f, 2.0f, 2.0f)}) {
    const Mesh m = concat(box, translated(box, d));
    const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
    const std::vector<CellPair> pairs = pairsOf(m, cells);
    ASSERT_EQ(pairs.size(), 1u);
    EXPECT_TRUE(pairs[0].separable);
    expectPairsValid(m, cells, pairs);
  }
  // Nested: no plane separates a box from the one around it.
  {
    Mesh inner = box;
    for (glm::vec3& p : inner.positions) p *= 0.5f;
    const Mesh m = concat(box, inner);
    const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
    ASSERT_EQ(cells.cellCount(), 2u);
    const std::vector<CellPair> pairs = pairsOf(m, cells);
    ASSERT_EQ(pairs.size(), 1u);
    EXPECT_FALSE(pairs[0].separable);
  }
  // Apart, with overlapping boxes: two spheres side by side, slightly rotated.
  {
    const Mesh s = makeUvSphere(1.0f, 24, 12);
    Mesh t = s;
    for (glm::vec3& p : t.positions)
      p = glm::vec3(p.y, p.z, p.x) * 0.5f + glm::vec3(1.2f, 0.9f, 0.0f);
    const Mesh m = concat(s, t);
    DecomposeOptions o;
    o.max_cell_triangles = 4096;
    const CellDecomposition cells = decomposeConvexCells(view(m), o);
    ASSERT_EQ(cells.cellCount(), 2u);
    const std::vector<CellPair> pairs = pairsOf(m, cells);
    ASSERT_EQ(pairs.size(), 1u);
    EXPECT_TRUE(pairs[0].separable);
    expectPairsValid(m, cells, pairs);
  }
  // Far apart: no pair at all.
  {
    const Mesh m = concat(box, translated(box, {5.0f, 0.0f, 0.0f}));
    const CellDecomposition cells = decomposeConvexCells(view(m), DecomposeOptions{});
    const std::vector<CellPair> pairs = pairsOf(m, cells);
    EXPECT_TRUE(pairs.empty());
  }
}

TEST(ConvexCellsCache, ReadsBackWhatItWrote) {
  ScratchDir dir;
  const Mesh m = loadMesh("cow.obj");
  bool cached = true;
  const CellPreprocess first = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_FALSE(cached);
  const std::string path = cellCachePath(view(m), DecomposeOptions{}, dir.str());
  EXPECT_EQ(fs::path(path).parent_path(), fs::path(dir.str()));
  EXPECT_EQ(fs::path(path).extension(), ".cells");
  ASSERT_TRUE(fs::exists(path));
  EXPECT_GT(first.decompose_seconds, 0.0);
  EXPECT_GT(first.pairs_seconds, 0.0);
  // The same as building directly.
  const CellDecomposition direct = decomposeConvexCells(view(m), DecomposeOptions{});
  EXPECT_EQ(first.cells.triangle_order, direct.triangle_order);
  const CellPreprocess second = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_TRUE(cached);
  EXPECT_TRUE(sameCells(first, second));
  EXPECT_EQ(second.decompose_seconds, first.decompose_seconds);
  EXPECT_EQ(second.pairs_seconds, first.pairs_seconds);
  // No temporary files left behind.
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir.str())) files += e.is_regular_file();
  EXPECT_EQ(files, 1u);
}

// The copies of coincident triangles survive the cache; a file whose classes are not a first
// cell and the one-triangle cells right after it is rebuilt.
TEST(ConvexCellsCache, CoincidentCopiesReadBack) {
  ScratchDir dir;
  Mesh m = loadMesh("cow.obj");
  for (int k = 0; k < 5; ++k)
    m.indices.insert(m.indices.end(), {m.indices[30], m.indices[31], m.indices[32]});
  bool cached = true;
  const CellPreprocess first = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_FALSE(cached);
  ASSERT_FALSE(first.cells.cell_leader.empty());
  const CellPreprocess second = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_TRUE(cached);
  EXPECT_TRUE(sameCells(first, second));
  // A copy whose first cell comes after it, or is not one triangle: not a valid cache.
  CellPreprocess bad = first;
  uint32_t copy = 0;
  while (!bad.cells.isCopy(copy)) ++copy;
  bad.cells.cell_leader[copy] = copy + 1;
  const std::vector<char> bytes = serializeCellCache(bad, view(m), DecomposeOptions{});
  CellPreprocess out;
  EXPECT_FALSE(parseCellCache(std::string_view(bytes.data(), bytes.size()), view(m),
                              DecomposeOptions{}, &out));
  uint32_t big = 0;
  while (first.cells.cell_begin[big + 1] - first.cells.cell_begin[big] < 2) ++big;
  ASSERT_LT(big, copy);
  bad = first;
  bad.cells.cell_leader[copy] = big;
  const std::vector<char> bytes2 = serializeCellCache(bad, view(m), DecomposeOptions{});
  EXPECT_FALSE(parseCellCache(std::string_view(bytes2.data(), bytes2.size()), view(m),
                              DecomposeOptions{}, &out));
  const std::vector<char> good = serializeCellCache(first, view(m), DecomposeOptions{});
  EXPECT_TRUE(parseCellCache(std::string_view(good.data(), good.size()), view(m),
                             DecomposeOptions{}, &out));
}

TEST(ConvexCellsCache, CorruptFilesAreRebuilt) {
  ScratchDir dir;
  const Mesh m = loadMesh("cow.obj");
  bool cached = true;
  const CellPreprocess ref = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  const std::string path = cellCachePath(view(m), DecomposeOptions{}, dir.str());
  std::vector<char> good;
  {
    std::ifstream in(path, std::ios::binary);
    good.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  ASSERT_GT(good.size(), 100u);
  auto write = [&](const std::vector<char>& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
  };
  std::vector<std::vector<char>> bad;
  for (size_t at :
       {size_t(0), size_t(12), size_t(20), good.size() / 2, good.size() - 20, good.size() - 1}) {
    std::vector<char> b = good;
    b[at] ^= 0x10;  // one flipped bit: magic, version, key, payload, times, checksum
    bad.push_back(b);
  }
  bad.push_back(
      std::vector<char>(good.begin(), good.begin() + long(good.size() / 2)));  // truncated
  bad.push_back(std::vector<char>(good.begin(), good.end() - 1));
  bad.push_back({});  // empty
  {
    std::vector<char> b = good;  // grown
    b.push_back(0);
    bad.push_back(b);
  }
  for (size_t i = 0; i < bad.size(); ++i) {
    SCOPED_TRACE("corruption " + std::to_string(i));
    write(bad[i]);
    const CellPreprocess r = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
    EXPECT_FALSE(cached);
    EXPECT_EQ(r.cells.triangle_order, ref.cells.triangle_order);
    EXPECT_EQ(r.pairs.size(), ref.pairs.size());
    // Replaced by a good file.
    loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
    EXPECT_TRUE(cached);
  }
}

TEST(ConvexCellsCache, KeyedOnMeshAndOptions) {
  ScratchDir dir;
  const Mesh m = loadMesh("cow.obj");
  DecomposeOptions paper;
  paper.mode = DecomposeMode::Paper;
  DecomposeOptions small;
  small.max_cell_triangles = 64;
  Mesh moved = m;
  moved.positions[7].x += 1e-3f;
  const std::set<std::string> paths = {cellCachePath(view(m), DecomposeOptions{}, dir.str()),
                                       cellCachePath(view(m), paper, dir.str()),
                                       cellCachePath(view(m), small, dir.str()),
                                       cellCachePath(view(moved), DecomposeOptions{}, dir.str())};
  EXPECT_EQ(paths.size(), 4u);
  bool cached = true;
  const CellPreprocess s = loadOrBuildCells(view(m), DecomposeOptions{}, dir.str(), &cached);
  EXPECT_FALSE(cached);
  const CellPreprocess p = loadOrBuildCells(view(m), paper, dir.str(), &cached);
  EXPECT_FALSE(cached);
  EXPECT_EQ(p.cells.mode, DecomposeMode::Paper);
  EXPECT_EQ(s.cells.mode, DecomposeMode::Strict);
  EXPECT_NE(p.cells.cellCount(), s.cells.cellCount());
  loadOrBuildCells(view(m), paper, dir.str(), &cached);
  EXPECT_TRUE(cached);
  // A file of another mesh or options under this name is not trusted.
  fs::copy_file(cellCachePath(view(m), paper, dir.str()), cellCachePath(view(m), small, dir.str()));
  const CellPreprocess r = loadOrBuildCells(view(m), small, dir.str(), &cached);
  EXPECT_FALSE(cached);
  for (uint32_t c = 0; c < r.cells.cellCount(); ++c)
    EXPECT_LE(r.cells.cell_begin[c + 1] - r.cells.cell_begin[c], 64u);
}

TEST(ConvexCellsCache, UnwritableFolderStillBuilds) {
  ScratchDir dir;
  const std::string file = dir.str() + "/not-a-folder";
  std::ofstream(file) << "x";
  const Mesh m = makeBox({1.0f, 1.0f, 1.0f});
  bool cached = true;
  testing::internal::CaptureStderr();
  const CellPreprocess r = loadOrBuildCells(view(m), DecomposeOptions{}, file + "/cells", &cached);
  const std::string err = testing::internal::GetCapturedStderr();
  EXPECT_FALSE(cached);
  EXPECT_EQ(r.cells.cellCount(), 1u);
  EXPECT_NE(err.find("warning"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
}

TEST(ConvexCellsCache, DefaultFolder) {
  const char* xdg = std::getenv("XDG_CACHE_HOME");
  const std::string saved = xdg ? xdg : "";
  ::setenv("XDG_CACHE_HOME", "/some/where", 1);
  EXPECT_EQ(defaultCellCacheDir(), "/some/where/strata/cells");
  ::unsetenv("XDG_CACHE_HOME");
  if (const char* home = std::getenv("HOME"); home && *home) {
    EXPECT_EQ(defaultCellCacheDir(), std::string(home) + "/.cache/strata/cells");
  }
  if (xdg) ::setenv("XDG_CACHE_HOME", saved.c_str(), 1);
  const Mesh m = makeBox({1.0f, 1.0f, 1.0f});
  EXPECT_EQ(fs::path(cellCachePath(view(m), DecomposeOptions{}, "")).parent_path().string(),
            defaultCellCacheDir());
}

// Report: cell counts, pair statistics and times for the test models and a sphere; run with
// --gtest_also_run_disabled_tests.
TEST(ConvexCellsReport, DISABLED_Models) {
  std::vector<std::pair<std::string, Mesh>> meshes;
  for (const char* name : kModels) meshes.push_back({name, loadMesh(name)});
  meshes.push_back({"uv-sphere-200x100", makeUvSphere(1.0f, 200, 100)});
  for (const auto& [name, mesh] : meshes) {
    for (DecomposeMode mode : {DecomposeMode::Strict, DecomposeMode::Paper}) {
      DecomposeOptions opt;
      opt.mode = mode;
      const auto t0 = std::chrono::steady_clock::now();
      const CellDecomposition cells = decomposeConvexCells(view(mesh), opt);
      const auto t1 = std::chrono::steady_clock::now();
      CellGrid grid;
      std::vector<CellPair> pairs;
      findCellPairs(view(mesh), cells, &grid, &pairs);
      const auto t2 = std::chrono::steady_clock::now();
      size_t sep = 0, convex = 0;
      std::vector<uint32_t> sizes;
      const float tol = float(tolerance(mesh) * 1.0001);
      for (const CellPair& p : pairs) sep += p.separable;
      for (uint32_t c = 0; c < cells.cellCount(); ++c) {
        const uint32_t n = cells.cell_begin[c + 1] - cells.cell_begin[c];
        sizes.push_back(n);
        convex +=
            cellIsStrictlyConvex(view(mesh), &cells.triangle_order[cells.cell_begin[c]], n, tol);
      }
      std::sort(sizes.begin(), sizes.end());
      std::printf(
          "%-20s %-6s tris %7zu cells %6u (median %u, max %u, non-convex %zu) grid %dx%dx%d "
          "pairs %8zu separable %8zu (%.2f%%) decompose %.3f s pairs %.3f s\n",
          name.c_str(), decomposeModeName(mode), mesh.triangleCount(), cells.cellCount(),
          sizes[sizes.size() / 2], sizes.back(), cells.cellCount() - convex, grid.dims.x,
          grid.dims.y, grid.dims.z, pairs.size(), sep,
          pairs.empty() ? 100.0 : 100.0 * double(sep) / double(pairs.size()),
          std::chrono::duration<double>(t1 - t0).count(),
          std::chrono::duration<double>(t2 - t1).count());
    }
  }
}

TEST(ConvexCellsReport, DISABLED_Million) {
  // 25 spheres of 39,600 triangles in a 5 x 5 block, touching neighbours overlapping a little,
  // and the horse tiled 10 times.
  const Mesh sphere = makeUvSphere(1.0f, 200, 100);
  Mesh spheres, horses;
  for (int i = 0; i < 25; ++i) {
    const glm::mat4 m = glm::rotate(
        glm::translate(glm::mat4(1.0f), glm::vec3(1.8f * (i % 5), 1.8f * (i / 5), 0.3f * i)),
        0.37f * i, glm::normalize(glm::vec3(1.0f, 0.5f, 0.2f)));
    const uint32_t base = uint32_t(spheres.positions.size());
    for (const glm::vec3& p : sphere.positions)
      spheres.positions.push_back(glm::vec3(m * glm::vec4(p, 1.0f)));
    for (uint32_t k : sphere.indices) spheres.indices.push_back(base + k);
  }
  const Mesh horse = loadMesh("horse.ply");
  for (int i = 0; i < 10; ++i) {
    const uint32_t base = uint32_t(horses.positions.size());
    for (const glm::vec3& p : horse.positions)
      horses.positions.push_back(p + glm::vec3(0.05f * i, 0.0f, 0.0f));
    for (uint32_t k : horse.indices) horses.indices.push_back(base + k);
  }
  for (const auto* mesh : {&spheres, &horses}) {
    for (DecomposeMode mode : {DecomposeMode::Strict, DecomposeMode::Paper}) {
      DecomposeOptions opt;
      opt.mode = mode;
      const auto t0 = std::chrono::steady_clock::now();
      const CellDecomposition cells = decomposeConvexCells(view(*mesh), opt);
      const auto t1 = std::chrono::steady_clock::now();
      CellGrid grid;
      std::vector<CellPair> pairs;
      findCellPairs(view(*mesh), cells, &grid, &pairs);
      const auto t2 = std::chrono::steady_clock::now();
      size_t sep = 0;
      for (const CellPair& p : pairs) sep += p.separable;
      std::printf(
          "%zu tris %s: cells %u grid %dx%dx%d pairs %zu separable %zu decompose %.3f s pairs %.3f "
          "s\n",
          mesh->triangleCount(), decomposeModeName(mode), cells.cellCount(), grid.dims.x,
          grid.dims.y, grid.dims.z, pairs.size(), sep,
          std::chrono::duration<double>(t1 - t0).count(),
          std::chrono::duration<double>(t2 - t1).count());
    }
    ScratchDir dir;
    bool cached = false;
    loadOrBuildCells(view(*mesh), DecomposeOptions{}, dir.str(), &cached);
    const auto t0 = std::chrono::steady_clock::now();
    const CellPreprocess r = loadOrBuildCells(view(*mesh), DecomposeOptions{}, dir.str(), &cached);
    const auto t1 = std::chrono::steady_clock::now();
    std::printf(
        "  cache read: %d in %.3f s, file %.1f MB\n", int(cached),
        std::chrono::duration<double>(t1 - t0).count(),
        double(fs::file_size(cellCachePath(view(*mesh), DecomposeOptions{}, dir.str()))) / 1e6);
  }
}
