// The octree (preprocess/octree.h): the separating-axis test against clipping, the build's
// invariants (every triangle in every leaf it meets, children contiguous, leaves within the face
// limit), the front-to-back leaf order against a brute-force occlusion test on random views,
// and the cache file (round trip, damaged, stale, unwritable).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/core/hash.h"
#include "preprocess/mesh_loader.h"
#include "preprocess/octree.h"
#include "preprocess/octree_partition.h"
#include "test_meshes.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;
using namespace strata;

struct Soup {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  MeshView view() const {
    MeshView v;
    v.positions = positions.data();
    v.vertex_count = positions.size();
    v.indices = indices.data();
    v.triangle_count = indices.size() / 3;
    return v;
  }
};

Soup loadModel(const std::string& name) {
  Mesh m = test::loadMesh(name);
  return Soup{std::move(m.positions), std::move(m.indices)};
}

// Random self-intersecting triangles of very different sizes in the unit cube, with exact
// duplicates and a few shared corners: non-manifold soup.
Soup randomSoup(uint32_t triangles, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  Soup s;
  for (uint32_t t = 0; t < triangles; ++t) {
    const glm::vec3 c(u(rng), u(rng), u(rng));
    const float r = t % 17 == 0 ? 0.6f : 0.02f + 0.1f * u(rng);
    for (int k = 0; k < 3; ++k) {
      s.positions.push_back(c + r * (glm::vec3(u(rng), u(rng), u(rng)) - 0.5f));
      s.indices.push_back(uint32_t(s.positions.size() - 1));
    }
    if (t % 11 == 0) {  // an exact duplicate of the triangle just made
      for (int k = 0; k < 3; ++k) s.indices.push_back(s.indices[s.indices.size() - 3]);
      ++t;
    }
  }
  return s;
}

// Whether the triangle meets the box, by clipping it against the box's six planes in double
// precision (independent of the separating-axis code).
bool clipOverlaps(const glm::dvec3 tri[3], const glm::dvec3& lo, const glm::dvec3& hi) {
  std::vector<glm::dvec3> poly(tri, tri + 3), next;
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      next.clear();
      auto inside = [&](const glm::dvec3& p) {
        return side ? p[axis] <= hi[axis] : p[axis] >= lo[axis];
      };
      const double plane = side ? hi[axis] : lo[axis];
      for (size_t i = 0; i < poly.size(); ++i) {
        const glm::dvec3& a = poly[i];
        const glm::dvec3& b = poly[(i + 1) % poly.size()];
        if (inside(a)) next.push_back(a);
        if (inside(a) != inside(b)) {
          const double t = (plane - a[axis]) / (b[axis] - a[axis]);
          next.push_back(a + t * (b - a));
        }
      }
      poly.swap(next);
      if (poly.empty()) return false;
    }
  return true;
}

TEST(Octree, SeparatingAxisTestAgreesWithClipping) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int overlapping = 0, apart = 0;
  for (int i = 0; i < 20000; ++i) {
    glm::dvec3 tri[3];
    const glm::dvec3 c(u(rng), u(rng), u(rng));
    const double r = 0.05 + std::abs(u(rng));
    for (auto& p : tri) p = c + r * glm::dvec3(u(rng), u(rng), u(rng));
    const glm::dvec3 lo(-0.3, -0.2, -0.25), hi(0.2, 0.3, 0.35);
    const glm::dvec3 eps(1e-5);
    const bool sat = triangleOverlapsBox(glm::vec3(tri[0]), glm::vec3(tri[1]), glm::vec3(tri[2]),
                                         glm::vec3(lo), glm::vec3(hi));
    // Clear cases only: within 1e-5 of touching, either answer is allowed.
    if (clipOverlaps(tri, lo + eps, hi - eps)) {
      EXPECT_TRUE(sat) << "case " << i;
      ++overlapping;
    } else if (!clipOverlaps(tri, lo - eps, hi + eps)) {
      EXPECT_FALSE(sat) << "case " << i;
      ++apart;
    }
  }
  EXPECT_GT(overlapping, 1500);
  EXPECT_GT(apart, 2000);
  // A triangle lying in a face of the box touches it.
  EXPECT_TRUE(triangleOverlapsBox({0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {0, 0, 0}, {1, 1, 1}));
  EXPECT_FALSE(
      triangleOverlapsBox({0, 0, 1.01f}, {1, 0, 1.01f}, {0, 1, 1.01f}, {0, 0, 0}, {1, 1, 1}));
  // Large triangle whose plane cuts the box while all corners lie outside it.
  EXPECT_TRUE(
      triangleOverlapsBox({-5, -5, 0.5f}, {5, -5, 0.5f}, {0, 5, 0.5f}, {0, 0, 0}, {1, 1, 1}));
  // Its plane misses the box corner region: the edge axes separate it.
  EXPECT_FALSE(triangleOverlapsBox({1.5f, 0, 0}, {0, 1.5f, 0}, {1.5f, 1.5f, -3}, {0, 0, 0},
                                   {0.5f, 0.5f, 0.5f}));
}

// Every structural rule of the tree, and completeness: each usable triangle is referenced by
// every leaf whose cube it clearly meets, and only by leaves whose widened cube it meets.
void expectValidTree(const Octree& tree, const Soup& soup, const OctreeOptions& options) {
  ASSERT_FALSE(tree.empty());
  const OctreeNode& root = tree.nodes[tree.root()];
  EXPECT_EQ(root.level, 0u);
  uint64_t refs = 0, leaves = 0, unsplit = 0;
  std::vector<int> parent_count(tree.nodes.size(), 0);
  for (size_t i = 0; i < tree.nodes.size(); ++i) {
    const OctreeNode& n = tree.nodes[i];
    if (n.leaf()) {
      ++leaves;
      refs += n.ref_count;
      // Over the face limit above the deepest level: only a leaf whose split would only have
      // copied references.
      if (n.level < options.max_level && n.ref_count > options.leaf_triangles) ++unsplit;
      continue;
    }
    ASSERT_LE(n.first_child + 8, i) << "children are emitted before their parent";
    for (uint32_t c = 0; c < 8; ++c) {
      const OctreeNode& k = tree.nodes[n.first_child + c];
      ++parent_count[n.first_child + c];
      EXPECT_EQ(k.level, n.level + 1);
      EXPECT_FLOAT_EQ(k.size, 0.5f * n.size);
      const glm::vec3 expect = n.lo + glm::vec3((c & 1) ? k.size : 0.0f, (c & 2) ? k.size : 0.0f,
                                                (c & 4) ? k.size : 0.0f);
      EXPECT_NEAR(glm::length(k.lo - expect), 0.0f, 1e-6f * n.size);
    }
  }
  EXPECT_EQ(unsplit, tree.stats.unsplit_leaves);
  for (size_t i = 0; i + 1 < tree.nodes.size(); ++i) EXPECT_EQ(parent_count[i], 1) << i;
  EXPECT_EQ(refs, tree.refs.size());
  EXPECT_EQ(refs, tree.stats.refs);
  EXPECT_EQ(leaves, tree.stats.leaves);
  EXPECT_EQ(tree.nodes.size(), tree.stats.nodes);

  const MeshView mesh = soup.view();
  for (const OctreeNode& n : tree.nodes) {
    if (!n.leaf()) continue;
    const std::set<uint32_t> mine(tree.refs.begin() + n.first_ref,
                                  tree.refs.begin() + n.first_ref + n.ref_count);
    EXPECT_EQ(mine.size(), n.ref_count) << "a leaf references a triangle once";
    const glm::dvec3 lo(n.lo), hi(n.hi()), eps(1e-3 * n.size);
    for (uint32_t t = 0; t < mesh.triangle_count; ++t) {
      glm::dvec3 tri[3];
      for (int k = 0; k < 3; ++k) tri[k] = glm::dvec3(soup.positions[soup.indices[t * 3 + k]]);
      if (mine.count(t)) {
        EXPECT_TRUE(clipOverlaps(tri, lo - eps, hi + eps))
            << "triangle " << t << " is far from its leaf";
      } else {
        EXPECT_FALSE(clipOverlaps(tri, lo + eps, hi - eps))
            << "triangle " << t << " is missing from a leaf it meets";
      }
    }
  }
}

TEST(Octree, BuildKeepsEveryTriangleInEveryLeafItMeets) {
  const Soup cow = loadModel("cow.obj");
  OctreeOptions options;
  options.leaf_triangles = 300;
  std::vector<double> progress;
  const Octree tree = buildOctree(cow.view(), options, [&](double f) { progress.push_back(f); });
  expectValidTree(tree, cow, options);
  EXPECT_GT(tree.stats.leaves, 20u);
  EXPECT_GE(tree.stats.refs, cow.indices.size() / 3);
  EXPECT_EQ(tree.stats.skipped, 0u);
  ASSERT_FALSE(progress.empty());
  EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
  EXPECT_NEAR(progress.back(), 1.0, 1e-9);

  const Soup soup = randomSoup(3000, 3);
  options.leaf_triangles = 64;
  expectValidTree(buildOctree(soup.view(), options), soup, options);
}

TEST(Octree, CoincidentAndBrokenTrianglesStopTheSplit) {
  Soup s;
  s.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0.2f, 0.2f, 0.2f}, {NAN, 0, 0}};
  for (int i = 0; i < 5000; ++i) s.indices.insert(s.indices.end(), {0, 1, 2});
  s.indices.insert(s.indices.end(), {0, 1, 4});  // a non-finite corner
  s.indices.insert(s.indices.end(), {0, 1, 9});  // an index past the vertices
  s.indices.insert(s.indices.end(), {3, 3, 3});  // a point: referenced, harmless
  OctreeOptions options;
  options.leaf_triangles = 100;
  options.max_level = 6;
  const Octree tree = buildOctree(s.view(), options);
  EXPECT_EQ(tree.stats.skipped, 2u);
  // 5000 copies of one face: no split separates them, and splitting on would copy their
  // references into every node they cover down to the deepest level (4^6 times here).
  EXPECT_LT(tree.stats.depth, 6u);
  EXPECT_GE(tree.stats.unsplit_leaves, 1u);
  EXPECT_GE(tree.stats.largest_leaf, 5000u);
  EXPECT_LE(tree.stats.refs, 3u * 3u * 5003u);
  for (uint32_t r : tree.refs) EXPECT_TRUE(r < 5000 || r == 5002);

  Soup empty;
  const Octree none = buildOctree(empty.view(), options);
  ASSERT_EQ(none.nodes.size(), 1u);
  EXPECT_TRUE(none.nodes[0].leaf());
  std::vector<uint32_t> order;
  frontToBackLeaves(none, true, glm::vec3(5.0f), glm::vec3(-1.0f), order);
  EXPECT_TRUE(order.empty());

  options.leaf_triangles = 0;
  EXPECT_THROW(buildOctree(s.view(), options), Error);
}

// Whether the segment from a to b passes through the open box (lo, hi) (slab test).
bool segmentEntersBox(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& lo,
                      const glm::dvec3& hi) {
  double t0 = 0.0, t1 = 1.0;
  const glm::dvec3 d = b - a;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-300) {
      if (a[k] <= lo[k] || a[k] >= hi[k]) return false;
      continue;
    }
    double ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 >= t1) return false;
  }
  return true;
}

// Brute force: no leaf listed later hides any sample point of a leaf listed earlier.
void expectFrontToBack(const Octree& tree, const std::vector<uint32_t>& order, bool perspective,
                       const glm::dvec3& eye, const glm::dvec3& forward, const std::string& what) {
  int violations = 0;
  for (size_t i = 0; i < order.size() && violations < 3; ++i) {
    const OctreeNode& a = tree.nodes[order[i]];
    for (size_t j = i + 1; j < order.size() && violations < 3; ++j) {
      const OctreeNode& b = tree.nodes[order[j]];
      const double shrink = 1e-6 * b.size;
      const glm::dvec3 blo = glm::dvec3(b.lo) + shrink, bhi = glm::dvec3(b.hi()) - shrink;
      for (int s = 0; s < 64; ++s) {
        const glm::dvec3 f((s & 3) / 3.0, ((s >> 2) & 3) / 3.0, ((s >> 4) & 3) / 3.0);
        const glm::dvec3 p = glm::dvec3(a.lo) + f * double(a.size);
        const glm::dvec3 from = perspective ? eye : p - 1e6 * forward;
        if (segmentEntersBox(from, p, blo, bhi)) {
          ADD_FAILURE() << what << ": leaf " << order[j] << " (listed " << j << ") hides leaf "
                        << order[i] << " (listed " << i << ")";
          ++violations;
          break;
        }
      }
    }
  }
}

TEST(Octree, LeafOrderIsFrontToBackFromEveryView) {
  const Soup soup = randomSoup(1500, 11);
  OctreeOptions options;
  options.leaf_triangles = 96;
  const Octree tree = buildOctree(soup.view(), options);
  size_t leaves = 0;
  for (const OctreeNode& n : tree.nodes) leaves += n.leaf() && n.ref_count > 0;
  ASSERT_GT(leaves, 30u);
  const OctreeNode& root = tree.nodes[tree.root()];
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<uint32_t> order;
  for (int v = 0; v < 24; ++v) {
    glm::dvec3 dir(u(rng), u(rng), u(rng));
    if (glm::length(dir) < 1e-3) dir = {1, 0, 0};
    dir = glm::normalize(dir);
    const glm::dvec3 center(root.center());
    // Outside, near the surface and inside the root cube (a view from within the scene).
    const double distance = v % 3 == 0 ? 3.0 : (v % 3 == 1 ? 0.9 : 0.25);
    const glm::dvec3 eye = center - dir * (distance * root.size);
    const bool perspective = v % 4 != 3;
    frontToBackLeaves(tree, perspective, glm::vec3(eye), glm::vec3(dir), order);
    EXPECT_EQ(order.size(), leaves);
    EXPECT_EQ(std::set<uint32_t>(order.begin(), order.end()).size(), order.size());
    expectFrontToBack(
        tree, order, perspective, eye, dir,
        std::string(perspective ? "perspective" : "orthographic") + " view " + std::to_string(v));
  }
}

// The partition of a distributed render: for 1..9 parts, the parts' leaves are disjoint and
// together every leaf with references, balanced within half again the even share, and
// the parts' order for a view, each part's leaves in their own order, is front to back leaf by
// leaf (so each part is a convex box and the boxes are ordered).
TEST(OctreePartition, PartsAreDisjointBalancedBoxesInVisibilityOrder) {
  const Soup soup = randomSoup(3000, 23);
  OctreeOptions options;
  options.leaf_triangles = 60;
  const Octree tree = buildOctree(soup.view(), options);
  std::vector<uint32_t> all;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i)
    if (tree.nodes[i].leaf() && tree.nodes[i].ref_count) all.push_back(i);
  ASSERT_GT(all.size(), 60u);
  const OctreeNode& root = tree.nodes[tree.root()];
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (uint32_t parts = 1; parts <= 9; ++parts) {
    SCOPED_TRACE(testing::Message() << parts << " parts");
    const OctreePartition p = partitionOctree(tree, parts);
    ASSERT_EQ(p.leaves.size(), parts);
    std::vector<uint32_t> seen;
    std::vector<std::set<uint32_t>> leaves_of(parts);
    uint64_t largest = 0;
    for (uint32_t i = 0; i < parts; ++i) {
      EXPECT_FALSE(p.leaves[i].empty()) << "part " << i;
      const std::vector<uint32_t>& leaves = p.leaves[i];
      uint64_t refs = 0;
      for (uint32_t l : leaves) refs += tree.nodes[l].ref_count;
      EXPECT_EQ(refs, p.refs[i]);
      largest = std::max(largest, refs);
      seen.insert(seen.end(), leaves.begin(), leaves.end());
      leaves_of[i].insert(leaves.begin(), leaves.end());
    }
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(seen, all) << "every leaf in exactly one part";
    // Within half again the even share and a leaf (the cuts fall between leaves, on planes no
    // leaf straddles).
    EXPECT_LE(largest, tree.stats.refs * 3 / (2 * parts) + tree.stats.largest_leaf);
    for (int v = 0; v < 8; ++v) {
      glm::dvec3 dir = glm::normalize(glm::dvec3(u(rng), u(rng), u(rng)) + glm::dvec3(1e-3));
      const double distance = v % 2 ? 3.0 : 0.2;  // outside, and inside the root
      const glm::dvec3 eye = glm::dvec3(root.center()) - dir * (distance * root.size);
      const bool perspective = v % 4 != 3;
      const std::vector<uint32_t> order =
          partsFrontToBack(p, perspective, glm::vec3(eye), glm::vec3(dir));
      ASSERT_EQ(std::set<uint32_t>(order.begin(), order.end()).size(), size_t(parts));
      std::vector<uint32_t> leaf_order, by_leaf;
      frontToBackLeaves(tree, perspective, glm::vec3(eye), glm::vec3(dir), by_leaf);
      for (uint32_t part : order)
        for (uint32_t l : by_leaf)
          if (leaves_of[part].count(l)) leaf_order.push_back(l);
      ASSERT_EQ(leaf_order.size(), all.size());
      expectFrontToBack(tree, leaf_order, perspective, eye, dir,
                        "parts, view " + std::to_string(v));
    }
  }
  EXPECT_THROW(partitionOctree(tree, 0), Error);
  // More parts than leaves: the parts a leaf cannot use stay empty, the others cover it all.
  const OctreePartition many = partitionOctree(tree, uint32_t(all.size()) + 5);
  size_t covered = 0, empty = 0;
  for (const std::vector<uint32_t>& leaves : many.leaves) {
    covered += leaves.size();
    empty += leaves.empty();
  }
  EXPECT_EQ(covered, all.size());
  EXPECT_GE(empty, 5u);
}

TEST(OctreeCache, RoundTripDamageStalenessAndUnwritableFolders) {
  const test::ScratchDir dir;
  const Soup cow = loadModel("cow.obj");
  OctreeOptions options;
  options.leaf_triangles = 500;
  const Octree fresh = buildOctree(cow.view(), options);

  bool cached = true;
  const Octree first = loadOrBuildOctree(cow.view(), options, dir.str(), &cached);
  EXPECT_FALSE(cached);
  const Octree second = loadOrBuildOctree(cow.view(), options, dir.str(), &cached);
  EXPECT_TRUE(cached);
  for (const Octree* t : {&first, &second}) {
    ASSERT_EQ(t->nodes.size(), fresh.nodes.size());
    EXPECT_EQ(t->refs, fresh.refs);
    for (size_t i = 0; i < fresh.nodes.size(); ++i) {
      EXPECT_EQ(t->nodes[i].first_child, fresh.nodes[i].first_child);
      EXPECT_EQ(t->nodes[i].ref_count, fresh.nodes[i].ref_count);
      EXPECT_EQ(t->nodes[i].lo, fresh.nodes[i].lo);
    }
  }
  const std::string path = octreeCachePath(cow.view(), options, dir.str());
  ASSERT_EQ(dir.entries(), std::vector<std::string>{fs::path(path).filename().string()})
      << "one cache file and no temporary left";

  // One flipped byte, a truncation, garbage: refused by the reader, rebuilt by the cache.
  const auto size = fs::file_size(path);
  for (int damage = 0; damage < 3; ++damage) {
    {
      std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
      if (damage == 0) {
        f.seekp(std::streamoff(size / 2));
        f.put('\x5a');
      } else if (damage == 2) {
        f << "garbage";
      }
    }
    if (damage == 1) fs::resize_file(path, size - 100);
    try {
      readOctreeFile(path, cow.view(), options);
      ADD_FAILURE() << "damage " << damage << " was not detected";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    const Octree rebuilt = loadOrBuildOctree(cow.view(), options, dir.str(), &cached);
    EXPECT_FALSE(cached);
    EXPECT_EQ(rebuilt.refs, fresh.refs);
    EXPECT_EQ(fs::file_size(path), size);
  }

  // A well-formed file (checksum recomputed) whose nodes share children is not a tree: refused,
  // since walking it could take exponential time.
  {
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    const size_t nodes_at = 48 + fresh.refs.size() * 4;
    std::vector<size_t> inner;
    for (size_t i = 0; i < fresh.nodes.size(); ++i)
      if (!fresh.nodes[i].leaf()) inner.push_back(i);
    ASSERT_GE(inner.size(), 2u);
    std::memcpy(&bytes[nodes_at + inner[1] * sizeof(OctreeNode) + 16],
                &fresh.nodes[inner[0]].first_child, 4);
    const uint64_t sum = fnv1a64(bytes.data(), bytes.size() - 8);
    std::memcpy(&bytes[bytes.size() - 8], &sum, 8);
    const std::string shared = (dir.path() / "shared.octree").string();
    std::ofstream(shared, std::ios::binary) << bytes;
    try {
      readOctreeFile(shared, cow.view(), options);
      ADD_FAILURE() << "a file whose nodes share children was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("two parents"), std::string::npos) << e.what();
    }
    fs::remove(shared);
  }

  // Other options: another file; the same file name for other options is refused.
  OctreeOptions other = options;
  other.leaf_triangles = 250;
  EXPECT_NE(octreeCachePath(cow.view(), other, dir.str()), path);
  EXPECT_THROW(readOctreeFile(path, cow.view(), other), Error);

  // An unwritable cache folder: a warning, and the octree built in memory.
  const Octree in_memory =
      loadOrBuildOctree(cow.view(), options, "/proc/strata-no-such-dir", &cached);
  EXPECT_FALSE(cached);
  EXPECT_EQ(in_memory.refs, fresh.refs);
  EXPECT_THROW(writeOctreeFile("/proc/strata-no-such-dir/x.octree", cow.view(), options), Error);
}

}  // namespace
