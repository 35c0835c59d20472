// The cells order's pixel masks (docs/cells.md, "Which pairs need an order"): a cell's
// triangles rasterized on the host into 64-bit masks of 8x8 screen tiles, every pixel centre
// within the slack of a triangle. Inline: the projector calls them per triangle. Internal to the
// order's stages.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "engine/cells/cell_order.h"
#include "kernels/strata_shared.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace strata::cellorder {

// Internal linkage, as for code of the one file that includes this (cell_order.cpp): the
// compiler then inlines the per-triangle steps as it does a file's own static functions.
namespace {

// floor and ceil of a pixel coordinate, saturated (strata_shared.h).
inline int floorPixel(float v) { return st_cover_floor(v); }
inline int ceilPixel(float v) { return st_cover_ceil(v); }

struct CoverageSink {
  int tx0, ty0, tiles_w;           // the cell's tile rectangle (origin and width)
  uint64_t* masks;                 // per tile of that rectangle, zero before the cell
  std::vector<uint32_t>* touched;  // the tiles of the rectangle made non-zero, in order

  void orTile(int tx, int ty, uint64_t m) {
    const uint32_t i = uint32_t(ty - ty0) * uint32_t(tiles_w) + uint32_t(tx - tx0);
    if (m && !masks[i]) touched->push_back(i);
    masks[i] |= m;
  }
  // Pixels x0..x1, y0..y1 of one tile.
  void setRect(int x0, int y0, int x1, int y1) {
    const uint64_t row = ((uint64_t(2) << (x1 & 7)) - 1) & ~((uint64_t(1) << (x0 & 7)) - 1);
    uint64_t m = 0;
    for (int y = y0 & 7; y <= (y1 & 7); ++y) m |= row << (y * 8);
    orTile(x0 >> 3, y0 >> 3, m);
  }
};

// A projected triangle set up for coverTriangle and coverTriangleRows (StCoverEdges).
using CoverEdges = StCoverEdges;

// Whether the centre (x0 + xf, y0 + yf) is inside every edge of t (st_cover_inside).
inline bool centreInside(const CoverEdges& t, float xf, float yf) {
  return st_cover_inside(&t, xf, yf) != 0;
}

#if defined(__SSE2__)
// centreInside for four centres of a row: ex * xf of columns x .. x + 3 (fourColumns), as bits.
struct FourColumns {
  __m128 ax[3];
  FourColumns(const CoverEdges& t, int x) {
    const __m128 xf = _mm_add_ps(_mm_set1_ps(float(x - t.x0)), _mm_setr_ps(0.0f, 1.0f, 2.0f, 3.0f));
    for (int i = 0; i < 3; ++i) ax[i] = _mm_mul_ps(_mm_set1_ps(t.ex[i]), xf);
  }
  uint32_t inside(const CoverEdges& t, float yf) const {
    const __m128 zero = _mm_setzero_ps();
    __m128 in = _mm_cmpge_ps(_mm_add_ps(ax[0], _mm_set1_ps(t.ey[0] * yf + t.ec[0])), zero);
    in = _mm_and_ps(in, _mm_cmpge_ps(_mm_add_ps(ax[1], _mm_set1_ps(t.ey[1] * yf + t.ec[1])), zero));
    in = _mm_and_ps(in, _mm_cmpge_ps(_mm_add_ps(ax[2], _mm_set1_ps(t.ey[2] * yf + t.ec[2])), zero));
    return uint32_t(_mm_movemask_ps(in));
  }
};
#endif

// The centres x = xa..xb, y = ya..yb of one tile (at most 8 x 8) inside every edge of t, as
// bits (y & 7) * 8 + (x & 7).
inline uint64_t tileCoverage(const CoverEdges& t, int xa, int xb, int ya, int yb) {
  uint64_t mask = 0;
#if defined(__SSE2__)
  const int first = xa & ~7;  // the tile's eight columns, in two rows of four lanes
  const FourColumns lo(t, first), hi(t, first + 4);
  const uint32_t columns = ((2u << (xb - first)) - 1u) & ~((1u << (xa - first)) - 1u);
  for (int y = ya; y <= yb; ++y) {
    const float yf = float(y - t.y0);
    const uint32_t bits = lo.inside(t, yf) | (hi.inside(t, yf) << 4);
    mask |= uint64_t(bits & columns) << ((y & 7) * 8);
  }
#else
  for (int y = ya; y <= yb; ++y)
    for (int x = xa; x <= xb; ++x)
      if (centreInside(t, float(x - t.x0), float(y - t.y0)))
        mask |= uint64_t(1) << ((y & 7) * 8 + (x & 7));
#endif
  return mask;
}

// Sets up triangle (a, b, d) so that its edge functions mark the centres (x + 0.5, y + 0.5) of
// the clipped pixel rectangle that lie within ST_COVER_SLACK of it. The edge functions are left
// unnormalised, each widened by the slack times its L1 length (at least the Euclidean one), so
// no square root is taken; a triangle with no area covers the centres next to its segment
// (within its bounds). false: the triangle is within the slack of no centre of the image.
inline bool setupCover(glm::vec2 a, glm::vec2 b, glm::vec2 d, int width, int height,
                       CoverEdges& t) {
  // A small triangle near the image (most of them) in float, as the device sets it up too.
  const int kind = st_cover_setup(a.x, a.y, b.x, b.y, d.x, d.y, width, height, &t);
  if (kind != ST_COVER_WIDE) return kind == ST_COVER_SET_UP;
  // Large or far off: set up in double precision (corners far off the image would lose the
  // slack to rounding).
  const glm::dvec2 da(a), db(b), dd(d);
  const double area = (db.x - da.x) * (dd.y - da.y) - (dd.x - da.x) * (db.y - da.y);
  const glm::dvec2 p[3] = {da, area < 0.0 ? dd : db, area < 0.0 ? db : dd};
  const glm::dvec2 origin(double(t.x0) + 0.5, double(t.y0) + 0.5);
  for (int i = 0; i < 3; ++i) {
    const glm::dvec2 e = p[(i + 1) % 3] - p[i];
    t.ex[i] = float(-e.y);
    t.ey[i] = float(e.x);
    t.ec[i] = float(-e.y * (origin.x - p[i].x) + e.x * (origin.y - p[i].y) +
                    ST_COVER_SLACK * (std::fabs(e.x) + std::fabs(e.y)));
  }
  return true;
}

#if defined(__SSE2__)
// setupCover for four triangles at once (corners a, b, d of lane i in a*[i], b*[i], d*[i]):
// lane i of the result is set up in t[i] when bit i of the returned `done` is set; bit i of
// `empty` says the lane covers no centre; a lane in neither (a large triangle, or one far off
// the image) is left to setupCover. Every value is rounded as setupCover's float path rounds
// it (the same operations in the same order; std::min(a, b) is _mm_min_ps(b, a)), so the
// coverage is bit for bit the same.
struct CoverSetup4 {
  uint32_t done = 0, empty = 0;
};
inline __m128i maxZero(__m128i v) {
  return _mm_and_si128(v, _mm_cmpgt_epi32(v, _mm_setzero_si128()));
}
inline __m128i minInt(__m128i v, __m128i limit) {
  const __m128i over = _mm_cmpgt_epi32(v, limit);
  return _mm_or_si128(_mm_and_si128(over, limit), _mm_andnot_si128(over, v));
}
// saturatePixel, ceilPixel and floorPixel in four lanes (NaN saturates low, as there).
inline __m128 saturatePixel4(__m128 v) {
  return _mm_min_ps(_mm_max_ps(v, _mm_set1_ps(-1.0e7f)), _mm_set1_ps(1.0e7f));
}
inline __m128i ceilPixel4(__m128 v) {
  v = saturatePixel4(v);
  const __m128i i = _mm_cvttps_epi32(v);
  return _mm_sub_epi32(i, _mm_castps_si128(_mm_cmplt_ps(_mm_cvtepi32_ps(i), v)));
}
inline __m128i floorPixel4(__m128 v) {
  v = saturatePixel4(v);
  const __m128i i = _mm_cvttps_epi32(v);
  return _mm_add_epi32(i, _mm_castps_si128(_mm_cmpgt_ps(_mm_cvtepi32_ps(i), v)));
}
inline __m128 absPs(__m128 v) { return _mm_andnot_ps(_mm_set1_ps(-0.0f), v); }
inline __m128 selectPs(__m128 mask, __m128 a, __m128 b) {  // mask ? a : b
  return _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b));
}

inline CoverSetup4 setupCover4(const float* ax, const float* ay, const float* bx, const float* by,
                               const float* dx, const float* dy, int width, int height,
                               CoverEdges* t) {
  const __m128 Ax = _mm_loadu_ps(ax), Ay = _mm_loadu_ps(ay), Bx = _mm_loadu_ps(bx),
               By = _mm_loadu_ps(by), Dx = _mm_loadu_ps(dx), Dy = _mm_loadu_ps(dy);
  const __m128 fx0 = _mm_min_ps(_mm_min_ps(Dx, Bx), Ax), fx1 = _mm_max_ps(_mm_max_ps(Dx, Bx), Ax);
  const __m128 fy0 = _mm_min_ps(_mm_min_ps(Dy, By), Ay), fy1 = _mm_max_ps(_mm_max_ps(Dy, By), Ay);
  const __m128 half = _mm_set1_ps(0.5f), slack = _mm_set1_ps(ST_COVER_SLACK);
  const __m128i x0 = maxZero(ceilPixel4(_mm_sub_ps(_mm_sub_ps(fx0, half), slack)));
  const __m128i x1 =
      minInt(floorPixel4(_mm_add_ps(_mm_sub_ps(fx1, half), slack)), _mm_set1_epi32(width - 1));
  const __m128i y0 = maxZero(ceilPixel4(_mm_sub_ps(_mm_sub_ps(fy0, half), slack)));
  const __m128i y1 =
      minInt(floorPixel4(_mm_add_ps(_mm_sub_ps(fy1, half), slack)), _mm_set1_epi32(height - 1));
  CoverSetup4 r;
  r.empty = uint32_t(_mm_movemask_ps(
      _mm_castsi128_ps(_mm_or_si128(_mm_cmpgt_epi32(x0, x1), _mm_cmpgt_epi32(y0, y1)))));
  const __m128 span = _mm_set1_ps(ST_COVER_FLOAT_SPAN), reach = _mm_set1_ps(ST_COVER_FLOAT_REACH);
  const __m128 small =
      _mm_and_ps(_mm_and_ps(_mm_cmple_ps(_mm_sub_ps(fx1, fx0), span),
                            _mm_cmple_ps(_mm_sub_ps(fy1, fy0), span)),
                 _mm_and_ps(_mm_cmplt_ps(absPs(fx0), reach), _mm_cmplt_ps(absPs(fy0), reach)));
  r.done = uint32_t(_mm_movemask_ps(small)) & ~r.empty;
  if (!r.done) return r;
  const __m128 ox = _mm_add_ps(_mm_cvtepi32_ps(x0), half),
               oy = _mm_add_ps(_mm_cvtepi32_ps(y0), half);
  const __m128 rax = _mm_sub_ps(Ax, ox), ray = _mm_sub_ps(Ay, oy);
  const __m128 rbx = _mm_sub_ps(Bx, ox), rby = _mm_sub_ps(By, oy);
  const __m128 rdx = _mm_sub_ps(Dx, ox), rdy = _mm_sub_ps(Dy, oy);
  const __m128 area = _mm_sub_ps(_mm_mul_ps(_mm_sub_ps(rbx, rax), _mm_sub_ps(rdy, ray)),
                                 _mm_mul_ps(_mm_sub_ps(rdx, rax), _mm_sub_ps(rby, ray)));
  const __m128 flip = _mm_cmplt_ps(area, _mm_setzero_ps());
  const __m128 px[3] = {rax, selectPs(flip, rdx, rbx), selectPs(flip, rbx, rdx)};
  const __m128 py[3] = {ray, selectPs(flip, rdy, rby), selectPs(flip, rby, rdy)};
  alignas(16) float ex[3][4], ey[3][4], ec[3][4];
  alignas(16) int32_t bounds[4][4];
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const __m128 exv = _mm_sub_ps(px[j], px[i]), eyv = _mm_sub_ps(py[j], py[i]);
    _mm_store_ps(ex[i], _mm_xor_ps(eyv, _mm_set1_ps(-0.0f)));
    _mm_store_ps(ey[i], exv);
    _mm_store_ps(ec[i], _mm_add_ps(_mm_sub_ps(_mm_mul_ps(eyv, px[i]), _mm_mul_ps(exv, py[i])),
                                   _mm_mul_ps(slack, _mm_add_ps(absPs(exv), absPs(eyv)))));
  }
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[0]), x0);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[1]), x1);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[2]), y0);
  _mm_store_si128(reinterpret_cast<__m128i*>(bounds[3]), y1);
  for (int l = 0; l < 4; ++l) {
    if (!(r.done >> l & 1u)) continue;
    CoverEdges& e = t[l];
    e.x0 = bounds[0][l];
    e.x1 = bounds[1][l];
    e.y0 = bounds[2][l];
    e.y1 = bounds[3][l];
    for (int i = 0; i < 3; ++i) {
      e.ex[i] = ex[i][l];
      e.ey[i] = ey[i][l];
      e.ec[i] = ec[i][l];
    }
  }
  return r;
}
#endif

// Adds the centres of a set-up triangle to the tiles of `sink`.
inline void coverTriangle(const CoverEdges& t, CoverageSink& sink) {
  const int x0 = t.x0, x1 = t.x1, y0 = t.y0, y1 = t.y1;
  const float *ex = t.ex, *ey = t.ey, *ec = t.ec;
  const bool large = (x1 - x0 + 1) * (y1 - y0 + 1) > 128;
  for (int ty = y0 >> 3; ty <= y1 >> 3; ++ty) {
    const int ya = std::max(y0, ty * 8), yb = std::min(y1, ty * 8 + 7);
    // The columns these rows can cover: an edge not close to horizontal is negative left (or
    // right) of where its largest value over the rows crosses zero. A pixel of margin keeps the
    // range a superset of the centres the tests below pass (their float rounding is orders of
    // magnitude smaller there), so the skipped tiles would have come out empty.
    int first = x0, last = x1;
    if (large) {
      for (int i = 0; i < 3; ++i) {
        const double a = ex[i], b = ey[i];
        if (!(std::fabs(a) >= 1e-3 * (std::fabs(a) + std::fabs(b)))) continue;
        const double top = std::max(b * double(ya - y0), b * double(yb - y0)) + double(ec[i]);
        const double cross = double(x0) - top / a;
        if (a > 0.0) {
          if (cross - 1.0 > double(first))
            first = cross - 1.0 > double(x1) ? x1 + 1 : int(cross - 1.0);
        } else if (cross + 1.0 < double(last)) {
          last = cross + 1.0 < double(x0) ? x0 - 1 : int(std::ceil(cross + 1.0));
        }
      }
      if (first > last) continue;
    }
    for (int tx = first >> 3; tx <= last >> 3; ++tx) {
      const int xa = std::max(x0, tx * 8), xb = std::min(x1, tx * 8 + 7);
      if (large) {
        // Linear edge functions: a part of the tile whose four corner centres are inside every
        // edge is covered whole; one whose corners are all outside one edge is missed whole.
        bool all_in = true, missed = false;
        for (int i = 0; i < 3 && !missed; ++i) {
          const float ax = ex[i] * float(xa - x0), bx = ex[i] * float(xb - x0);
          const float ay = ey[i] * float(ya - y0) + ec[i], by = ey[i] * float(yb - y0) + ec[i];
          const float lo = std::min(std::min(ax + ay, bx + ay), std::min(ax + by, bx + by));
          const float hi = std::max(std::max(ax + ay, bx + ay), std::max(ax + by, bx + by));
          missed = hi < 0.0f;
          all_in = all_in && lo >= 0.0f;
        }
        if (missed) continue;
        if (all_in) {
          sink.setRect(xa, ya, xb, yb);
          continue;
        }
      }
      // Centre by centre, a row of the tile at a time.
      sink.orTile(tx, ty, tileCoverage(t, xa, xb, ya, yb));
    }
  }
}

// A small cell's centres as one 64-bit row per pixel row: bit x - bx of rows[y - by]. Adds a
// set-up triangle's centres (all within 64 columns from bx and 64 rows from by), four columns
// at a time from the triangle's first.
inline void coverTriangleRows(const CoverEdges& t, int bx, int by, uint64_t* rows) {
#if defined(__SSE2__)
  for (int cx = t.x0; cx <= t.x1; cx += 4) {
    const FourColumns four(t, cx);
    const uint32_t valid = t.x1 - cx >= 3 ? 15u : (2u << (t.x1 - cx)) - 1u;
    for (int y = t.y0; y <= t.y1; ++y)
      rows[y - by] |= uint64_t(four.inside(t, float(y - t.y0)) & valid) << (cx - bx);
  }
#else
  for (int y = t.y0; y <= t.y1; ++y)
    for (int x = t.x0; x <= t.x1; ++x)
      if (centreInside(t, float(x - t.x0), float(y - t.y0)))
        rows[y - by] |= uint64_t(1) << (x - bx);
#endif
}

// out[j] byte k = in[k] byte j: eight 64-bit pixel rows (bit x of row k) as the masks of the
// eight 8x8 tiles they cross (bit k * 8 + (x & 7) of tile x / 8).
inline void transposeBytes8x8(const uint64_t* in, uint64_t* out) {
#if defined(__SSE2__)
  auto row = [&](int k) { return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(in + k)); };
  const __m128i a0 = _mm_unpacklo_epi8(row(0), row(1)), a1 = _mm_unpacklo_epi8(row(2), row(3));
  const __m128i a2 = _mm_unpacklo_epi8(row(4), row(5)), a3 = _mm_unpacklo_epi8(row(6), row(7));
  const __m128i b0 = _mm_unpacklo_epi16(a0, a1), b1 = _mm_unpackhi_epi16(a0, a1);
  const __m128i b2 = _mm_unpacklo_epi16(a2, a3), b3 = _mm_unpackhi_epi16(a2, a3);
  __m128i* o = reinterpret_cast<__m128i*>(out);
  _mm_storeu_si128(o + 0, _mm_unpacklo_epi32(b0, b2));
  _mm_storeu_si128(o + 1, _mm_unpackhi_epi32(b0, b2));
  _mm_storeu_si128(o + 2, _mm_unpacklo_epi32(b1, b3));
  _mm_storeu_si128(o + 3, _mm_unpackhi_epi32(b1, b3));
#else
  for (int j = 0; j < 8; ++j) {
    uint64_t m = 0;
    for (int k = 0; k < 8; ++k) m |= ((in[k] >> (8 * j)) & 0xFFu) << (8 * k);
    out[j] = m;
  }
#endif
}

}  // namespace

}  // namespace strata::cellorder
