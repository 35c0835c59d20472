// The octree method's leaves as its kernels see them: the planes of each non-empty leaf's cube
// for the claim rule (kernels/strata_shared.h, st_octree_leaf_interval). Private to the library.
#pragma once

#include <cstdint>
#include <vector>

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

}  // namespace strata
