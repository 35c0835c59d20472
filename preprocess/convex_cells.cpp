// Convex cells by seed growing (methods/convex-cells.md, preprocessing step 1).
//
// Strict mode: a candidate face reached across an edge of the cell joins only if, afterwards,
// every vertex of the cell is within the tolerance of or behind every oriented face plane of the
// cell and the candidate overlaps no face of the cell lying in (within the tolerance) the same
// plane. The cell then lies on the boundary of one convex body, so from any viewpoint it has at
// most one front and one back fragment per pixel. Each face's orientation is taken from the
// geometry (the side the cell lies on), so flipped windings and triangle soups are handled; while
// a cell is flat its orientation is free, so concave regions (seen from outside) grow cells too.
// Paper mode: the paper's local test (the candidate's far corner on or below the plane of the face
// it is reached from, faces oriented by their winding), which can admit non-convex cells.
//
// Cells grow across edges: the neighbours of a face are all faces with both corners of one of its
// edges (welded by position), from the half-edge connectivity of preprocess/mesh_connectivity.h,
// which keeps the faces OpenMesh refuses (a third face on an edge, duplicates, flipped windings).
//
// Plane and distance arithmetic is in double precision on positions centred on the bounding box,
// so the tolerance (1e-6 of the bounding-box diagonal) is not eaten by float rounding.
#include "preprocess/convex_cells.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "preprocess/cell_convexity.h"
#include "preprocess/core/enum_table.h"
#include "preprocess/mesh_connectivity.h"
#include "preprocess/scene/scene.h"

namespace strata {

using cells_detail::coplanarTrianglesOverlap;

constexpr const char* kDecomposeModeNames[] = {"strict", "paper"};

const char* decomposeModeName(DecomposeMode mode) {
  return enumLookup(mode, kDecomposeModeNames, "unknown");
}

const char* optionName(DecomposeMode value) { return decomposeModeName(value); }

DecomposeMode parseDecomposeMode(const std::string& name) {
  if (auto mode = enumFromName<DecomposeMode>(name, kDecomposeModeNames)) return *mode;
  throw Error("unknown decomposition mode '" + name + "' (expected strict or paper)");
}

namespace {

constexpr uint32_t kNone = UINT32_MAX;
constexpr size_t kGroupedCopies = 3;  // coincident triangles grouped from this many

// Per-mesh data of the decomposition: welded corners, planes, edge adjacency.
struct Prepared {
  double tol = 0.0;
  std::vector<double> pos;       // 3 per vertex, centred on the bounding box
  std::vector<uint32_t> corner;  // 3 per triangle: welded vertex ids
  std::vector<double> plane;     // 4 per triangle: unit normal (winding) and d, centred coords
  std::vector<uint8_t> bad;      // degenerate or non-finite: a cell of its own
  // Per triangle: the lowest triangle with the same three welded corners (in any order), when
  // kGroupedCopies or more share them (kNone otherwise). Such copies are cells of their own too
  // (alone).
  std::vector<uint32_t> copy_of;
  std::vector<uint8_t> alone;  // bad or a copy: a cell of one triangle, never grown or merged
  // Edge adjacency (preprocess/mesh_connectivity.h): the face-edge slots (3 * triangle + edge)
  // on each edge, every face with both the edge's welded corners whatever its winding or how many
  // faces share the edge; bad triangles have none.
  std::optional<MeshConnectivity> edges;

  glm::dvec3 p(uint32_t v) const { return {pos[3 * v], pos[3 * v + 1], pos[3 * v + 2]}; }
  glm::dvec3 normal(uint32_t t) const { return {plane[4 * t], plane[4 * t + 1], plane[4 * t + 2]}; }
};

Prepared prepare(const MeshView& mesh) {
  Prepared pr;
  const size_t T = mesh.triangle_count, V = mesh.vertex_count;
  glm::dvec3 center;
  pr.tol = cells_detail::cellTolerance(mesh, &center);
  std::vector<uint32_t> weld;
  cells_detail::weldVertices(mesh, &weld);
  pr.pos.resize(3 * V);
  for (size_t v = 0; v < V; ++v)
    for (int k = 0; k < 3; ++k) pr.pos[3 * v + k] = double(mesh.positions[v][k]) - center[k];

  pr.corner.resize(3 * T);
  pr.plane.assign(4 * T, 0.0);
  pr.bad.assign(T, 0);
  for (size_t t = 0; t < T; ++t) {
    uint32_t w[3];
    bool finite = true;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.indices[3 * t + k];
      w[k] = weld[v];
      const glm::vec3& q = mesh.positions[v];
      finite = finite && std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z);
      pr.corner[3 * t + k] = w[k];
    }
    if (!finite || w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) {
      pr.bad[t] = 1;
      continue;
    }
    const glm::dvec3 a = pr.p(w[0]), b = pr.p(w[1]), c = pr.p(w[2]);
    const glm::dvec3 cr = glm::cross(b - a, c - a);
    const double len = glm::length(cr);
    if (!(len > 0.0) || !std::isfinite(len)) {
      pr.bad[t] = 1;
      continue;
    }
    const glm::dvec3 n = cr / len;
    pr.plane[4 * t] = n.x;
    pr.plane[4 * t + 1] = n.y;
    pr.plane[4 * t + 2] = n.z;
    pr.plane[4 * t + 3] = -glm::dot(n, (a + b + c) / 3.0);
  }

  // Coincident triangles, grouped by their sorted corners: one pass of a sort, however many
  // copies, where growing and pairing them one by one would be quadratic in the copies. A pair
  // (two solids touching along a face, a face modelled twice) costs one pair, and its cells stay
  // whole: only three or more are grouped.
  pr.copy_of.assign(T, kNone);
  pr.alone = pr.bad;
  {
    std::vector<std::array<uint32_t, 4>> keys(T);
    for (size_t t = 0; t < T; ++t) {
      std::array<uint32_t, 3> w{pr.corner[3 * t], pr.corner[3 * t + 1], pr.corner[3 * t + 2]};
      std::sort(w.begin(), w.end());
      keys[t] = {w[0], w[1], w[2], uint32_t(t)};
    }
    std::sort(keys.begin(), keys.end());
    for (size_t i = 0; i < T;) {
      size_t j = i + 1;
      while (j < T && keys[j][0] == keys[i][0] && keys[j][1] == keys[i][1] &&
             keys[j][2] == keys[i][2])
        ++j;
      if (j - i >= kGroupedCopies)
        for (size_t k = i; k < j; ++k) {
          pr.copy_of[keys[k][3]] = keys[i][3];
          pr.alone[keys[k][3]] = 1;
        }
      i = j;
    }
  }

  ConnectivityOptions co;
  co.vertex_map = weld.data();
  co.exclude = pr.alone.data();
  pr.edges.emplace(mesh, co);
  return pr;
}

// One growing cell of the strict test: oriented planes, unique vertices, faces.
class StrictGrower {
 public:
  StrictGrower(const Prepared& pr, size_t triangles, size_t vertices, uint32_t max_faces)
      : pr_(pr),
        max_(max_faces),
        tstamp_(triangles, 0),
        vstamp_(vertices, 0),
        vlocal_(vertices, 0) {
    planes_.reserve(4 * size_t(max_faces));
    verts_.reserve(3 * 3 * size_t(max_faces));
    vdist_.reserve(3 * size_t(max_faces));
  }

  // Grows the cell from `seed`; appends its triangles to `out`, their final orientations (+1:
  // the winding's normal is outward) to `sign`, and returns whether the cell is flat (every
  // vertex within tol of every face plane, so it may still turn over).
  bool grow(uint32_t seed, uint32_t cell, std::vector<uint32_t>* owner, std::vector<uint32_t>* out,
            std::vector<int8_t>* sign) {
    growFaces(seed, cell, owner, out);
    for (size_t i = 0; i < faces_.size(); ++i) {
      const uint32_t t = faces_[i];
      const double* w = &pr_.plane[4 * t];
      (*sign)[t] = planes_[4 * i] * w[0] + planes_[4 * i + 1] * w[1] + planes_[4 * i + 2] * w[2] > 0
                       ? 1
                       : -1;
    }
    return flat_;
  }

 private:
  void growFaces(uint32_t seed, uint32_t cell, std::vector<uint32_t>* owner,
                 std::vector<uint32_t>* out) {
    stamp_ = cell + 1;
    planes_.clear();
    verts_.clear();
    faces_.clear();
    face_local_.clear();
    queue_.clear();
    flat_ = true;
    add(seed, 1.0, owner, out);
    for (size_t head = 0; head < queue_.size() && faces_.size() < max_; ++head) {
      const auto [t, src] = queue_[head];
      if ((*owner)[t] != kNone || tstamp_[t] == stamp_ || pr_.alone[t]) continue;
      double s = 1.0;
      if (test(t, src, &s)) {
        add(t, s, owner, out);
      } else {
        tstamp_[t] = stamp_;
      }
    }
  }

  void add(uint32_t t, double s, std::vector<uint32_t>* owner, std::vector<uint32_t>* out) {
    if (flip_pending_) {
      for (size_t i = 0; i < planes_.size(); ++i) planes_[i] = -planes_[i];
      flip_pending_ = false;
    }
    if (!faces_.empty()) flat_ = flat_ && stays_flat_;
    (*owner)[t] = stamp_ - 1;
    out->push_back(t);
    faces_.push_back(t);
    for (int k = 0; k < 4; ++k) planes_.push_back(s * pr_.plane[4 * t + k]);
    for (int k = 0; k < 3; ++k) {
      const uint32_t w = pr_.corner[3 * t + k];
      if (vstamp_[w] != stamp_) {
        vstamp_[w] = stamp_;
        vlocal_[w] = uint32_t(verts_.size() / 3);
        for (int j = 0; j < 3; ++j) verts_.push_back(pr_.pos[3 * w + j]);
      }
      face_local_.push_back(vlocal_[w]);
    }
    // Neighbours in triangle order, so the result does not depend on windings or on which
    // corner a triangle starts at.
    const size_t first = queue_.size();
    for (int k = 0; k < 3; ++k) {
      const uint32_t e = pr_.edges->edgeOf(t, k);
      if (e == MeshConnectivity::kNone) continue;
      for (uint32_t slot : pr_.edges->edgeSlots(e)) {
        const uint32_t u = slot / 3;
        if (u != t && tstamp_[u] != stamp_ && (*owner)[u] == kNone) queue_.push_back({u, t});
      }
    }
    std::sort(queue_.begin() + long(first), queue_.end());
  }

  // The strict test for candidate t reached from cell face src; *s receives its orientation.
  bool test(uint32_t t, uint32_t src, double* s) {
    const double tol = pr_.tol;
    const uint32_t* w = &pr_.corner[3 * t];
    glm::dvec3 q[3];
    bool is_new[3];
    int new_count = 0;
    for (int k = 0; k < 3; ++k) {
      q[k] = pr_.p(w[k]);
      is_new[k] = vstamp_[w[k]] != stamp_;
      new_count += is_new[k];
    }
    // A flat cell (every vertex within tol of every face plane) may turn over: the candidate's
    // new corners decide which side is behind.
    double flip = 1.0;
    for (int k = 0; k < 3 && flat_; ++k) {
      if (!is_new[k]) continue;
      const double e = planes_[0] * q[k].x + planes_[1] * q[k].y + planes_[2] * q[k].z + planes_[3];
      if (e > tol) flip = -1.0;
    }
    flip_pending_ = false;
    stays_flat_ = flat_;

    // The cell's vertices against the candidate's plane: all on one side.
    const double nx = pr_.plane[4 * t], ny = pr_.plane[4 * t + 1], nz = pr_.plane[4 * t + 2],
                 nd = pr_.plane[4 * t + 3];
    const size_t nv = verts_.size() / 3;
    vdist_.resize(nv);
    double mx = -std::numeric_limits<double>::max(), mn = std::numeric_limits<double>::max();
    const double* vp = verts_.data();
    for (size_t i = 0; i < nv; ++i) {
      const double e = nx * vp[3 * i] + ny * vp[3 * i + 1] + nz * vp[3 * i + 2] + nd;
      vdist_[i] = e;
      mx = std::max(mx, e);
      mn = std::min(mn, e);
      if (mx > tol && mn < -tol) return false;
    }
    if (mx <= tol && mn >= -tol) {
      // (stays_flat_ keeps its value: the cell is in the candidate's plane)
      // The cell lies in the candidate's plane: face the way the face it is reached from does.
      const double* sp = &pr_.plane[4 * src];
      double src_sign = 1.0;
      for (size_t i = 0; i < faces_.size(); ++i)
        if (faces_[i] == src) {
          src_sign =
              planes_[4 * i] * sp[0] + planes_[4 * i + 1] * sp[1] + planes_[4 * i + 2] * sp[2] > 0
                  ? 1.0
                  : -1.0;
          break;
        }
      *s = (nx * sp[0] + ny * sp[1] + nz * sp[2]) * src_sign * flip >= 0 ? 1.0 : -1.0;
    } else {
      *s = mx <= tol ? 1.0 : -1.0;
      stays_flat_ = false;
    }

    // The candidate's new corners against the cell's planes; coplanar faces collected.
    coplanar_.clear();
    const double* pp = planes_.data();
    const size_t nf = faces_.size();
    for (size_t f = 0; f < nf; ++f) {
      const double a = pp[4 * f] * flip, b = pp[4 * f + 1] * flip, c = pp[4 * f + 2] * flip,
                   d = pp[4 * f + 3] * flip;
      bool in_plane = true;
      for (int k = 0; k < 3; ++k) {
        if (!is_new[k]) continue;
        const double e = a * q[k].x + b * q[k].y + c * q[k].z + d;
        if (e > tol) return false;
        if (e < -tol) in_plane = false;
      }
      if (!in_plane) stays_flat_ = false;
      // Coplanar either way: the candidate in this face's plane, or this face in the candidate's.
      const uint32_t* fl = &face_local_[3 * f];
      bool face_in_cand = std::fabs(vdist_[fl[0]]) <= tol && std::fabs(vdist_[fl[1]]) <= tol &&
                          std::fabs(vdist_[fl[2]]) <= tol;
      bool cand_in_face = in_plane;
      if (cand_in_face && new_count < 3) {
        for (int k = 0; k < 3 && cand_in_face; ++k)
          if (!is_new[k]) cand_in_face = std::fabs(a * q[k].x + b * q[k].y + c * q[k].z + d) <= tol;
      }
      if (cand_in_face || face_in_cand) coplanar_.push_back({uint32_t(f), cand_in_face});
    }
    for (const auto& [f, in_face] : coplanar_) {
      const uint32_t g = faces_[f];
      glm::dvec3 r[3];
      for (int k = 0; k < 3; ++k) r[k] = pr_.p(pr_.corner[3 * g + k]);
      const glm::dvec3 n = in_face ? pr_.normal(g) : pr_.normal(t);
      if (coplanarTrianglesOverlap(q, r, n, tol)) return false;
    }
    flip_pending_ = flip < 0;
    return true;
  }

  const Prepared& pr_;
  const uint32_t max_;
  std::vector<uint32_t> tstamp_, vstamp_, vlocal_;
  uint32_t stamp_ = 0;
  std::vector<double> planes_, verts_, vdist_;
  std::vector<uint32_t> faces_, face_local_;
  std::vector<std::pair<uint32_t, uint32_t>> queue_;
  std::vector<std::pair<uint32_t, bool>> coplanar_;
  bool flat_ = true, stays_flat_ = true, flip_pending_ = false;
};

// Second pass of the strict mode: adjacent cells whose union still passes the strict test are
// merged (greedy, in the order of their first triangles; a failed union never succeeds later,
// since a superset of a non-convex set is not convex).
class CellMerger {
 public:
  CellMerger(const Prepared& pr, size_t vertices, uint32_t max_faces)
      : pr_(pr), max_(max_faces), vstamp_(vertices, 0) {}

  void run(CellDecomposition* cells, std::vector<int8_t>* sign,
           const std::vector<uint8_t>& flat_in) {
    const uint32_t C = cells->cellCount();
    const size_t T = cells->triangle_order.size();
    std::vector<uint32_t> cell_of(T);
    faces_.resize(C);
    verts_.resize(C);
    flat_ = flat_in;
    parent_.resize(C);
    for (uint32_t c = 0; c < C; ++c) {
      parent_[c] = c;
      faces_[c].assign(cells->triangle_order.begin() + cells->cell_begin[c],
                       cells->triangle_order.begin() + cells->cell_begin[c + 1]);
      for (uint32_t t : faces_[c]) cell_of[t] = c;
      verts_[c] = uniqueVerts(faces_[c], c + 1);
    }
    // Cells sharing a vertex. (Cells sharing an edge were tried by the growing: a face across
    // the edge failed to join, so their union fails too, unless the size cap stopped growth.)
    std::vector<uint64_t> corners;  // (welded vertex, cell)
    corners.reserve(3 * T);
    for (uint32_t c = 0; c < C; ++c) {
      if (pr_.alone[faces_[c][0]]) continue;  // degenerate, non-finite and copies stay alone
      for (uint32_t w : verts_[c]) corners.push_back((uint64_t(w) << 32) | c);
    }
    std::sort(corners.begin(), corners.end());
    std::vector<uint64_t> adj;
    for (size_t i = 0; i < corners.size();) {
      size_t j = i + 1;
      while (j < corners.size() && (corners[j] >> 32) == (corners[i] >> 32)) ++j;
      for (size_t x = i; x < j; ++x)
        for (size_t y = x + 1; y < j; ++y) adj.push_back((corners[x] << 32) | uint32_t(corners[y]));
      i = j;
    }
    corners = {};
    std::sort(adj.begin(), adj.end());
    adj.erase(std::unique(adj.begin(), adj.end()), adj.end());
    sign_ = sign;
    bool merged = false;
    for (uint64_t k : adj) {
      const uint32_t a = find(uint32_t(k >> 32)), b = find(uint32_t(k));
      if (a == b || faces_[a].size() + faces_[b].size() > max_) continue;
      if (tryMerge(std::min(a, b), std::max(a, b))) merged = true;
    }
    if (!merged) return;
    cells->cell_begin.assign(1, 0);
    cells->triangle_order.clear();
    for (uint32_t c = 0; c < C; ++c) {
      if (parent_[c] != c) continue;
      cells->triangle_order.insert(cells->triangle_order.end(), faces_[c].begin(), faces_[c].end());
      cells->cell_begin.push_back(uint32_t(cells->triangle_order.size()));
    }
  }

 private:
  uint32_t find(uint32_t x) {
    while (parent_[x] != x) x = parent_[x] = parent_[parent_[x]];
    return x;
  }

  std::vector<uint32_t> uniqueVerts(const std::vector<uint32_t>& faces, uint32_t stamp) {
    std::vector<uint32_t> v;
    for (uint32_t t : faces)
      for (int k = 0; k < 3; ++k) {
        const uint32_t w = pr_.corner[3 * t + k];
        if (vstamp_[w] != stamp) vstamp_[w] = stamp, v.push_back(w);
      }
    return v;
  }

  // Faces of x (turned over by fx) against the vertices of y: all behind within tol?
  bool behind(uint32_t x, double fx, uint32_t y, bool* in_plane) {
    for (uint32_t t : faces_[x]) {
      const double* P = &pr_.plane[4 * t];
      const double s = fx * (*sign_)[t];
      for (uint32_t w : verts_[y]) {
        const double* q = &pr_.pos[3 * w];
        const double e = s * (P[0] * q[0] + P[1] * q[1] + P[2] * q[2] + P[3]);
        if (e > pr_.tol) return false;
        if (e < -pr_.tol) *in_plane = false;
      }
    }
    return true;
  }

  bool inPlane(uint32_t plane_tri, uint32_t tri) const {
    const double* P = &pr_.plane[4 * plane_tri];
    for (int k = 0; k < 3; ++k) {
      const double* q = &pr_.pos[3 * pr_.corner[3 * tri + k]];
      if (std::fabs(P[0] * q[0] + P[1] * q[1] + P[2] * q[2] + P[3]) > pr_.tol) return false;
    }
    return true;
  }

  bool tryMerge(uint32_t a, uint32_t b) {
    // Orientations: a flat cell may turn over.
    const double flips[2] = {1.0, -1.0};
    bool ok = false, flat = false;
    double fa = 1.0, fb = 1.0;
    for (int i = 0; i < (flat_[a] ? 2 : 1) && !ok; ++i)
      for (int j = 0; j < (flat_[b] ? 2 : 1) && !ok; ++j) {
        bool in_plane = true;
        if (behind(a, flips[i], b, &in_plane) && behind(b, flips[j], a, &in_plane)) {
          ok = true;
          fa = flips[i];
          fb = flips[j];
          flat = flat_[a] && flat_[b] && in_plane;
        }
      }
    if (!ok) return false;
    // No overlap between faces of a and b lying in one plane.
    for (uint32_t f : faces_[a])
      for (uint32_t g : faces_[b]) {
        const bool g_in_f = inPlane(f, g), f_in_g = inPlane(g, f);
        if (!g_in_f && !f_in_g) continue;
        glm::dvec3 tf[3], tg[3];
        for (int k = 0; k < 3; ++k) {
          tf[k] = pr_.p(pr_.corner[3 * f + k]);
          tg[k] = pr_.p(pr_.corner[3 * g + k]);
        }
        if (coplanarTrianglesOverlap(tf, tg, g_in_f ? pr_.normal(f) : pr_.normal(g), pr_.tol))
          return false;
      }
    if (fa < 0)
      for (uint32_t t : faces_[a]) (*sign_)[t] = int8_t(-(*sign_)[t]);
    if (fb < 0)
      for (uint32_t t : faces_[b]) (*sign_)[t] = int8_t(-(*sign_)[t]);
    faces_[a].insert(faces_[a].end(), faces_[b].begin(), faces_[b].end());
    faces_[b] = {};
    ++stamp_base_;
    verts_[a] = uniqueVerts(faces_[a], uint32_t(parent_.size()) + stamp_base_);
    verts_[b] = {};
    flat_[a] = flat;
    parent_[b] = a;
    return true;
  }

  const Prepared& pr_;
  const uint32_t max_;
  std::vector<uint32_t> vstamp_, parent_;
  std::vector<std::vector<uint32_t>> faces_, verts_;
  std::vector<uint8_t> flat_;
  std::vector<int8_t>* sign_ = nullptr;
  uint32_t stamp_base_ = 0;
};

// The paper's local test.
void growPaper(const Prepared& pr, uint32_t seed, uint32_t cell, uint32_t max_faces,
               std::vector<uint32_t>* owner, std::vector<int8_t>* sign, std::vector<uint32_t>* out,
               std::vector<std::pair<uint32_t, uint32_t>>* queue) {
  queue->clear();
  size_t count = 0;
  auto add = [&](uint32_t t, int8_t s) {
    (*owner)[t] = cell;
    (*sign)[t] = s;
    out->push_back(t);
    ++count;
    for (int k = 0; k < 3; ++k) {
      const uint32_t e = pr.edges->edgeOf(t, k);
      if (e == MeshConnectivity::kNone) continue;
      for (uint32_t slot : pr.edges->edgeSlots(e)) {  // ascending
        const uint32_t u = slot / 3;
        if (u != t && (*owner)[u] == kNone) queue->push_back({slot, 3 * t + k});
      }
    }
  };
  add(seed, 1);
  for (size_t head = 0; head < queue->size() && count < max_faces; ++head) {
    const uint32_t cand_slot = (*queue)[head].first, src_slot = (*queue)[head].second;
    const uint32_t t = cand_slot / 3, src = src_slot / 3;
    if ((*owner)[t] != kNone) continue;
    // Winding: the shared edge traversed in opposite directions keeps the orientation.
    const uint32_t b = pr.corner[3 * src + (src_slot % 3 + 1) % 3];
    const bool consistent = pr.corner[cand_slot] == b;
    const uint32_t far = pr.corner[3 * t + (cand_slot % 3 + 2) % 3];
    const double e = glm::dot(pr.normal(src), pr.p(far)) + pr.plane[4 * src + 3];
    // A lone seed's orientation is free (as in the strict mode): the first neighbour that joins
    // decides it, so concave regions grow cells too.
    if (count == 1 && e * (*sign)[src] > pr.tol) (*sign)[src] = int8_t(-(*sign)[src]);
    if (e * (*sign)[src] <= pr.tol) add(t, consistent ? (*sign)[src] : int8_t(-(*sign)[src]));
  }
}

// The cells of coincident triangles renumbered so that each class's copies follow its first
// triangle's cell, in triangle order (the order of equal depths), and cell_leader filled.
void groupCopies(const Prepared& pr, CellDecomposition* out) {
  const uint32_t T = uint32_t(pr.copy_of.size());
  std::vector<std::pair<uint32_t, uint32_t>> copies;  // (first triangle, copy), copies only
  for (uint32_t t = 0; t < T; ++t)
    if (pr.copy_of[t] != kNone && pr.copy_of[t] != t) copies.emplace_back(pr.copy_of[t], t);
  if (copies.empty()) return;
  std::sort(copies.begin(), copies.end());
  CellDecomposition grouped;
  grouped.mode = out->mode;
  grouped.cell_begin.push_back(0);
  grouped.triangle_order.reserve(out->triangle_order.size());
  const uint32_t C = out->cellCount();
  for (uint32_t c = 0; c < C; ++c) {
    const uint32_t b = out->cell_begin[c], e = out->cell_begin[c + 1];
    const uint32_t t = out->triangle_order[b];
    const bool single = e - b == 1;
    if (single && pr.copy_of[t] != kNone && pr.copy_of[t] != t) continue;  // with its first
    const uint32_t leader = grouped.cellCount();
    grouped.triangle_order.insert(grouped.triangle_order.end(), out->triangle_order.begin() + b,
                                  out->triangle_order.begin() + e);
    grouped.cell_begin.push_back(uint32_t(grouped.triangle_order.size()));
    grouped.cell_leader.push_back(leader);
    if (!single || pr.copy_of[t] != t) continue;
    auto it = std::lower_bound(copies.begin(), copies.end(), std::make_pair(t, uint32_t(0)));
    for (; it != copies.end() && it->first == t; ++it) {
      grouped.triangle_order.push_back(it->second);
      grouped.cell_begin.push_back(uint32_t(grouped.triangle_order.size()));
      grouped.cell_leader.push_back(leader);
    }
  }
  *out = std::move(grouped);
}

}  // namespace

CellDecomposition decomposeConvexCells(const MeshView& mesh, const DecomposeOptions& options) {
  if (options.max_cell_triangles == 0)
    throw Error("decomposeConvexCells: max_cell_triangles must be at least 1");
  if (mesh.triangle_count >= size_t(UINT32_MAX) || mesh.vertex_count >= size_t(UINT32_MAX))
    throw Error("decomposeConvexCells: mesh too large (" + std::to_string(mesh.triangle_count) +
                " triangles, " + std::to_string(mesh.vertex_count) + " vertices)");
  if (mesh.triangle_count > 0 && (!mesh.indices || !mesh.positions))
    throw Error("decomposeConvexCells: mesh has triangles but no index or position data");
  for (size_t i = 0; i < 3 * mesh.triangle_count; ++i)
    if (mesh.indices[i] >= mesh.vertex_count)
      throw Error("decomposeConvexCells: triangle " + std::to_string(i / 3) + " has vertex index " +
                  std::to_string(mesh.indices[i]) + " past the vertex count " +
                  std::to_string(mesh.vertex_count));

  CellDecomposition out;
  out.mode = options.mode;
  out.cell_begin.push_back(0);
  const size_t T = mesh.triangle_count;
  if (T == 0) return out;
  out.triangle_order.reserve(T);
  const Prepared pr = prepare(mesh);
  std::vector<uint32_t> owner(T, kNone);

  // The whole-mesh test costs vertices x faces when the mesh is convex: bounded so that 1 M
  // triangles still decompose in seconds (a larger convex mesh is grown in capped cells).
  const bool try_whole = options.mode == DecomposeMode::Strict && T > options.max_cell_triangles &&
                         double(mesh.vertex_count) * double(T) <= 2.5e9;
  if (try_whole && cells_detail::wholeMeshIsConvex(mesh)) {
    bool finite = true;
    for (uint32_t t = 0; t < T; ++t) finite = finite && !pr.bad[t];
    if (finite) {
      for (uint32_t t = 0; t < T; ++t) out.triangle_order.push_back(t);
      out.cell_begin.push_back(uint32_t(T));
      return out;
    }
  }
  const bool strict = options.mode == DecomposeMode::Strict;
  std::vector<int8_t> sign(T, 1);
  std::vector<uint8_t> flat;                         // strict: per cell, whether it is still flat
  std::vector<std::pair<uint32_t, uint32_t>> queue;  // paper: the growth queue
  {
    std::optional<StrictGrower> grower;  // released before the merger runs
    if (strict) grower.emplace(pr, T, mesh.vertex_count, options.max_cell_triangles);
    for (uint32_t seed = 0; seed < T; ++seed) {
      if (owner[seed] != kNone) continue;
      const uint32_t cell = out.cellCount();
      if (pr.alone[seed]) {
        owner[seed] = cell;
        out.triangle_order.push_back(seed);
        flat.push_back(0);  // never merged: it has no edges
      } else if (strict) {
        flat.push_back(grower->grow(seed, cell, &owner, &out.triangle_order, &sign) ? 1 : 0);
      } else {
        growPaper(pr, seed, cell, options.max_cell_triangles, &owner, &sign, &out.triangle_order,
                  &queue);
      }
      out.cell_begin.push_back(uint32_t(out.triangle_order.size()));
    }
  }
  if (strict) CellMerger(pr, mesh.vertex_count, options.max_cell_triangles).run(&out, &sign, flat);
  groupCopies(pr, &out);
  return out;
}

}  // namespace strata
