// A triangle mesh by reference (positions and three indices per triangle), what the
// preprocessing steps read, and the content key their cache files are named by.
#pragma once

#include <cstddef>
#include <cstdint>

#include <glm/glm.hpp>

#include "preprocess/core/hash.h"

namespace strata {

struct MeshView {
  const glm::vec3* positions = nullptr;
  size_t vertex_count = 0;
  const uint32_t* indices = nullptr;
  size_t triangle_count = 0;
};

// FNV-1a 64 of, in order: the tag's bytes (its terminating zero included), the format version,
// the vertex and triangle counts, the positions, the indices and the options' bytes.
template <size_t N, typename Options>
uint64_t meshCacheKey(const char (&tag)[N], uint32_t version, const MeshView& mesh,
                      const Options& options) {
  uint64_t h = fnv1a64(tag, N);
  h = fnv1a64(&version, sizeof(version), h);
  const uint64_t counts[2] = {mesh.vertex_count, mesh.triangle_count};
  h = fnv1a64(counts, sizeof(counts), h);
  if (mesh.vertex_count) h = fnv1a64(mesh.positions, mesh.vertex_count * sizeof(glm::vec3), h);
  if (mesh.triangle_count) h = fnv1a64(mesh.indices, mesh.triangle_count * 3 * sizeof(uint32_t), h);
  return fnv1a64(&options, sizeof(options), h);
}

}  // namespace strata
