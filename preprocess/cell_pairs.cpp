// The uniform grid over the mesh and the separation of every pair of convex cells whose
// (tolerance-inflated) bounding boxes overlap (methods/convex-cells.md, preprocessing step 2).
//
// A separating plane of two cells has all of a's vertices on its negative side and all of b's on
// its positive side, within the tolerance. Candidates, each checked against every vertex of both
// cells with the plane exactly as stored (float normal and offset) before it is accepted:
//  - cells sharing two distant vertices: every separating plane contains (within the tolerance)
//    the line through them, and the one-parameter family of planes through that line is solved
//    exactly (each vertex forbids an arc of angles; a gap between the arcs is a plane);
//  - cells sharing one vertex: planes through it, the normal from the minimum-norm point (GJK)
//    of the hull of the unit directions from that vertex (a's, and b's mirrored);
//  - disjoint cells: the centroid difference, then the minimum-norm point (GJK) of
//    conv(a) - conv(b), the maximum-margin direction;
//  - the face planes of either cell that best face the other (a bounded number).
#include "preprocess/convex_cells.h"
#include "preprocess/core/threads.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <thread>

#include "preprocess/cell_convexity.h"
#include "preprocess/scene/scene.h"

namespace strata {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr int kFaceCandidates = 8;  // face planes tried per side
constexpr int kMinNormSteps = 64;   // GJK iterations per pair

struct CellData {
  std::vector<uint32_t> vbegin;  // per cell: its unique vertices vid/vpos[vbegin[c] .. vbegin[c+1])
  std::vector<uint32_t> vid;     // welded vertex ids, sorted per cell
  std::vector<glm::dvec3> vpos;
  std::vector<glm::dvec3> lo, hi, centroid;
  std::vector<uint8_t> valid;  // all vertices finite
};

class Separator {
 public:
  Separator(const MeshView& mesh, const CellDecomposition& cells, const CellData& cd, double tol)
      : mesh_(mesh), cells_(cells), cd_(cd), tol_(tol) {}

  bool separate(uint32_t a, uint32_t b, CellPlane* plane) {
    a_ = a;
    b_ = b;
    A_ = &cd_.vpos[cd_.vbegin[a]];
    na_ = cd_.vbegin[a + 1] - cd_.vbegin[a];
    B_ = &cd_.vpos[cd_.vbegin[b]];
    nb_ = cd_.vbegin[b + 1] - cd_.vbegin[b];
    // Shared vertices (same position).
    shared_.clear();
    const uint32_t* ia = &cd_.vid[cd_.vbegin[a]];
    const uint32_t* ib = &cd_.vid[cd_.vbegin[b]];
    for (size_t i = 0, j = 0; i < na_ && j < nb_;) {
      if (ia[i] < ib[j]) {
        ++i;
      } else if (ib[j] < ia[i]) {
        ++j;
      } else {
        shared_.push_back(A_[i]);
        ++i;
        ++j;
      }
    }
    const glm::dvec3 ca = cd_.centroid[a], cb = cd_.centroid[b];
    if (!shared_.empty()) {
      const glm::dvec3 p0 = shared_[0];
      glm::dvec3 p1 = p0;
      double far = 0.0;
      for (const glm::dvec3& p : shared_) {
        const double l = glm::length(p - p0);
        if (l > far) far = l, p1 = p;
      }
      if (far > 1000.0 * tol_) {
        // Every separating plane contains the line p0 p1 (within the tolerance): exhaustive.
        if (edgeFamily(p0, p1, plane)) return true;
        return faceCandidates(ca, cb, plane);
      }
      if (coneSearch(p0, plane)) return true;
      return faceCandidates(ca, cb, plane);
    }
    if (tryDirection(cb - ca, plane)) return true;
    if (diffSearch(ca - cb, plane)) return true;
    return faceCandidates(ca, cb, plane);
  }

 private:
  // Whether some plane with (about) normal n separates the cells: the normal is rounded to
  // float, the offset chosen inside the allowed interval and rounded, and every vertex checked
  // against the plane as stored.
  bool tryDirection(const glm::dvec3& n_in, CellPlane* plane) {
    const double len = glm::length(n_in);
    if (!(len > 0.0) || !std::isfinite(len)) return false;
    glm::vec3 nf = glm::vec3(n_in / len);
    const float lf = glm::length(nf);
    if (!(lf > 0.0f)) return false;
    nf /= lf;
    const glm::dvec3 n(nf);
    double amin = 1e300, amax = -1e300, bmin = 1e300, bmax = -1e300;
    for (size_t i = 0; i < na_; ++i) {
      const double e = glm::dot(n, A_[i]);
      amin = std::min(amin, e);
      amax = std::max(amax, e);
    }
    for (size_t i = 0; i < nb_; ++i) {
      const double e = glm::dot(n, B_[i]);
      bmin = std::min(bmin, e);
      bmax = std::max(bmax, e);
    }
    // a negative, b positive: d in [-tol - bmin, tol - amax].
    auto pick = [&](double lo, double hi, float* d) {
      if (lo > hi) return false;
      float f = float(0.5 * (lo + hi));
      if (double(f) < lo) f = std::nextafter(f, std::numeric_limits<float>::infinity());
      if (double(f) > hi) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
      if (double(f) < lo || double(f) > hi) return false;
      *d = f;
      return true;
    };
    float d;
    if (pick(-tol_ - bmin, tol_ - amax, &d)) {
      plane->n = nf;
      plane->d = d;
      return true;
    }
    // The reverse orientation, normal -n: d in [bmax - tol, tol + amin].
    if (pick(bmax - tol_, tol_ + amin, &d)) {
      plane->n = -nf;
      plane->d = d;
      return true;
    }
    return false;
  }

  // Planes containing the line p0 p1: normal n(t) = cos t u + sin t w. A point q (a's vertices
  // relative to p0, and b's mirrored) needs n(t).q <= tol, which forbids the open arc of half
  // width acos(tol / rho) around its angle. A gap between the forbidden arcs is a plane.
  bool edgeFamily(const glm::dvec3& p0, const glm::dvec3& p1, CellPlane* plane) {
    const glm::dvec3 e = glm::normalize(p1 - p0);
    glm::dvec3 u = std::fabs(e.x) < 0.6 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    u = glm::normalize(u - e * glm::dot(e, u));
    const glm::dvec3 w = glm::cross(e, u);
    arcs_.clear();
    auto add = [&](const glm::dvec3& q) {
      const double qu = glm::dot(q, u), qw = glm::dot(q, w);
      const double rho = std::sqrt(qu * qu + qw * qw);
      if (rho <= tol_) return;
      const double h = std::acos(std::min(1.0, tol_ / rho));
      double s = std::atan2(qw, qu) - h;
      if (s < 0) s += 2 * kPi;
      if (s >= 2 * kPi) s -= 2 * kPi;
      arcs_.push_back({s, s + 2 * h});
    };
    for (size_t i = 0; i < na_; ++i) add(A_[i] - p0);
    for (size_t i = 0; i < nb_; ++i) add(p0 - B_[i]);
    if (arcs_.empty()) return tryDirection(u, plane);
    std::sort(arcs_.begin(), arcs_.end());
    // Sweep twice around the circle; gaps of the second round are true gaps (every arc that
    // wraps past 2 pi has been seen by then).
    const size_t m = arcs_.size();
    double end = arcs_[0].first;
    double best_len = 0.0, best_mid = 0.0;
    for (size_t k = 0; k < 2 * m; ++k) {
      const double off = k < m ? 0.0 : 2 * kPi;
      const double s = arcs_[k % m].first + off, t = arcs_[k % m].second + off;
      if (k >= m && s > end && s - end > best_len) {
        best_len = s - end;
        best_mid = 0.5 * (s + end);
      }
      end = std::max(end, t);
    }
    // The gap that closes the second round.
    const double close = arcs_[0].first + 4 * kPi;
    if (close > end && close - end > best_len) {
      best_len = close - end;
      best_mid = 0.5 * (close + end);
    }
    if (best_len <= 0.0) return false;
    return tryDirection(std::cos(best_mid) * u + std::sin(best_mid) * w, plane);
  }

  // Planes through p (a vertex of both cells): the minimum-norm point x of the hull of the unit
  // directions q (a's vertices from p, and b's mirrored); n = -x has n.q <= 0 for every q when x
  // is not the origin.
  bool coneSearch(const glm::dvec3& p, CellPlane* plane) {
    dirs_.clear();
    for (size_t i = 0; i < na_; ++i) {
      const glm::dvec3 q = A_[i] - p;
      const double l = glm::length(q);
      if (l > tol_) dirs_.push_back(q / l);
    }
    for (size_t i = 0; i < nb_; ++i) {
      const glm::dvec3 q = p - B_[i];
      const double l = glm::length(q);
      if (l > tol_) dirs_.push_back(q / l);
    }
    if (dirs_.empty()) return false;
    auto support = [&](const glm::dvec3& x) {
      size_t arg = 0;
      double lo = glm::dot(x, dirs_[0]);
      for (size_t i = 1; i < dirs_.size(); ++i) {
        const double e = glm::dot(x, dirs_[i]);
        if (e < lo) lo = e, arg = i;
      }
      return dirs_[arg];
    };
    // Accept as soon as -x faces away from every direction (a plane through p); tryDirection
    // then checks the real distances with the tolerance.
    auto good = [&](const glm::dvec3& x, const glm::dvec3& s) {
      return glm::dot(x, s) >= -1e-9 * glm::length(x) && tryDirection(-x, plane);
    };
    return minNorm(dirs_[0], support, good) || tryDirection(-lastX_, plane);
  }

  // Disjoint cells: the minimum-norm point x of conv(a) - conv(b); n = -x separates when the
  // minimum over a of x.a is at least the maximum over b of x.b.
  bool diffSearch(const glm::dvec3& start, CellPlane* plane) {
    auto support = [&](const glm::dvec3& x) {
      size_t ia = 0, ib = 0;
      double amin = 1e300, bmax = -1e300;
      for (size_t i = 0; i < na_; ++i) {
        const double e = glm::dot(x, A_[i]);
        if (e < amin) amin = e, ia = i;
      }
      for (size_t i = 0; i < nb_; ++i) {
        const double e = glm::dot(x, B_[i]);
        if (e > bmax) bmax = e, ib = i;
      }
      return A_[ia] - B_[ib];
    };
    auto good = [&](const glm::dvec3& x, const glm::dvec3& s) {
      return glm::dot(x, s) >= -2.0 * tol_ * glm::length(x) && tryDirection(-x, plane);
    };
    return minNorm(start, support, good);
  }

  // GJK: the point of minimum norm of a convex hull given by its support function (the hull
  // point minimising x.z), kept as the closest point of a simplex of at most 4 support points.
  // Stops with true when good(x, support(x)) holds, false at convergence or at the origin.
  template <class Support, class Good>
  bool minNorm(const glm::dvec3& start, Support support, Good good) {
    glm::dvec3 simplex[4];
    int k = 1;
    simplex[0] = start;
    glm::dvec3 x = start;
    lastX_ = x;
    for (int it = 0; it < kMinNormSteps; ++it) {
      const double xx = glm::dot(x, x);
      if (xx <= 1e-28) return false;
      const glm::dvec3 s = support(x);
      if (good(x, s)) return true;
      if (xx - glm::dot(x, s) <= 1e-12 * xx) return false;  // converged: x is the minimum
      bool repeat = false;
      for (int i = 0; i < k; ++i) repeat = repeat || simplex[i] == s;
      if (repeat) return false;
      simplex[k++] = s;
      x = closestOnSimplex(simplex, &k);
      lastX_ = x;
      if (k == 4) return false;  // the origin is inside a tetrahedron of the hull
    }
    return false;
  }

  // The point of minimum norm of the simplex's hull; the simplex is reduced to the points it
  // needs. Brute force over the (at most 15) sub-simplices: robust, and cheap next to support().
  static glm::dvec3 closestOnSimplex(glm::dvec3* p, int* count) {
    const int n = *count;
    double best = std::numeric_limits<double>::max();
    glm::dvec3 best_x = p[0];
    int best_mask = 1;
    for (int mask = 1; mask < (1 << n); ++mask) {
      int idx[4], m = 0;
      for (int i = 0; i < n; ++i)
        if (mask & (1 << i)) idx[m++] = i;
      // Minimise |p0 + sum mu_j (pj - p0)|: normal equations of size m - 1.
      double lambda[4] = {1, 0, 0, 0};
      if (m > 1) {
        double g[3][4] = {};
        glm::dvec3 d[3];
        for (int j = 1; j < m; ++j) d[j - 1] = p[idx[j]] - p[idx[0]];
        for (int r = 0; r < m - 1; ++r) {
          for (int c = 0; c < m - 1; ++c) g[r][c] = glm::dot(d[r], d[c]);
          g[r][m - 1] = -glm::dot(d[r], p[idx[0]]);
        }
        // Gaussian elimination with partial pivoting.
        bool singular = false;
        const int sz = m - 1;
        for (int c = 0; c < sz && !singular; ++c) {
          int piv = c;
          for (int r = c + 1; r < sz; ++r)
            if (std::fabs(g[r][c]) > std::fabs(g[piv][c])) piv = r;
          if (std::fabs(g[piv][c]) <= 1e-30 * (1.0 + std::fabs(g[0][0]))) singular = true;
          if (singular) break;
          for (int c2 = 0; c2 <= sz; ++c2) std::swap(g[c][c2], g[piv][c2]);
          for (int r = 0; r < sz; ++r) {
            if (r == c) continue;
            const double f = g[r][c] / g[c][c];
            for (int c2 = c; c2 <= sz; ++c2) g[r][c2] -= f * g[c][c2];
          }
        }
        if (singular) continue;
        double sum = 0.0;
        for (int j = 1; j < m; ++j) {
          lambda[j] = g[j - 1][sz] / g[j - 1][j - 1];
          sum += lambda[j];
        }
        lambda[0] = 1.0 - sum;
        bool inside = true;
        for (int j = 0; j < m; ++j) inside = inside && lambda[j] >= -1e-12;
        if (!inside) continue;
      }
      glm::dvec3 x(0.0);
      for (int j = 0; j < m; ++j) x += lambda[j] * p[idx[j]];
      const double xx = glm::dot(x, x);
      if (xx < best) best = xx, best_x = x, best_mask = mask;
    }
    int m = 0;
    for (int i = 0; i < n; ++i)
      if (best_mask & (1 << i)) p[m++] = p[i];
    *count = m;
    return best_x;
  }

  // The face planes of each cell that best face the other cell.
  bool faceCandidates(const glm::dvec3& ca, const glm::dvec3& cb, CellPlane* plane) {
    for (int side = 0; side < 2; ++side) {
      const uint32_t c = side == 0 ? a_ : b_;
      const glm::dvec3 from = side == 0 ? ca : cb, to = side == 0 ? cb : ca;
      const glm::dvec3 dir = to - from;
      scored_.clear();
      for (uint32_t i = cells_.cell_begin[c]; i < cells_.cell_begin[c + 1]; ++i) {
        const uint32_t t = cells_.triangle_order[i];
        glm::dvec3 p[3];
        for (int k = 0; k < 3; ++k)
          p[k] = glm::dvec3(mesh_.positions[mesh_.indices[3 * size_t(t) + k]]);
        glm::dvec3 n = glm::cross(p[1] - p[0], p[2] - p[0]);
        const double l = glm::length(n);
        if (!(l > 0.0)) continue;
        n /= l;
        // Outward: away from the cell's centroid (behind every face of a convex cell).
        if (glm::dot(n, (p[0] + p[1] + p[2]) / 3.0 - from) < 0) n = -n;
        scored_.push_back({-glm::dot(n, dir), n});
      }
      const size_t k = std::min<size_t>(kFaceCandidates, scored_.size());
      std::partial_sort(scored_.begin(), scored_.begin() + k, scored_.end(),
                        [](const auto& x, const auto& y) { return x.first < y.first; });
      for (size_t i = 0; i < k; ++i)
        if (tryDirection(scored_[i].second, plane)) return true;
    }
    return false;
  }

  const MeshView& mesh_;
  const CellDecomposition& cells_;
  const CellData& cd_;
  const double tol_;
  uint32_t a_ = 0, b_ = 0;
  const glm::dvec3* A_ = nullptr;
  const glm::dvec3* B_ = nullptr;
  size_t na_ = 0, nb_ = 0;
  std::vector<glm::dvec3> shared_, dirs_;
  glm::dvec3 lastX_{0.0};
  std::vector<std::pair<double, double>> arcs_;
  std::vector<std::pair<double, glm::dvec3>> scored_;
};

CellData gatherCells(const MeshView& mesh, const CellDecomposition& cells) {
  const uint32_t C = cells.cellCount();
  std::vector<uint32_t> weld;
  cells_detail::weldVertices(mesh, &weld);
  CellData cd;
  cd.vbegin.reserve(C + 1);
  cd.vbegin.push_back(0);
  cd.lo.resize(C);
  cd.hi.resize(C);
  cd.centroid.resize(C);
  cd.valid.assign(C, 1);
  cd.vid.reserve(cells.triangle_order.size() * 2);
  std::vector<uint32_t> ids;
  for (uint32_t c = 0; c < C; ++c) {
    ids.clear();
    for (uint32_t i = cells.cell_begin[c]; i < cells.cell_begin[c + 1]; ++i) {
      const uint32_t t = cells.triangle_order[i];
      for (int k = 0; k < 3; ++k) ids.push_back(weld[mesh.indices[3 * size_t(t) + k]]);
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    glm::dvec3 lo(1e300), hi(-1e300), sum(0.0);
    for (uint32_t v : ids) {
      const glm::vec3& p = mesh.positions[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) cd.valid[c] = 0;
      const glm::dvec3 q(p);
      cd.vid.push_back(v);
      cd.vpos.push_back(q);
      lo = glm::min(lo, q);
      hi = glm::max(hi, q);
      sum += q;
    }
    cd.vbegin.push_back(uint32_t(cd.vid.size()));
    cd.lo[c] = lo;
    cd.hi[c] = hi;
    cd.centroid[c] = ids.empty() ? glm::dvec3(0.0) : sum / double(ids.size());
  }
  return cd;
}

}  // namespace

uint64_t cellPairBound(uint32_t cells) { return uint64_t(cells) * 64 + (uint64_t(1) << 20); }

bool findCellPairs(const MeshView& mesh, const CellDecomposition& cells, CellGrid* grid,
                   std::vector<CellPair>* pairs, uint64_t max_pairs) {
  const uint32_t C = cells.cellCount();
  if (!cells.cell_begin.empty() &&
      (cells.cell_begin.front() != 0 || cells.cell_begin.back() != cells.triangle_order.size()))
    throw Error("findCellPairs: cell offsets do not cover the triangle order");
  for (uint32_t c = 0; c < C; ++c)
    if (cells.cell_begin[c] > cells.cell_begin[c + 1])
      throw Error("findCellPairs: cell offsets are not increasing at cell " + std::to_string(c));
  if (!cells.cell_leader.empty() && cells.cell_leader.size() != C)
    throw Error("findCellPairs: cell_leader does not list every cell");
  for (uint32_t t : cells.triangle_order)
    if (t >= mesh.triangle_count)
      throw Error("findCellPairs: triangle " + std::to_string(t) + " past the mesh's " +
                  std::to_string(mesh.triangle_count) + " triangles");
  for (size_t i = 0; i < 3 * mesh.triangle_count; ++i)
    if (mesh.indices[i] >= mesh.vertex_count)
      throw Error("findCellPairs: triangle " + std::to_string(i / 3) + " has vertex index " +
                  std::to_string(mesh.indices[i]) + " past the vertex count " +
                  std::to_string(mesh.vertex_count));

  *grid = CellGrid{};
  pairs->clear();
  const double tol = cells_detail::cellTolerance(mesh, nullptr);
  const CellData cd = gatherCells(mesh, cells);

  // The grid over the boxes of the cells (cells with a non-finite vertex draw nothing and take
  // no part in ordering; copies of a triangle are ordered with their first cell).
  const auto paired = [&](uint32_t c) {
    return cd.valid[c] && cd.vbegin[c] != cd.vbegin[c + 1] && !cells.isCopy(c);
  };
  glm::dvec3 lo(1e300), hi(-1e300);
  size_t n_valid = 0;
  for (uint32_t c = 0; c < C; ++c) {
    if (!paired(c)) continue;
    lo = glm::min(lo, cd.lo[c]);
    hi = glm::max(hi, cd.hi[c]);
    ++n_valid;
  }
  if (n_valid == 0) return true;
  if (max_pairs == 0) max_pairs = cellPairBound(C);
  lo -= glm::dvec3(tol);
  hi += glm::dvec3(tol);
  const glm::dvec3 ext = hi - lo;
  const double emax = std::max({ext.x, ext.y, ext.z});
  glm::ivec3 dims(1);
  if (emax > 0.0) {
    double vol = 1.0;
    int active = 0;
    for (int k = 0; k < 3; ++k)
      if (ext[k] > 1e-3 * emax) vol *= ext[k], ++active;
    const double h = std::pow(vol / double(n_valid), 1.0 / double(active));
    for (int k = 0; k < 3; ++k)
      if (ext[k] > 1e-3 * emax) dims[k] = int(std::clamp(std::round(ext[k] / h), 1.0, 128.0));
  }
  grid->dims = dims;
  grid->origin = glm::vec3(lo);
  for (int k = 0; k < 3; ++k) grid->cell_size[k] = ext[k] > 0.0 ? float(ext[k] / dims[k]) : 1.0f;
  const glm::dvec3 origin(grid->origin), size(grid->cell_size);

  // Bin the inflated boxes.
  std::vector<glm::ivec3> r0(C), r1(C);
  const size_t G = size_t(dims.x) * dims.y * dims.z;
  std::vector<uint32_t> gbegin(G + 1, 0);
  auto cellIndex = [&](double x, int k) {
    return std::clamp(int(std::floor((x - origin[k]) / size[k])), 0, dims[k] - 1);
  };
  // The entries (a cell in every grid cell its box spans) are bounded with the pairs: boxes
  // that span much of the grid are the ones that overlap one another.
  uint64_t entries = 0;
  for (uint32_t c = 0; c < C; ++c) {
    if (!paired(c)) continue;
    for (int k = 0; k < 3; ++k) {
      r0[c][k] = cellIndex(cd.lo[c][k] - tol, k);
      r1[c][k] = cellIndex(cd.hi[c][k] + tol, k);
    }
    const glm::ivec3 span = r1[c] - r0[c] + 1;
    entries += uint64_t(span.x) * uint64_t(span.y) * uint64_t(span.z);
  }
  if (entries > 16 * max_pairs || entries >= UINT32_MAX) return false;
  for (uint32_t c = 0; c < C; ++c) {
    if (!paired(c)) continue;
    for (int z = r0[c].z; z <= r1[c].z; ++z)
      for (int y = r0[c].y; y <= r1[c].y; ++y)
        for (int x = r0[c].x; x <= r1[c].x; ++x)
          ++gbegin[(size_t(z) * dims.y + y) * dims.x + x + 1];
  }
  for (size_t g = 0; g < G; ++g) gbegin[g + 1] += gbegin[g];
  std::vector<uint32_t> gcells(gbegin[G]);
  {
    std::vector<uint32_t> fill(gbegin.begin(), gbegin.end() - 1);
    for (uint32_t c = 0; c < C; ++c) {
      if (!paired(c)) continue;
      for (int z = r0[c].z; z <= r1[c].z; ++z)
        for (int y = r0[c].y; y <= r1[c].y; ++y)
          for (int x = r0[c].x; x <= r1[c].x; ++x)
            gcells[fill[(size_t(z) * dims.y + y) * dims.x + x]++] = c;
    }
  }

  // Pairs with overlapping inflated boxes, each reported by the first grid cell they share.
  std::vector<uint64_t> keys;
  for (int z = 0; z < dims.z; ++z)
    for (int y = 0; y < dims.y; ++y)
      for (int x = 0; x < dims.x; ++x) {
        const size_t g = (size_t(z) * dims.y + y) * dims.x + x;
        const glm::ivec3 here(x, y, z);
        for (uint32_t i = gbegin[g]; i < gbegin[g + 1]; ++i) {
          const uint32_t a = gcells[i];
          for (uint32_t j = i + 1; j < gbegin[g + 1]; ++j) {
            const uint32_t b = gcells[j];
            if (glm::max(r0[a], r0[b]) != here) continue;
            bool overlap = true;
            for (int k = 0; k < 3 && overlap; ++k)
              overlap =
                  cd.lo[a][k] - tol <= cd.hi[b][k] + tol && cd.lo[b][k] - tol <= cd.hi[a][k] + tol;
            if (!overlap) continue;
            keys.push_back((uint64_t(std::min(a, b)) << 32) | std::max(a, b));
            if (keys.size() > max_pairs) return false;
          }
        }
      }
  std::sort(keys.begin(), keys.end());
  pairs->resize(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) {
    (*pairs)[i].a = uint32_t(keys[i] >> 32);
    (*pairs)[i].b = uint32_t(keys[i]);
  }
  keys = {};

  // Separate, in parallel over blocks of pairs (each pair's result is independent of the rest).
  const size_t n_pairs = pairs->size();
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const unsigned n_threads = unsigned(std::min<size_t>(std::min(hw, 16u), n_pairs / 256 + 1));
  std::atomic<size_t> next{0};
  auto work = [&]() {
    Separator sep(mesh, cells, cd, tol);
    for (;;) {
      const size_t begin = next.fetch_add(256);
      if (begin >= n_pairs) break;
      const size_t end = std::min(n_pairs, begin + 256);
      for (size_t i = begin; i < end; ++i) {
        CellPair& p = (*pairs)[i];
        p.separable = sep.separate(p.a, p.b, &p.plane);
        if (!p.separable) p.plane = CellPlane{};
      }
    }
  };
  runOnThreads(n_threads, [&](unsigned) { work(); });
  return true;
}

}  // namespace strata
