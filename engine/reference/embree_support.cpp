// The Embree reference's errors and hits (embree_support.h).
#include "engine/reference/embree_support.h"

#include <algorithm>
#include <cmath>

#include "strata/error.h"

namespace strata::embree_support {

// ---- Embree errors ------------------------------------------------------------------------------

// Embree reports the message through the error callback on the thread that made the failing call
// and the code through rtcGetDeviceError; both are read right after the call.
thread_local std::string t_embree_message;

void onEmbreeError(void*, RTCError, const char* message) {
  t_embree_message = message ? message : "";
}

const char* errorName(RTCError e) {
  switch (e) {
    case RTC_ERROR_NONE:
      return "no error";
    case RTC_ERROR_UNKNOWN:
      return "unknown error";
    case RTC_ERROR_INVALID_ARGUMENT:
      return "invalid argument";
    case RTC_ERROR_INVALID_OPERATION:
      return "invalid operation";
    case RTC_ERROR_OUT_OF_MEMORY:
      return "out of memory";
    case RTC_ERROR_UNSUPPORTED_CPU:
      return "unsupported CPU";
    case RTC_ERROR_CANCELLED:
      return "cancelled";
  }
  return "unknown error code";
}

void checkEmbree(RTCDevice device, const char* call) {
  const RTCError code = rtcGetDeviceError(device);
  if (code == RTC_ERROR_NONE) return;
  std::string message = std::string("Embree: ") + call + " failed: " + errorName(code);
  if (!t_embree_message.empty() && t_embree_message != errorName(code))
    message += ": " + t_embree_message;
  t_embree_message.clear();
  throw Error(message);
}

// Transparency filter: records the hit and rejects it, so one traversal visits every hit.
void gatherEveryHit(const RTCFilterFunctionNArguments* args) {
  const TraceContext* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    const unsigned slot = RTCRayN_id(args->ray, n, i);
    const float t = RTCRayN_tfar(args->ray, n, i);  // the candidate's distance
    ctx->hits[slot].push_back(hitKey(t, RTCHitN_primID(args->hit, n, i)));
    args->valid[i] = 0;
  }
}

// Opaque filter: accepts a hit only if it is nearer than the best so far, or as near with a
// smaller triangle id. Accepting shortens the ray; Embree's distance test includes tfar, so a tie
// still reaches the filter and the result does not depend on traversal order.
void keepNearestHit(const RTCFilterFunctionNArguments* args) {
  const TraceContext* ctx = reinterpret_cast<const TraceContext*>(args->context);
  const unsigned n = args->N;
  for (unsigned i = 0; i < n; ++i) {
    if (args->valid[i] == 0) continue;
    NearestHit& best = ctx->nearest[RTCRayN_id(args->ray, n, i)];
    const float t = RTCRayN_tfar(args->ray, n, i);
    const uint32_t triangle = RTCHitN_primID(args->hit, n, i);
    if (t < best.t || (t == best.t && triangle < best.triangle))
      best = {t, triangle};
    else
      args->valid[i] = 0;
  }
}

// Sorts a ray's hits by (t, triangle id) and drops repeated triangles, keeping the nearest: a
// high-quality (spatial split) BVH can report one triangle from several leaves. Returns the count.
size_t sortUniqueHits(std::vector<uint64_t>& hits, std::vector<uint64_t>& scratch) {
  std::sort(hits.begin(), hits.end());
  hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
  const size_t n = hits.size();
  if (n < 2) return n;
  // Repeats of one triangle normally carry the same distance (removed above); guard against
  // repeats whose distance differs in the last bits too.
  if (n <= 32) {
    size_t kept = 0;
    for (size_t i = 0; i < n; ++i) {
      const uint32_t tri = hitTriangle(hits[i]);
      bool seen = false;
      for (size_t j = 0; j < kept && !seen; ++j) seen = hitTriangle(hits[j]) == tri;
      if (!seen) hits[kept++] = hits[i];
    }
    hits.resize(kept);
    return kept;
  }
  scratch.clear();
  for (uint64_t h : hits) scratch.push_back((h << 32) | (h >> 32));  // (triangle, t)
  std::sort(scratch.begin(), scratch.end());
  hits.clear();
  for (size_t i = 0; i < scratch.size(); ++i)
    if (i == 0 || (scratch[i] >> 32) != (scratch[i - 1] >> 32))
      hits.push_back((scratch[i] << 32) | (scratch[i] >> 32));
  std::sort(hits.begin(), hits.end());
  return hits.size();
}

// Barycentric weights of the point where the line org + t dir meets the plane of triangle
// (a, b, c), in double precision; false if the line is parallel to the plane.
bool barycentric(const glm::dvec3& org, const glm::dvec3& dir, const glm::dvec3& a,
                 const glm::dvec3& b, const glm::dvec3& c, double w[3]) {
  const glm::dvec3 e1 = b - a, e2 = c - a;
  const glm::dvec3 p = glm::cross(dir, e2);
  const double det = glm::dot(e1, p);
  if (det == 0.0) return false;
  const glm::dvec3 s = org - a;
  const double u = glm::dot(s, p) / det;
  const double v = glm::dot(dir, glm::cross(s, e1)) / det;
  w[0] = 1.0 - u - v;
  w[1] = u;
  w[2] = v;
  return true;
}

// Hits closer than this (relative distance) may be one crossing reported twice.
constexpr float kSameCrossing = 1e-5f;
// Barycentric weight below which a point counts as lying on a triangle's boundary. Embree's
// watertight test accepts hits within about one ulp of an edge, from both triangles.
constexpr double kOnBoundary = 1e-5;

// Embree's watertight test includes the edges, so a ray through an edge shared by two triangles
// (or through a vertex shared by a fan) reports every one of them, where a rasterizer with a
// fill rule covers the pixel once. Hits at the same distance from triangles that share one or
// two corners, where the ray passes through those shared corners' edge or vertex and the
// surface is not folded there, are one crossing: keep the smaller triangle id. Coincident
// triangles (three shared corners) and folds (a silhouette edge) stay separate hits.
//
// Only hits whose ray passes within kOnBoundary of their triangle's boundary can merge (an
// unshared corner's weight must vanish), so each hit is tested for that once and the others
// are passed over: thousands of coincident copies hit in their interiors, all at one distance,
// cost linear time instead of a comparison of every pair.
size_t mergeSharedBoundaryHits(std::vector<uint64_t>& hits, const WorldGeometry& geo,
                               const glm::vec3& org_f, const glm::vec3& dir_f) {
  const size_t n = hits.size();
  bool any_removed = false;
  std::vector<int8_t> on_boundary;  // per hit: -1 not yet known, else 0 or 1
  auto onBoundary = [&](size_t k) {
    if (on_boundary.empty()) on_boundary.assign(n, -1);
    if (on_boundary[k] < 0) {
      const uint32_t* c = &geo.indices[3 * size_t(hitTriangle(hits[k]))];
      double w[3];
      on_boundary[k] =
          barycentric(glm::dvec3(org_f), glm::dvec3(dir_f), glm::dvec3(geo.positions[c[0]]),
                      glm::dvec3(geo.positions[c[1]]), glm::dvec3(geo.positions[c[2]]), w) &&
          std::min({std::abs(w[0]), std::abs(w[1]), std::abs(w[2])}) <= kOnBoundary;
    }
    return on_boundary[k] == 1;
  };
  auto hitDistance = [&](size_t k) {
    float t;
    const uint32_t bits = uint32_t(hits[k] >> 32);
    std::memcpy(&t, &bits, sizeof(t));
    return t;
  };
  for (size_t i = 0; i + 1 < n; ++i) {
    if (hits[i] == ~uint64_t(0)) continue;
    const float limit = hitDistance(i) + kSameCrossing * hitDistance(i);
    if (hitDistance(i + 1) > limit || !onBoundary(i)) continue;
    for (size_t j = i + 1; j < n; ++j) {
      if (hits[j] == ~uint64_t(0)) continue;
      if (hitDistance(j) > limit) break;
      if (!onBoundary(j)) continue;
      const uint32_t A = hitTriangle(hits[i]), B = hitTriangle(hits[j]);
      const uint32_t* ia = &geo.indices[3 * size_t(A)];
      const uint32_t* ib = &geo.indices[3 * size_t(B)];
      // Which corners are shared.
      int shared = 0;
      bool a_shared[3] = {false, false, false}, b_shared[3] = {false, false, false};
      for (int p = 0; p < 3; ++p)
        for (int q = 0; q < 3; ++q)
          if (ia[p] == ib[q] && !a_shared[p] && !b_shared[q]) {
            a_shared[p] = b_shared[q] = true;
            ++shared;
          }
      if (shared != 1 && shared != 2) continue;
      // The ray must pass through the shared edge or vertex of both triangles.
      const glm::dvec3 org(org_f), dir(dir_f);
      glm::dvec3 pa[3], pb[3];
      for (int k = 0; k < 3; ++k) {
        pa[k] = glm::dvec3(geo.positions[ia[k]]);
        pb[k] = glm::dvec3(geo.positions[ib[k]]);
      }
      double wa[3], wb[3];
      if (!barycentric(org, dir, pa[0], pa[1], pa[2], wa) ||
          !barycentric(org, dir, pb[0], pb[1], pb[2], wb))
        continue;
      bool on_shared = true;
      for (int k = 0; k < 3; ++k) {
        if (!a_shared[k] && std::abs(wa[k]) > kOnBoundary) on_shared = false;
        if (!b_shared[k] && std::abs(wb[k]) > kOnBoundary) on_shared = false;
      }
      if (!on_shared) continue;
      // Not folded: across a shared edge the two triangles lie on opposite sides of the edge as
      // seen along the ray; around a shared vertex they face the ray the same way.
      bool single_crossing;
      if (shared == 2) {
        int oa = 0, ob = 0, e0 = -1, e1 = -1;  // unshared corners; shared edge (A's corners)
        for (int k = 0; k < 3; ++k) {
          if (!a_shared[k]) oa = k;
          if (!b_shared[k]) ob = k;
          if (a_shared[k]) (e0 < 0 ? e0 : e1) = k;
        }
        const glm::dvec3 edge_normal = glm::cross(pa[e1] - pa[e0], dir);
        const double side_a = glm::dot(edge_normal, pa[oa] - pa[e0]);
        const double side_b = glm::dot(edge_normal, pb[ob] - pa[e0]);
        single_crossing = (side_a > 0.0 && side_b < 0.0) || (side_a < 0.0 && side_b > 0.0);
      } else {
        const double face_a = glm::dot(glm::cross(pa[1] - pa[0], pa[2] - pa[0]), dir);
        const double face_b = glm::dot(glm::cross(pb[1] - pb[0], pb[2] - pb[0]), dir);
        single_crossing = (face_a > 0.0 && face_b > 0.0) || (face_a < 0.0 && face_b < 0.0);
      }
      if (!single_crossing) continue;
      if (B < A) hits[i] = (hits[i] & ~uint64_t(0xFFFFFFFFu)) | B;
      hits[j] = ~uint64_t(0);
      any_removed = true;
    }
  }
  if (!any_removed) return n;
  hits.erase(std::remove(hits.begin(), hits.end(), ~uint64_t(0)), hits.end());
  return hits.size();
}

}  // namespace strata::embree_support
