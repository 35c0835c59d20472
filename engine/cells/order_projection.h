// The cells order's view (engine/cells/cell_order.cpp): a box's screen rectangle and depth
// range, the side of a plane the eye is on, and the order of two depth ranges. Internal to the
// order's stages.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "engine/cells/cell_order.h"
#include "kernels/strata_shared.h"

namespace strata::cellorder {

struct ScreenExtent {
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // inclusive pixel rectangle; empty when x0 > x1
  float zmin = 0.0f, zmax = 0.0f;        // view distance
  bool visible() const { return x0 <= x1 && y0 <= y1; }
};

inline bool rectsOverlap(const ScreenExtent& a, const ScreenExtent& b) {
  return a.x0 <= b.x1 && b.x0 <= a.x1 && a.y0 <= b.y1 && b.y0 <= a.y1;
}

// View-dependent helpers: the projection of a box and the side of a plane the eye is on.
struct ViewGeometry {
  glm::mat4 view_proj;
  glm::vec3 eye, forward;
  bool perspective;
  float near_distance;
  int width, height;

  ScreenExtent extent(const Bounds& b) const {
    ScreenExtent e;
    e.zmin = 1e30f;
    e.zmax = -1e30f;
    float px0 = 1e30f, py0 = 1e30f, px1 = -1e30f, py1 = -1e30f;
    bool behind = false;
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 p((k & 1) ? b.max.x : b.min.x, (k & 2) ? b.max.y : b.min.y,
                        (k & 4) ? b.max.z : b.min.z);
      const float z = glm::dot(forward, p - eye);
      e.zmin = std::min(e.zmin, z);
      e.zmax = std::max(e.zmax, z);
      if (z < near_distance * 0.5f) {
        behind = true;
        continue;
      }
      const glm::vec4 c = view_proj * glm::vec4(p, 1.0f);
      const float x = (c.x / c.w * 0.5f + 0.5f) * float(width);
      const float y = (0.5f - c.y / c.w * 0.5f) * float(height);
      px0 = std::min(px0, x);
      px1 = std::max(px1, x);
      py0 = std::min(py0, y);
      py1 = std::max(py1, y);
    }
    if (e.zmax < near_distance) return e;  // wholly behind the near plane: empty
    if (behind) {
      e.x0 = 0;
      e.y0 = 0;
      e.x1 = width - 1;
      e.y1 = height - 1;
      return e;
    }
    // One pixel of margin covers snapping and the pixel-centre rule.
    e.x0 = std::max(0, int(std::floor(px0)) - 1);
    e.y0 = std::max(0, int(std::floor(py0)) - 1);
    e.x1 = std::min(width - 1, int(std::ceil(px1)) + 1);
    e.y1 = std::min(height - 1, int(std::ceil(py1)) + 1);
    return e;
  }

  // +1: the cell on the plane's negative side can only be in front (draw it first); -1: the
  // one on the positive side; 0: the eye is on the plane (their projections cannot overlap).
  int negativeFirst(const CellPlane& p) const {
    return st_order_negative_first(p.n.x, p.n.y, p.n.z, p.d, &eye.x, &forward.x,
                                   perspective ? 1 : 0);
  }

  // Order from disjoint boxes: +1 a first, -1 b first, 0 none found (boxes overlap).
  int boxOrder(const Bounds& a, const Bounds& b) const {
    return st_order_boxes(&a.min.x, &a.max.x, &b.min.x, &b.max.x, &eye.x, &forward.x,
                          perspective ? 1 : 0);
  }
};

// +1 a before b, -1 b before a, 0 any order, 2 unknown.
inline int orderOf(const ScreenExtent& ea, const ScreenExtent& eb) {
  if (ea.zmax <= eb.zmin) return 1;
  if (eb.zmax <= ea.zmin) return -1;
  return 2;
}

}  // namespace strata::cellorder
