// libFuzzer target: the octree cache reader. Whatever it accepts must be a tree whose leaves
// reference only existing triangles, and walking it front to back must end.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "fuzz/fuzz_caches.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace strata;
  const MeshView mesh = fuzz::fuzzMesh().view();
  const std::string bytes =
      fuzz::withTrailingChecksum(std::string(reinterpret_cast<const char*>(data), size));
  Octree tree;
  if (!parseOctreeFile(bytes, mesh, fuzz::fuzzOctreeOptions(), &tree).empty()) return 0;
  for (uint32_t r : tree.refs)
    if (r >= mesh.triangle_count) std::abort();
  std::vector<uint32_t> leaves;
  frontToBackLeaves(tree, true, glm::vec3(3.0f, 2.0f, 1.0f), glm::vec3(-1.0f, 0.0f, 0.0f), leaves);
  for (uint32_t leaf : leaves)
    if (leaf >= tree.nodes.size()) std::abort();
  return 0;
}
