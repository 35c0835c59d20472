#include "engine/octree/octree_leaves.h"

#include <cmath>
#include <string>

namespace strata {

namespace {

void addLeaves(const Octree& tree, uint32_t node, uint32_t level, const uint32_t ijk[3],
               bool empty_too, std::vector<LeafPlanes>& out) {
  const OctreeNode& n = tree.nodes[node];
  if (!n.leaf()) {
    for (uint32_t c = 0; c < 8; ++c) {
      const uint32_t child[3] = {2 * ijk[0] + (c & 1), 2 * ijk[1] + ((c >> 1) & 1),
                                 2 * ijk[2] + ((c >> 2) & 1)};
      addLeaves(tree, n.first_child + c, level + 1, child, empty_too, out);
    }
    return;
  }
  if (n.ref_count == 0 && !empty_too) return;
  const OctreeNode& root = tree.nodes[tree.root()];
  const double cells = std::ldexp(1.0, int(level));
  auto plane = [&](int axis, uint32_t i) -> float {
    if (i == 0) return -INFINITY;
    if (double(i) == cells) return INFINITY;
    return float(double(root.lo[axis]) + double(i) * (double(root.size) / cells));
  };
  LeafPlanes leaf;
  leaf.node = node;
  for (int a = 0; a < 3; ++a) {
    leaf.box.lo[a] = plane(a, ijk[a]);
    leaf.box.hi[a] = plane(a, ijk[a] + 1);
  }
  out.push_back(leaf);
}

}  // namespace

std::vector<LeafPlanes> octreeLeafPlanes(const Octree& tree, bool empty_too) {
  std::vector<LeafPlanes> out;
  if (tree.empty()) return out;
  const uint32_t origin[3] = {0, 0, 0};
  addLeaves(tree, tree.root(), 0, origin, empty_too, out);
  return out;
}

Variant parseVariant(const OctreeMethodOptions& o) {
  if (o.variant == "kbuffer") {
    if (o.k < 1 || o.k > ST_OCTREE_MAX_K)
      throw Error("octree: the k-buffer size k = " + std::to_string(o.k) +
                  " must be between 1 and " + std::to_string(ST_OCTREE_MAX_K));
    return {true, o.k, ST_OCTREE_COUNT_FIRST};
  }
  if (o.variant == "blocks-histogram") return {true, 1, ST_OCTREE_COUNT_COVERAGE};
  if (o.variant == "blocks") return {true, 1, ST_OCTREE_COUNT_NONE};
  if (o.variant == "histogram") return {false, 1, ST_OCTREE_COUNT_COVERAGE};
  if (o.variant == "dp") return {false, 1, ST_OCTREE_COUNT_NONE};
  throw Error("octree: unknown variant '" + o.variant +
              "' (known: kbuffer, blocks-histogram, blocks, histogram, dp)");
}

}  // namespace strata
