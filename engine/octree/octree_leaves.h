// The octree method's leaves as its kernels see them: the planes of each non-empty leaf's cube
// for the claim rule (kernels/strata_shared.h, st_octree_leaf_interval), the blocks and batches
// a frame streams, and the variant that resolves them. Private to the library.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/octree.h"

namespace strata {

struct LeafPlanes {
  uint32_t node = 0;  // the leaf's node in the tree
  StOctreeLeaf box{};
};

// Every leaf with references (or every leaf, with `empty_too`: the leaves tile the whole space),
// depth first. A plane's exact value is root_lo + i * side / 2^level
// for the leaf's integer position i at its level, rounded once to float: leaves that share a
// face hold the same float for it whatever their levels. The root's own faces are at infinity.
std::vector<LeafPlanes> octreeLeafPlanes(const Octree& tree, bool empty_too = false);

// How a variant resolves its blocks (OctreeMethodOptions).
struct Variant {
  bool blocks = true;  // false: the whole scene is one block, nothing is claimed
  uint32_t k = 1;      // fragments per pixel taken per walk
  int count_mode = ST_OCTREE_COUNT_NONE;
};

// The variant OctreeMethodOptions::variant names (k checked); Error for an unknown one.
Variant parseVariant(const OctreeMethodOptions& o);

struct LeafBatch {
  uint32_t first = 0, leaves = 0, refs = 0;       // ordered leaves [first, first + leaves)
  glm::ivec4 rect{INT32_MAX, INT32_MAX, -1, -1};  // pixels its leaves may cover
};

// The blocks a frame streams: leaves with references (or the whole scene as one block), each
// with its planes for the claim rule.
struct BlockSet {
  std::vector<uint32_t> node;   // block -> octree node (kNoChildren for the whole-scene block)
  std::vector<uint32_t> first;  // block -> first reference
  std::vector<uint32_t> count;  // block -> references
  std::vector<StOctreeLeaf> box;
  std::vector<uint32_t> block_of_node;  // octree node -> block (kNoChildren: none)
};

}  // namespace strata
