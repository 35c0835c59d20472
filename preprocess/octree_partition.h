// Splitting an octree into P boxes of balanced triangle references, one per process of a
// distributed render, and the front-to-back order of those boxes for a view. No MPI here.
//
// The split is a k-d tree over the octree's leaves: a set of leaves is cut by an axis-aligned
// plane on the leaves' own grid that no leaf of the set straddles, chosen (over the three axes
// and every such plane) to give the two sides references in proportion to the parts each side
// gets, and the sides are split again until each holds one part's leaves. Each part is thus the
// leaves inside one cell of the k-d tree, a box, so the parts are convex and disjoint, and the
// k-d tree's own order (at each cut the side of the eye first) lists them front to back for
// every view. Planes are compared on the exact integer grid of the octree's finest level; a set
// of one leaf cannot be cut, and the parts it cannot use stay empty.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/octree.h"

namespace strata {

struct OctreePartition {
  // The k-d tree: an inner entry cuts on `axis` at world coordinate `plane` into `lower` and
  // `upper` (entry indices); a leaf entry is part `part`'s cell (-1: a cell no part takes).
  struct Entry {
    int axis = -1;  // -1: a leaf entry
    double plane = 0.0;
    uint32_t lower = 0, upper = 0;
    int part = -1;
  };
  std::vector<Entry> entries;                 // entries[0] is the root
  std::vector<std::vector<uint32_t>> leaves;  // per part: its leaves (node indices, sorted)
  std::vector<uint64_t> refs;                 // per part: triangle references
  // Per part: its cell of the k-d tree, the box [lo, hi) (infinite where no cut bounds it; the
  // cells tile all of space, so along any ray the parts' intervals follow one another).
  std::vector<glm::dvec3> box_lo, box_hi;
};

// Splits `tree`'s leaves with references into `parts` (>= 1) parts; throws Error for 0 parts.
OctreePartition partitionOctree(const Octree& tree, uint32_t parts);

// The parts front to back for a view (perspective from `eye`, or orthographic along `forward`):
// a part is listed before every part it can occlude. Empty parts are listed too (last).
std::vector<uint32_t> partsFrontToBack(const OctreePartition& partition, bool perspective,
                                       const glm::vec3& eye, const glm::vec3& forward);

}  // namespace strata
