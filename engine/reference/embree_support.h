// What the Embree reference renderer (embree_reference.cpp) builds on: Embree's errors as
// strata's, the hits of one ray (sortable words, the filters that gather them, their sort and the
// merge of one crossing reported by the triangles sharing an edge), and its worker threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <exception>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#if defined(__SSE__) || defined(__x86_64__)
#include <xmmintrin.h>
#define STRATA_HAVE_MXCSR 1
#endif

#include <embree3/rtcore.h>
#include <glm/glm.hpp>

#include "preprocess/scene/world_geometry.h"

namespace strata::embree_support {

// Embree's error callback: keeps the message for checkEmbree (set with rtcSetDeviceErrorFunction).
void onEmbreeError(void*, RTCError, const char* message);
// The name of an Embree error code.
const char* errorName(RTCError e);
// Throws Error naming `call` and Embree's error when the device reports one.
void checkEmbree(RTCDevice device, const char* call);

// A hit as one sortable word: the distance's bits (t >= 0, so they order like the value) above
// the triangle id, so sorting the words sorts by (t, triangle id).
inline uint64_t hitKey(float t, uint32_t triangle) {
  if (!(t > 0.0f)) t = 0.0f;  // -0 and NaN would break the bit order
  uint32_t bits;
  std::memcpy(&bits, &t, sizeof(bits));
  return (uint64_t(bits) << 32) | triangle;
}
inline uint32_t hitTriangle(uint64_t key) { return uint32_t(key); }

struct NearestHit {
  float t;
  uint32_t triangle;
};

// The intersection context of one worker: Embree hands the address of `embree` back to the
// filter, which recovers the rest (standard layout, `embree` first). Rays carry their slot in
// `id`.
struct TraceContext {
  RTCIntersectContext embree;
  std::vector<uint64_t>* hits;  // transparency: every hit per ray slot
  NearestHit* nearest;          // opaque: the nearest hit per ray slot
};
static_assert(std::is_standard_layout<TraceContext>::value && offsetof(TraceContext, embree) == 0,
              "the filter casts Embree's context pointer back to TraceContext");

// Transparency filter: records the hit and rejects it, so one traversal visits every hit.
void gatherEveryHit(const RTCFilterFunctionNArguments* args);
// Opaque filter: accepts a hit only if it is nearer than the best so far, or as near with a
// smaller triangle id.
void keepNearestHit(const RTCFilterFunctionNArguments* args);

// Sorts a ray's hits by (t, triangle id) and drops repeated triangles, keeping the nearest: a
// high-quality (spatial split) BVH can report one triangle from several leaves. Returns the count.
size_t sortUniqueHits(std::vector<uint64_t>& hits, std::vector<uint64_t>& scratch);

// One crossing of a ray through an edge or vertex shared by several triangles, reported by each
// of them, kept once (the smaller triangle id); hits sorted by sortUniqueHits. Returns the count.
size_t mergeSharedBoundaryHits(std::vector<uint64_t>& hits, const WorldGeometry& geo,
                               const glm::vec3& org_f, const glm::vec3& dir_f);

// ---- Parallel loops -----------------------------------------------------------------------------

// Runs body(worker) on `threads` threads (the caller is worker 0) and rethrows the first
// exception. Flush-to-zero / denormals-are-zero are set while tracing, as Embree recommends.
template <typename Body>
void runWorkers(int threads, Body&& body) {
  std::exception_ptr failure;
  std::mutex failure_mutex;
  auto guarded = [&](int worker) {
#ifdef STRATA_HAVE_MXCSR
    const unsigned saved_csr = _mm_getcsr();
    _mm_setcsr(saved_csr | 0x8040);  // FTZ | DAZ
#endif
    try {
      body(worker);
    } catch (...) {
      std::lock_guard<std::mutex> lock(failure_mutex);
      if (!failure) failure = std::current_exception();
    }
#ifdef STRATA_HAVE_MXCSR
    _mm_setcsr(saved_csr);
#endif
  };
  std::vector<std::thread> pool;
  pool.reserve(size_t(threads > 1 ? threads - 1 : 0));
  for (int w = 1; w < threads; ++w) pool.emplace_back(guarded, w);
  guarded(0);
  for (std::thread& t : pool) t.join();
  if (failure) std::rethrow_exception(failure);
}

}  // namespace strata::embree_support
