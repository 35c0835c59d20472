// The octree of the octree method: the scene's triangles (any soup: non-manifold, dangling,
// self-intersecting) sorted into the leaves of a cube octree, a triangle referenced by every leaf
// its triangle overlaps (only the index is duplicated), and the front-to-back order of the leaves
// for a view from the octant lookup table (no sort, no graph). No OpenCL here.
//
// Build: top-down, depth-first in Morton order (child i has x = bit 0, y = bit 1, z = bit 2 of
// i set for the upper half). A node is split while it holds more than `leaf_triangles`
// references and is above `max_level`, unless its children would hold more than three times its
// references between them while one child keeps 90% of them (coincident or overlapping faces,
// which no split separates: such a node stays a leaf, counted in `unsplit_leaves`); a child holds
// the node's triangles that overlap its closed cube (the separating-axis test of Akenine-Moeller).
// A node's eight children's lists are filtered from its own when it is split, so the lists held at
// any time are those of the nodes on the path from the root and of their siblings. Bottom-up, the
// eight children of a node are emitted together when the node is finished, so they are contiguous
// and the node keeps one offset; a leaf's references are emitted when the leaf is finished. The
// root is emitted last. Node records wait in one 8-entry queue per level: what the build holds
// besides the path's lists is bounded by the depth, not by the scene.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/mesh_view.h"
#include "strata/error.h"

namespace strata {

// Default face limit per leaf, chosen by measurement on the massive built-ins.
inline constexpr uint32_t kDefaultLeafTriangles = 16384;  // measured: docs/octree.md
inline constexpr uint32_t kMaxOctreeLevel = 16;
inline constexpr uint32_t kNoChildren = 0xFFFFFFFFu;

struct OctreeOptions {
  uint32_t leaf_triangles = kDefaultLeafTriangles;  // split while a node references more
  uint32_t max_level = kMaxOctreeLevel;             // the root is level 0
};

// One node: its cube, its eight children (contiguous, from first_child) or, for a leaf
// (first_child == kNoChildren), its triangle references refs[first_ref, first_ref + ref_count).
struct OctreeNode {
  glm::vec3 lo{0.0f};
  float size = 0.0f;
  uint32_t first_child = kNoChildren;
  uint32_t first_ref = 0;
  uint32_t ref_count = 0;
  uint32_t level = 0;

  bool leaf() const { return first_child == kNoChildren; }
  glm::vec3 hi() const { return lo + glm::vec3(size); }
  glm::vec3 center() const { return lo + glm::vec3(0.5f * size); }
};
static_assert(sizeof(OctreeNode) == 32, "OctreeNode is a file record");

struct OctreeStats {
  uint64_t triangles = 0;  // triangles of the mesh
  uint64_t skipped = 0;    // degenerate or non-finite: in no leaf
  uint64_t nodes = 0, leaves = 0, empty_leaves = 0;
  uint64_t refs = 0;          // triangle references over all leaves
  uint64_t largest_leaf = 0;  // references
  uint32_t depth = 0;         // deepest level
  double build_ms = 0.0;
  // Leaves over the face limit that a split would only have copied (this build's; not stored in
  // an octree file, so 0 for a tree read from one).
  uint64_t unsplit_leaves = 0;
};

// A build that would make more references than its input allows (OctreeStats::refs bounded by
// 32 per triangle plus about a million): thrown by every build, in memory or to a file.
class OctreeRefused : public Error {
 public:
  using Error::Error;
};

// Where the build puts what it finishes, in the order it finishes it.
class OctreeSink {
 public:
  virtual ~OctreeSink() = default;
  virtual void leafRefs(const uint32_t* refs, size_t count) = 0;  // one finished leaf's refs
  virtual void nodes(const OctreeNode* nodes, size_t count) = 0;  // 8 siblings, or the root
};

// Builds the octree of `mesh` into `sink`. `progress(fraction)` (may be empty) is called as
// subtrees finish, with the share of the root's volume done. Throws Error for bad options.
OctreeStats buildOctree(const MeshView& mesh, const OctreeOptions& options, OctreeSink& sink,
                        const std::function<void(double)>& progress = {});

// A whole octree in memory: nodes in emission order (the root last) and the leaves' refs.
struct Octree {
  std::vector<OctreeNode> nodes;
  std::vector<uint32_t> refs;
  OctreeStats stats;
  OctreeOptions options;

  uint32_t root() const { return uint32_t(nodes.size() - 1); }
  bool empty() const { return nodes.empty(); }
};
Octree buildOctree(const MeshView& mesh, const OctreeOptions& options,
                   const std::function<void(double)>& progress = {});

// Why `nodes` (emission order, the root last) is not a well-formed tree over `ref_count`
// references with levels up to `max_level`, or empty when it is: every node but the root the
// child of exactly one node, children before their parents, finite cubes, leaves inside the
// references. Every reader of an octree file checks this before trusting the nodes.
std::string checkOctreeNodes(const std::vector<OctreeNode>& nodes, uint64_t ref_count,
                             uint32_t max_level);

// The separating-axis test: whether the triangle (a, b, c) meets the closed box [lo, hi].
bool triangleOverlapsBox(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                         const glm::vec3& lo, const glm::vec3& hi);

// The leaves (with references) in front-to-back order for a view: perspective from `eye`, or
// orthographic looking along `forward`. A leaf is listed before every leaf it can occlude.
void frontToBackLeaves(const Octree& tree, bool perspective, const glm::vec3& eye,
                       const glm::vec3& forward, std::vector<uint32_t>& leaves);

// The octree cache file, written in one sequential pass as the build streams (host byte order):
//   "STRATAOCTREE", u32 version, u64 key, u32 leaf_triangles, u32 max_level, u64 triangles,
//   u64 vertices; the refs (u32 each, leaf by leaf); the nodes (32-byte OctreeNode records);
//   the trailer: the stats, u64 ref count, u64 node count; u64 checksum (FNV-1a 64 of every
//   byte before it).
// Keyed on the mesh's positions and indices and the options; written through a temporary name;
// a file that fails any check is rebuilt and replaced, never trusted.
std::string defaultOctreeCacheDir();
std::string octreeCachePath(const MeshView& mesh, const OctreeOptions& options,
                            const std::string& cache_dir);
// The reason `bytes` are not a valid octree file of `mesh` with `options`, or empty (then *out
// holds the tree).
std::string parseOctreeFile(std::string_view bytes, const MeshView& mesh,
                            const OctreeOptions& options, Octree* out);
// Throws Error naming the file when it is not a valid octree of `mesh` with `options`.
Octree readOctreeFile(const std::string& path, const MeshView& mesh, const OctreeOptions& options);
// Builds straight into `path`; returns the stats and, when `keep` is given, also keeps the tree
// there. Throws Error naming the file on failure (no partial file is left).
OctreeStats writeOctreeFile(const std::string& path, const MeshView& mesh,
                            const OctreeOptions& options,
                            const std::function<void(double)>& progress = {},
                            Octree* keep = nullptr);
// The cached octree, or a fresh build written to the cache (a warning, not an error, when the
// cache cannot be written).
Octree loadOrBuildOctree(const MeshView& mesh, const OctreeOptions& options,
                         const std::string& cache_dir, bool* from_cache = nullptr,
                         const std::function<void(double)>& progress = {});

}  // namespace strata
