// FNV-1a, 64 bits: the one content hash of cache keys and checksums (program binaries, convex
// cells, the octree). Not cryptographic; it detects stale and damaged files, not forgeries.
// And a 32-bit integer mix for deterministic variation in generated scenes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace strata {

inline constexpr uint64_t kFnvOffsetBasis = 14695981039346656037ull;

inline uint64_t fnv1a64(const void* data, size_t size, uint64_t h = kFnvOffsetBasis) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

inline uint64_t fnv1a64(std::string_view bytes, uint64_t h = kFnvOffsetBasis) {
  return fnv1a64(bytes.data(), bytes.size(), h);
}

// A 32-bit integer hash (the "lowbias32" mix): neighbouring inputs give unrelated outputs.
inline uint32_t mixU32(uint32_t x) {
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

}  // namespace strata
