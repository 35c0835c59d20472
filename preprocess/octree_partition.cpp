#include "preprocess/octree_partition.h"

#include <algorithm>
#include <cmath>

#include "strata/error.h"

namespace strata {

namespace {

// A leaf with references on the integer grid of the finest level: [lo, hi) per axis.
struct GridLeaf {
  uint32_t node = 0;
  uint64_t refs = 0;
  uint32_t lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
};

void gridLeaves(const Octree& tree, uint32_t node, uint32_t level, const uint32_t ijk[3],
                std::vector<GridLeaf>& out) {
  const OctreeNode& n = tree.nodes[node];
  if (!n.leaf()) {
    for (uint32_t c = 0; c < 8; ++c) {
      const uint32_t child[3] = {2 * ijk[0] + (c & 1), 2 * ijk[1] + ((c >> 1) & 1),
                                 2 * ijk[2] + ((c >> 2) & 1)};
      gridLeaves(tree, n.first_child + c, level + 1, child, out);
    }
    return;
  }
  if (n.ref_count == 0) return;
  GridLeaf g;
  g.node = node;
  g.refs = n.ref_count;
  const uint32_t shift = kMaxOctreeLevel - level;
  for (int a = 0; a < 3; ++a) {
    g.lo[a] = ijk[a] << shift;
    g.hi[a] = (ijk[a] + 1) << shift;
  }
  out.push_back(g);
}

class Partitioner {
 public:
  Partitioner(const Octree& tree, OctreePartition& out) : tree_(tree), out_(out) {
    const OctreeNode& root = tree.nodes[tree.root()];
    for (int a = 0; a < 3; ++a) root_lo_[a] = root.lo[a];
    cell_ = double(root.size) / std::ldexp(1.0, int(kMaxOctreeLevel));
  }

  // Deals parts [first, first + count) out over `leaves`; returns the entry made for them.
  uint32_t assign(std::vector<GridLeaf> leaves, uint32_t first, uint32_t count,
                  const glm::dvec3& lo, const glm::dvec3& hi) {
    const uint32_t e = uint32_t(out_.entries.size());
    out_.entries.push_back({});
    uint64_t refs = 0;
    for (const GridLeaf& l : leaves) refs += l.refs;
    if (count == 0 || leaves.empty()) return e;  // a cell no part needs
    if (count == 1 || leaves.size() == 1) {
      out_.entries[e].part = int(first);
      for (const GridLeaf& l : leaves) out_.leaves[first].push_back(l.node);
      std::sort(out_.leaves[first].begin(), out_.leaves[first].end());
      out_.refs[first] = refs;
      out_.box_lo[first] = lo;
      out_.box_hi[first] = hi;
      return e;
    }
    // Over every axis and every grid plane no leaf straddles (the smallest node holding the
    // leaves always offers one), the cut whose sides, given parts in proportion, would have the
    // smallest share per part on the heavier side.
    const auto partsBelow = [&](uint64_t below) {
      return std::clamp<uint32_t>(
          uint32_t(std::llround(double(count) * double(below) / double(refs))), 1, count - 1);
    };
    int best_axis = -1;
    uint32_t best_plane = 0;
    double best_share = INFINITY;
    for (int axis = 0; axis < 3; ++axis) {
      std::sort(leaves.begin(), leaves.end(),
                [axis](const GridLeaf& a, const GridLeaf& b) { return a.lo[axis] < b.lo[axis]; });
      uint64_t below = 0;
      uint32_t reach = 0;  // the highest end of the leaves taken so far
      for (size_t i = 0; i + 1 < leaves.size(); ++i) {
        below += leaves[i].refs;
        reach = std::max(reach, leaves[i].hi[axis]);
        const uint32_t next = leaves[i + 1].lo[axis];
        if (reach > next || next == leaves[i].lo[axis]) continue;  // straddled, or not between
        const uint32_t n = partsBelow(below);
        const double share =
            std::max(double(below) / double(n), double(refs - below) / double(count - n));
        if (share < best_share) {
          best_share = share;
          best_axis = axis;
          best_plane = next;
        }
      }
    }
    if (best_axis < 0) throw Error("octree partition: leaves that no plane separates");
    std::vector<GridLeaf> lower, upper;
    uint64_t lower_refs = 0;
    for (const GridLeaf& l : leaves) {
      if (l.hi[best_axis] <= best_plane) {
        lower.push_back(l);
        lower_refs += l.refs;
      } else {
        upper.push_back(l);
      }
    }
    const uint32_t to_lower = partsBelow(lower_refs);
    out_.entries[e].axis = best_axis;
    out_.entries[e].plane = double(root_lo_[best_axis]) + double(best_plane) * cell_;
    glm::dvec3 cut_hi = hi, cut_lo = lo;
    cut_hi[best_axis] = cut_lo[best_axis] = out_.entries[e].plane;
    const uint32_t le = assign(std::move(lower), first, to_lower, lo, cut_hi);
    const uint32_t ue = assign(std::move(upper), first + to_lower, count - to_lower, cut_lo, hi);
    out_.entries[e].lower = le;
    out_.entries[e].upper = ue;
    return e;
  }

 private:
  const Octree& tree_;
  OctreePartition& out_;
  float root_lo_[3] = {0, 0, 0};
  double cell_ = 1.0;
};

}  // namespace

OctreePartition partitionOctree(const Octree& tree, uint32_t parts) {
  if (parts < 1) throw Error("an octree is split into at least one part");
  OctreePartition p;
  p.leaves.assign(parts, {});
  p.refs.assign(parts, 0);
  p.box_lo.assign(parts, glm::dvec3(INFINITY));
  p.box_hi.assign(parts, glm::dvec3(-INFINITY));
  if (tree.empty()) return p;
  std::vector<GridLeaf> leaves;
  const uint32_t origin[3] = {0, 0, 0};
  gridLeaves(tree, tree.root(), 0, origin, leaves);
  Partitioner(tree, p).assign(std::move(leaves), 0, parts, glm::dvec3(-INFINITY),
                              glm::dvec3(INFINITY));
  return p;
}

std::vector<uint32_t> partsFrontToBack(const OctreePartition& partition, bool perspective,
                                       const glm::vec3& eye, const glm::vec3& forward) {
  std::vector<uint32_t> order;
  std::vector<uint8_t> listed(partition.leaves.size(), 0);
  std::vector<uint32_t> stack;
  if (!partition.entries.empty()) stack.push_back(0);
  while (!stack.empty()) {
    const OctreePartition::Entry& e = partition.entries[stack.back()];
    stack.pop_back();
    if (e.axis < 0) {
      if (e.part >= 0) {
        order.push_back(uint32_t(e.part));
        listed[size_t(e.part)] = 1;
      }
      continue;
    }
    // The side of the eye first (orthographic: the viewer is at infinity against the view
    // direction), as frontToBackLeaves orders a node's children.
    const bool upper_first = perspective ? double(eye[e.axis]) > e.plane : forward[e.axis] < 0.0f;
    stack.push_back(upper_first ? e.lower : e.upper);
    stack.push_back(upper_first ? e.upper : e.lower);
  }
  for (uint32_t i = 0; i < partition.leaves.size(); ++i)
    if (!listed[i]) order.push_back(i);
  return order;
}

}  // namespace strata
