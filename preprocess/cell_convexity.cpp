// The convexity tests of the cell decomposition: the tolerance and the welding of corners it
// works with, the overlap of coplanar triangles, whether a whole mesh is convex, and the
// strict test of one cell (cellIsStrictlyConvex, convex_cells.h).
#include "preprocess/cell_convexity.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include "preprocess/convex_cells.h"

namespace strata {

namespace cells_detail {

// 1e-6 of the diagonal of the bounding box of the mesh's finite positions (0 for no positions),
// plus the rounding of float coordinates far from the origin (a few units in the last place of
// the largest coordinate), so an instance placed far away decomposes like one at the origin.
double cellTolerance(const MeshView& mesh, glm::dvec3* center) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
  bool any = false;
  for (size_t i = 0; i < mesh.vertex_count; ++i) {
    const glm::vec3& p = mesh.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
    any = true;
  }
  if (!any) {
    if (center) *center = glm::dvec3(0.0);
    return 0.0;
  }
  if (center) *center = (lo + hi) * 0.5;
  const glm::dvec3 far = glm::max(glm::abs(lo), glm::abs(hi));
  return 1e-6 * glm::length(hi - lo) + 5e-7 * std::max(far.x, std::max(far.y, far.z));
}

// weld[v] = the first vertex with exactly v's position (+0 and -0 equal); non-finite vertices
// weld only to themselves.
void weldVertices(const MeshView& mesh, std::vector<uint32_t>* weld) {
  const size_t n = mesh.vertex_count;
  weld->resize(n);
  size_t cap = 16;
  while (cap < 2 * n) cap <<= 1;
  std::vector<uint32_t> table(cap, UINT32_MAX);
  auto bits = [](float f) {
    uint32_t u;
    std::memcpy(&u, &f, 4);
    return u == 0x80000000u ? 0u : u;
  };
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3& p = mesh.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      (*weld)[i] = uint32_t(i);
      continue;
    }
    const uint32_t bx = bits(p.x), by = bits(p.y), bz = bits(p.z);
    uint64_t h = (uint64_t(bx) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(by) * 0xC2B2AE3D27D4EB4Full) ^
                 (uint64_t(bz) * 0x165667B19E3779F9ull);
    h ^= h >> 29;
    size_t slot = size_t(h) & (cap - 1);
    for (;;) {
      const uint32_t e = table[slot];
      if (e == UINT32_MAX) {
        table[slot] = uint32_t(i);
        (*weld)[i] = uint32_t(i);
        break;
      }
      const glm::vec3& q = mesh.positions[e];
      if (bits(q.x) == bx && bits(q.y) == by && bits(q.z) == bz) {
        (*weld)[i] = e;
        break;
      }
      slot = (slot + 1) & (cap - 1);
    }
  }
}

// Whether two triangles lying (within tol) in the plane with unit normal n overlap by more than
// tol, judged in the projection along n: separated if an edge line of either triangle has the
// other triangle entirely (within tol) on its outer side.
bool coplanarTrianglesOverlap(const glm::dvec3 t1[3], const glm::dvec3 t2[3], const glm::dvec3& n,
                              double tol) {
  // A 2-D basis of the plane.
  glm::dvec3 e1 = std::fabs(n.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
  e1 = glm::normalize(e1 - n * glm::dot(n, e1));
  const glm::dvec3 e2 = glm::cross(n, e1);
  glm::dvec2 a[3], b[3];
  for (int i = 0; i < 3; ++i) {
    a[i] = {glm::dot(t1[i] - t1[0], e1), glm::dot(t1[i] - t1[0], e2)};
    b[i] = {glm::dot(t2[i] - t1[0], e1), glm::dot(t2[i] - t1[0], e2)};
  }
  auto separated = [tol](const glm::dvec2 p[3], const glm::dvec2 q[3]) {
    const double area =
        (p[1].x - p[0].x) * (p[2].y - p[0].y) - (p[1].y - p[0].y) * (p[2].x - p[0].x);
    if (area == 0.0) return true;  // a segment covers no area
    const double s = area > 0 ? 1.0 : -1.0;
    for (int i = 0; i < 3; ++i) {
      const glm::dvec2 e = p[(i + 1) % 3] - p[i];
      const double len = std::sqrt(e.x * e.x + e.y * e.y);
      if (len == 0.0) continue;
      // Outward normal of edge i (the triangle is on its negative side).
      const glm::dvec2 m = glm::dvec2(e.y, -e.x) * (s / len);
      bool all_out = true;
      for (int j = 0; j < 3 && all_out; ++j) all_out = glm::dot(m, q[j] - p[i]) >= -tol;
      if (all_out) return true;
    }
    return false;
  };
  return !separated(a, b) && !separated(b, a);
}

// Whether a whole mesh lies on the boundary of one convex body (the strict test over all of it),
// checked in O(vertices x faces) with an early exit: most meshes fail at their first faces. A
// convex mesh larger than the cell size limit (a sphere, a box, a convex CAD part) then stays one
// cell instead of pieces with jagged shared boundaries that no plane separates. Written here
// rather than through cellIsStrictlyConvex, whose coplanar check is quadratic in the faces.
bool wholeMeshIsConvex(const MeshView& mesh) {
  const size_t T = mesh.triangle_count;
  glm::dvec3 centre;
  const double tol = cells_detail::cellTolerance(mesh, &centre);
  std::vector<uint32_t> weld;
  cells_detail::weldVertices(mesh, &weld);
  std::vector<uint32_t> distinct(weld.begin(), weld.end());
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  std::vector<double> xs, ys, zs;
  for (uint32_t v : distinct) {
    const glm::vec3& p = mesh.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
    xs.push_back(double(p.x) - centre.x);
    ys.push_back(double(p.y) - centre.y);
    zs.push_back(double(p.z) - centre.z);
  }
  // Faces in a scattered order, so a non-convex mesh fails fast.
  std::vector<glm::dvec4> planes;
  std::vector<uint32_t> plane_face;
  for (size_t i = 0; i < T; ++i) {
    const size_t f = (i * 2654435761u) % T;
    glm::dvec3 c[3];
    for (int k = 0; k < 3; ++k) c[k] = glm::dvec3(mesh.positions[mesh.indices[3 * f + k]]) - centre;
    const glm::dvec3 cr = glm::cross(c[1] - c[0], c[2] - c[0]);
    const double len = glm::length(cr);
    if (!(len > 0.0)) continue;
    const glm::dvec3 n = cr / len;
    const double d = -glm::dot(n, c[0]);
    double mx = -1e300, mn = 1e300;
    for (size_t v0 = 0; v0 < xs.size(); v0 += 256) {  // blocks: a vectorised inner loop
      const size_t v1 = std::min(xs.size(), v0 + 256);
      for (size_t v = v0; v < v1; ++v) {
        const double e = n.x * xs[v] + n.y * ys[v] + n.z * zs[v] + d;
        mx = e > mx ? e : mx;
        mn = e < mn ? e : mn;
      }
      if (mx > tol && mn < -tol) return false;
    }
    planes.emplace_back(mx > tol ? -n : n, mx > tol ? -d : d);  // outward: vertices behind
    plane_face.push_back(uint32_t(f));
  }
  // No two faces overlapping in one supporting plane: faces grouped by their plane.
  std::vector<uint32_t> order(planes.size());
  for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  auto key = [&](uint32_t i) {
    const glm::dvec4& p = planes[i];
    const double q = 1e-6;
    return std::array<long long, 4>{llround(p.x / q), llround(p.y / q), llround(p.z / q),
                                    llround(p.w / (tol * 4.0))};
  };
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return key(a) < key(b); });
  for (size_t i = 0; i < order.size();) {
    size_t j = i + 1;
    while (j < order.size() && key(order[j]) == key(order[i])) ++j;
    for (size_t a = i; a < j; ++a) {
      for (size_t b = a + 1; b < j; ++b) {
        glm::dvec3 ta[3], tb[3];
        for (int k = 0; k < 3; ++k) {
          ta[k] = glm::dvec3(mesh.positions[mesh.indices[3 * size_t(plane_face[order[a]]) + k]]) -
                  centre;
          tb[k] = glm::dvec3(mesh.positions[mesh.indices[3 * size_t(plane_face[order[b]]) + k]]) -
                  centre;
        }
        if (cells_detail::coplanarTrianglesOverlap(ta, tb, glm::dvec3(planes[order[a]]), tol))
          return false;
      }
    }
    i = j;
  }
  return true;
}

}  // namespace cells_detail

bool cellIsStrictlyConvex(const MeshView& mesh, const uint32_t* triangles, size_t count,
                          float tolerance) {
  if (count <= 1) return true;
  const double tol = tolerance;
  // Unique vertex positions and the faces' planes, in double precision.
  std::vector<glm::dvec3> verts;
  std::vector<glm::dvec3> tri(3 * count);
  std::vector<glm::dvec4> planes(count);
  std::vector<uint8_t> has_plane(count, 0);
  for (size_t i = 0; i < count; ++i) {
    const uint32_t t = triangles[i];
    if (t >= mesh.triangle_count) return false;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.indices[3 * size_t(t) + k];
      if (v >= mesh.vertex_count) return false;
      const glm::vec3& p = mesh.positions[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
      tri[3 * i + k] = glm::dvec3(p);
      verts.push_back(glm::dvec3(p));
    }
    const glm::dvec3 cr = glm::cross(tri[3 * i + 1] - tri[3 * i], tri[3 * i + 2] - tri[3 * i]);
    const double len = glm::length(cr);
    if (len > 0.0) {  // zero-area faces cover nothing and constrain nothing
      const glm::dvec3 n = cr / len;
      planes[i] = glm::dvec4(n, -glm::dot(n, (tri[3 * i] + tri[3 * i + 1] + tri[3 * i + 2]) / 3.0));
      has_plane[i] = 1;
    }
  }
  std::sort(verts.begin(), verts.end(), [](const glm::dvec3& a, const glm::dvec3& b) {
    return a.x != b.x ? a.x < b.x : a.y != b.y ? a.y < b.y : a.z < b.z;
  });
  verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
  auto dist = [&](size_t f, const glm::dvec3& x) {
    return glm::dot(glm::dvec3(planes[f]), x) + planes[f].w;
  };
  // Every face a supporting plane: all vertices (within tol) on one side of it. The outward side
  // is then the other one, so orientations are consistent by construction.
  for (size_t f = 0; f < count; ++f) {
    if (!has_plane[f]) continue;
    double mx = -1e300, mn = 1e300;
    for (const glm::dvec3& x : verts) {
      const double e = dist(f, x);
      mx = std::max(mx, e);
      mn = std::min(mn, e);
    }
    if (mx > tol && mn < -tol) return false;
  }
  // No two faces in one plane overlapping.
  for (size_t f = 0; f < count; ++f) {
    if (!has_plane[f]) continue;
    for (size_t g = f + 1; g < count; ++g) {
      if (!has_plane[g]) continue;
      const bool g_in_f = std::fabs(dist(f, tri[3 * g])) <= tol &&
                          std::fabs(dist(f, tri[3 * g + 1])) <= tol &&
                          std::fabs(dist(f, tri[3 * g + 2])) <= tol;
      const bool f_in_g = std::fabs(dist(g, tri[3 * f])) <= tol &&
                          std::fabs(dist(g, tri[3 * f + 1])) <= tol &&
                          std::fabs(dist(g, tri[3 * f + 2])) <= tol;
      if (g_in_f && cells_detail::coplanarTrianglesOverlap(&tri[3 * f], &tri[3 * g],
                                                           glm::dvec3(planes[f]), tol))
        return false;
      if (f_in_g && cells_detail::coplanarTrianglesOverlap(&tri[3 * g], &tri[3 * f],
                                                           glm::dvec3(planes[g]), tol))
        return false;
    }
  }
  return true;
}

}  // namespace strata
