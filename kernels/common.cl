/* common.cl: helpers every stage uses. */
#ifndef ST_NO_INT64_ATOMICS
#pragma OPENCL EXTENSION cl_khr_int64_base_atomics : enable
#pragma OPENCL EXTENSION cl_khr_int64_extended_atomics : enable
#endif

/* 64-bit atomics. With them (cl_khr_int64_*_atomics), a tile kernel's work-group merges 64-bit
 * (depth, id) words with atom_min / atom_max / atom_xchg, and the frame counters are 64-bit
 * atomics. Without them (the host sets ST_NO_INT64_ATOMICS for a device that lacks the
 * extensions, or when asked), the host runs only the serial forms of the tile kernels, where a
 * work-item owns its tile alone: the ST_ATOM64_* of the work-group forms then compile to plain
 * operations that never run, and each counter is two 32-bit words (little-endian: the host
 * checks) updated with 32-bit atomics (st_counter_*). */
#ifdef ST_NO_INT64_ATOMICS
#define ST_ATOM64_MIN(p, v) (*(p) = min(*(p), (v)))
#define ST_ATOM64_MAX(p, v) (*(p) = max(*(p), (v)))
#define ST_ATOM64_DEFINE(NAME, SPACE, OP)                    \
  inline ulong st_atom64_##NAME(SPACE ulong* p, ulong v) { \
    const ulong old = *p;                                  \
    *p = OP;                                               \
    return old;                                            \
  }
ST_ATOM64_DEFINE(min_local, __local, min(old, v))
ST_ATOM64_DEFINE(min_global, __global, min(old, v))
ST_ATOM64_DEFINE(xchg_local, __local, v)
#undef ST_ATOM64_DEFINE
#else
#define ST_ATOM64_MIN(p, v) atom_min((p), (v))
#define ST_ATOM64_MAX(p, v) atom_max((p), (v))
/* The same, returning the old value, per address space (OpenCL C 1.2 has no generic one). */
inline ulong st_atom64_min_local(__local ulong* p, ulong v) { return atom_min(p, v); }
inline ulong st_atom64_min_global(__global ulong* p, ulong v) { return atom_min(p, v); }
inline ulong st_atom64_xchg_local(__local ulong* p, ulong v) { return atom_xchg(p, v); }
#endif

/* counters[i] += v. Without 64-bit atomics: the low word's add, and its carry (or v's high
 * word) added to the high word: the sum is exact once every update is done, which is when the
 * host reads it. */
inline void st_counter_add(__global ulong* counter, ulong v) {
#ifdef ST_NO_INT64_ATOMICS
  volatile __global uint* w = (volatile __global uint*)counter;
  const uint lo = (uint)v, hi = (uint)(v >> 32);
  const uint old = lo ? atomic_add(&w[0], lo) : 0u;
  const uint carry = old > 0xffffffffu - lo ? 1u : 0u;
  if (hi + carry) atomic_add(&w[1], hi + carry);
#else
  atom_add(counter, v);
#endif
}

/* counters[i] = max(counters[i], v). Without 64-bit atomics the maximum is kept in the low word,
 * so a value past 2^32 - 1 is recorded as 2^32 - 1 (the maxima counted are depths and table
 * sizes, far below it). */
inline void st_counter_max(__global ulong* counter, ulong v) {
#ifdef ST_NO_INT64_ATOMICS
  atomic_max((volatile __global uint*)counter, (uint)min(v, (ulong)0xffffffffu));
#else
  atom_max(counter, v);
#endif
}

/* Reserves n consecutive indices from an allocation counter: returns the first. Without 64-bit
 * atomics the counter stops short of 2^32 (a compare-and-swap loop on the low word): a claim
 * that would pass it sets the high word and returns 2^32, past any capacity, so the caller's
 * bound check refuses it and the host sees a counter of 2^32 or more. */
inline ulong st_counter_claim(__global ulong* counter, ulong n) {
#ifdef ST_NO_INT64_ATOMICS
  volatile __global uint* w = (volatile __global uint*)counter;
  uint seen = atomic_or(&w[0], 0u);
  for (;;) {
    if (n > (ulong)(0xffffffffu - seen)) {
      atomic_max(&w[1], 1u);
      return (ulong)1 << 32;
    }
    const uint was = atomic_cmpxchg(&w[0], seen, seen + (uint)n);
    if (was == seen) return (ulong)seen;
    seen = was;
  }
#else
  return atom_add(counter, n);
#endif
}

/* Oclgrind's uninitialised-value checker (21.10), which the tests run most methods under,
 * crashes on vloadN and on a vector shuffle with an undefined lane. Clang emits such a shuffle
 * for (float4)(float3 v, w), and for every float3 kept in memory unless -fpreserve-vec3-type is
 * given (the tests give it). So kernels load points with st_load_point and build a float4 from
 * a float3 component by component. */

/* Point i of a packed array of xyz floats: vload3(i, p). */
inline float3 st_load_point(const size_t i, __global const float* p) {
  return (float3)(p[3 * i], p[3 * i + 1], p[3 * i + 2]);
}

/* dst[i] = (uint2)(x, y), as two scalar stores: Oclgrind compiles the vector store as an
 * undefined vector stored and then overwritten lane by lane, which its checker reports. */
inline void st_store_uint2(__global uint2* dst, const size_t i, const uint x, const uint y) {
  __global uint* p = (__global uint*)(dst + i);
  p[0] = x;
  p[1] = y;
}

/* dst[i] = v, as two scalar stores (st_store_uint2). */
inline void st_store_float2(__global float2* dst, const size_t i, const float2 v) {
  __global float* p = (__global float*)(dst + i);
  p[0] = v.x;
  p[1] = v.y;
}

/* A hint to fetch global memory a work-item reads a little later, for the kernels whose reads
 * wander (the host sets ST_USE_BUILTIN_PREFETCH on PoCL, whose prefetch() is empty). */
#ifdef ST_USE_BUILTIN_PREFETCH
#define ST_PREFETCH(p) __builtin_prefetch((__global const void*)(p))
#else
#define ST_PREFETCH(p) prefetch((__global const uchar*)(p), 1)
#endif

/* Rounding to the nearest integer, ties to even (rint). PoCL's rint() is a software routine
 * (most of the transform stage's time), while clang's builtin is the CPU's rounding
 * instruction: the host sets ST_USE_BUILTIN_RINT on PoCL. */
#ifdef ST_USE_BUILTIN_RINT
#define ST_RINT(x) __builtin_elementwise_roundeven(x)
#else
#define ST_RINT(x) rint(x)
#endif

/* Linear index of a work-item inside a 2-D work-group. */
inline uint st_local_index(void) {
  return get_local_id(0) + get_local_id(1) * get_local_size(0);
}

/* Updates of a tile's __local tables by the work-item owning the pixel: a local atomic in a
 * work-group, a plain operation for a work-item alone on its tile (tile_walk.cl: one body for a
 * tile kernel's two forms). */
inline __attribute__((always_inline)) void st_owned_min_ulong(bool alone, __local ulong* a,
                                                              ulong v) {
  if (alone) *a = min(*a, v);
  else ST_ATOM64_MIN(a, v);
}

inline __attribute__((always_inline)) void st_owned_max_ulong(bool alone, __local ulong* a,
                                                              ulong v) {
  if (alone) *a = max(*a, v);
  else ST_ATOM64_MAX(a, v);
}

inline __attribute__((always_inline)) void st_owned_min_uint(bool alone, __local uint* a, uint v) {
  if (alone) *a = min(*a, v);
  else atomic_min(a, v);
}

inline __attribute__((always_inline)) void st_owned_max_uint(bool alone, __local uint* a, uint v) {
  if (alone) *a = max(*a, v);
  else atomic_max(a, v);
}

inline __attribute__((always_inline)) void st_owned_add_uint(bool alone, __local uint* a, uint v) {
  if (alone) *a += v;
  else atomic_add(a, v);
}

/* Returns the value before the increment (a record index, as atomic_inc). */
inline __attribute__((always_inline)) uint st_owned_inc_uint(bool alone, __local uint* a) {
  if (alone) return (*a)++;
  return atomic_inc(a);
}

inline __attribute__((always_inline)) void st_owned_or_uint(bool alone, __local uint* a, uint v) {
  if (alone) *a |= v;
  else atomic_or(a, v);
}

/* *word += v or *word *= v (multiply) on a float: alone, a plain update; in a work-group, a
 * compare-and-swap loop whose every read is atomic (a plain read beside other work-items'
 * atomics would be a data race; OpenCL 1.2 has no float atomic add). In a work-group the order
 * of a word's updates, and so its last bits, may vary from run to run. */
inline __attribute__((always_inline)) void st_owned_update_float(bool alone, bool multiply,
                                                                 __local float* word, float v) {
  if (alone) {
    *word = multiply ? *word * v : *word + v;
    return;
  }
  volatile __local uint* bits = (volatile __local uint*)word;
  uint seen = atomic_or(bits, 0u);
  for (;;) {
    const float old = as_float(seen);
    const uint next = as_uint(multiply ? old * v : old + v);
    const uint was = atomic_cmpxchg(bits, seen, next);
    if (was == seen) break;
    seen = was;
  }
}

inline __attribute__((always_inline)) void st_owned_add_float(bool alone, __local float* a,
                                                              float v) {
  st_owned_update_float(alone, false, a, v);
}

inline __attribute__((always_inline)) void st_owned_mul_float(bool alone, __local float* a,
                                                              float v) {
  st_owned_update_float(alone, true, a, v);
}

/* Work-group sum over ST_TILE_PIXELS items (a power of two), through local memory. */
inline uint st_group_sum(__local uint* scratch, uint v) {
  const uint lid = st_local_index();
  scratch[lid] = v;
  barrier(CLK_LOCAL_MEM_FENCE);
  for (uint s = ST_TILE_PIXELS / 2; s > 0; s >>= 1) {
    if (lid < s) scratch[lid] += scratch[lid + s];
    barrier(CLK_LOCAL_MEM_FENCE);
  }
  const uint r = scratch[0];
  barrier(CLK_LOCAL_MEM_FENCE);
  return r;
}

/* Adds a tile's fragment count and depth maximum, and a method's own maximum `extra` (0: none)
 * into counters[extra_counter], to the frame counters: one global atomic each per group. The
 * group's totals gather in scratch[0..2] through local atomics, skipped by the work-items with
 * nothing to add: three barriers, where tree reductions took fourteen, and PoCL runs every
 * barrier region as a loop over the 64 work-items even on an empty tile. */
inline void st_report_group_counts(__local uint* scratch, __global ulong* counters, uint fragments,
                                   uint depth, uint extra, uint extra_counter) {
  const uint lid = st_local_index();
  barrier(CLK_LOCAL_MEM_FENCE); /* the caller may still be reading scratch */
  if (lid == 0) scratch[0] = scratch[1] = scratch[2] = 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  if (fragments) atomic_add(&scratch[0], fragments);
  if (depth) atomic_max(&scratch[1], depth);
  if (extra) atomic_max(&scratch[2], extra);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (lid == 0) {
    if (scratch[0]) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)scratch[0]);
    if (scratch[1]) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)scratch[1]);
    if (scratch[2]) st_counter_max(&counters[extra_counter], (ulong)scratch[2]);
  }
}

/* A tile's fragment count, deepest pixel and lost fragments, in either form of a tile kernel:
 * gathered in scratch[0..2] (local atomics in a work-group, plain adds alone), then one global
 * atomic each. Every work-item calls it with what its own pixels add. */
inline __attribute__((always_inline)) void st_report_owned_counts(bool alone,
                                                                  __local uint* scratch,
                                                                  __global ulong* counters,
                                                                  uint fragments, uint depth,
                                                                  uint lost) {
  barrier(CLK_LOCAL_MEM_FENCE); /* the caller may still be reading scratch */
  if (st_local_index() == 0) scratch[0] = scratch[1] = scratch[2] = 0;
  barrier(CLK_LOCAL_MEM_FENCE);
  if (fragments) st_owned_add_uint(alone, &scratch[0], fragments);
  if (depth) st_owned_max_uint(alone, &scratch[1], depth);
  if (lost) st_owned_add_uint(alone, &scratch[2], lost);
  barrier(CLK_LOCAL_MEM_FENCE);
  if (st_local_index() == 0) {
    if (scratch[0]) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)scratch[0]);
    if (scratch[1]) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)scratch[1]);
    if (scratch[2]) st_counter_add(&counters[ST_COUNTER_FRAGMENTS_LOST], (ulong)scratch[2]);
  }
}

/* A serial tile kernel's (one work-item per tile) fragment count and deepest pixel, added to the
 * frame counters. */
inline void st_report_counts_alone(__global ulong* counters, uint fragments, uint depth) {
  if (fragments) st_counter_add(&counters[ST_COUNTER_FRAGMENTS], (ulong)fragments);
  if (depth) st_counter_max(&counters[ST_COUNTER_MAX_DEPTH], (ulong)depth);
}

/* st_report_group_counts without a method maximum. */
inline void st_report_tile_counts(__local uint* scratch, __global ulong* counters, uint fragments,
                                  uint depth) {
  st_report_group_counts(scratch, counters, fragments, depth, 0u, 0u);
}

/* Background colour at a pixel. */
inline float3 st_background(__constant StViewConstants* view, int x, int y) {
  StViewConstants v = *view;
  return (float3)(st_background_channel(&v, x, y, 0), st_background_channel(&v, x, y, 1),
                  st_background_channel(&v, x, y, 2));
}

/* Visibility word: view distance (a positive float, so its bits order like the value) above the
 * source triangle id; the smallest word is the nearest fragment, ties broken by the lower id. */
inline ulong st_visibility_word(float depth, uint source) {
  return ((ulong)as_uint(fmax(depth, 0.0f)) << 32) | (ulong)source;
}

/* Front-to-back "under" compositing of colour c (RGB, opacity) into a running colour and
 * transmittance. */
inline void st_composite_under(float3* color, float* transmittance, float4 c) {
  *color += *transmittance * c.w * c.xyz;
  *transmittance *= 1.0f - c.w;
}

/* The background of a pixel that no fragment reached, as st_pack_rgba8(st_background(..)). */
inline uchar4 st_background_rgba8(__constant StViewConstants* view, int x, int y) {
  const uint p = view->background_rgba8[st_background_index(view->background_kind, x, y)];
#ifdef __ENDIAN_LITTLE__
  return as_uchar4(p);
#else
  return (uchar4)((uchar)p, (uchar)(p >> 8), (uchar)(p >> 16), (uchar)(p >> 24));
#endif
}

inline uchar4 st_pack_rgba8(float3 c) {
  return (uchar4)((uchar)st_to_unorm8(c.x), (uchar)st_to_unorm8(c.y), (uchar)st_to_unorm8(c.z),
                  (uchar)255);
}

/* Behind a pixel's front layers (colour *color, transmittance *t), the n fragments of a tail
 * blended order-independently by Bavoil and Myers' weighted average (2008): their opacity-
 * weighted mean colour sum_c / sum_a (sum_c premultiplied) shown through 1 - (1 - sum_a / n)^n,
 * which also multiplies *t. */
inline void st_blend_tail(float3* color, float* t, float3 sum_c, float sum_a, uint n) {
  if (n == 0 || !(sum_a > 0.0f)) return;
  const float tail_t = pown(1.0f - sum_a / (float)n, (int)n);
  *color += *t * (1.0f - tail_t) * sum_c / sum_a;
  *t *= tail_t;
}

/* A resolved pixel (x, y) of the image: `color` with the background seen through
 * `transmittance` into the image, its fragment count into the depth-complexity map when the
 * frame captures it, and into the tile's totals (*fragments, *deepest). */
inline void st_put_resolved_pixel(__constant StViewConstants* view, __global uchar4* image,
                                  __global uint* depth_complexity, int capture_depth_complexity,
                                  int x, int y, float3 color, float transmittance, uint count,
                                  uint* fragments, uint* deepest) {
  const size_t at = (size_t)y * (size_t)view->width + (size_t)x;
  image[at] = st_pack_rgba8(color + transmittance * st_background(view, x, y));
  if (capture_depth_complexity) depth_complexity[at] = count;
  *fragments += count;
  *deepest = max(*deepest, count);
}

/* a.xyz + a.w * behind: a front-to-back accumulator (colour, transmittance) over what lies
 * behind it. Per component: the splat of a.w into a float3 is a shuffle Oclgrind's checker
 * misreads (top of this file). */
inline float3 st_over(const float4 a, const float3 behind) {
  const float w = a.w;
  return (float3)(a.x + w * behind.x, a.y + w * behind.y, a.z + w * behind.z);
}
