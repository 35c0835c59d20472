// The fixed meshes and options the cache targets read caches of, shared with the seed writer.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/builtin_scenes.h"
#include "preprocess/convex_cells.h"
#include "preprocess/core/hash.h"
#include "preprocess/mesh_view.h"
#include "preprocess/octree.h"

namespace strata::fuzz {

// A torus: several convex cells and pairs between them, and an octree a few levels deep.
struct FuzzMesh {
  Mesh mesh = makeTorus(1.0f, 0.35f, 24, 12);
  MeshView view() const {
    return MeshView{mesh.positions.data(), mesh.positions.size(), mesh.indices.data(),
                    mesh.indices.size() / 3};
  }
};

inline const FuzzMesh& fuzzMesh() {
  static const FuzzMesh m;
  return m;
}

inline DecomposeOptions fuzzDecomposeOptions() {
  DecomposeOptions o;
  o.max_cell_triangles = 64;
  return o;
}

inline OctreeOptions fuzzOctreeOptions() {
  OctreeOptions o;
  o.leaf_triangles = 16;
  return o;
}

// Cache files end with the FNV-1a 64 of every byte before it. A mutated input gets its checksum
// recomputed, so the checks past the checksum are what is fuzzed (the checksum guards against
// damage, not against a crafted file).
inline std::string withTrailingChecksum(std::string bytes) {
  if (bytes.size() < 8) return bytes;
  const uint64_t sum = fnv1a64(bytes.data(), bytes.size() - 8);
  std::memcpy(bytes.data() + bytes.size() - 8, &sum, 8);
  return bytes;
}

}  // namespace strata::fuzz
