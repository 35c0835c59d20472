// libFuzzer target: the convex-cell cache reader (a file in the user's cache folder that anyone
// with write access there can craft). Whatever it accepts must be a consistent decomposition of
// the mesh it was asked about.
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
  CellPreprocess cells;
  if (!parseCellCache(bytes, mesh, fuzz::fuzzDecomposeOptions(), &cells)) return 0;
  // Accepted: every triangle in exactly one cell, every pair between existing cells.
  const auto& order = cells.cells.triangle_order;
  if (order.size() != mesh.triangle_count) std::abort();
  std::vector<uint8_t> seen(mesh.triangle_count, 0);
  for (uint32_t t : order) {
    if (t >= mesh.triangle_count || seen[t]) std::abort();
    seen[t] = 1;
  }
  for (const CellPair& p : cells.pairs)
    if (p.a >= cells.cells.cellCount() || p.b >= cells.cells.cellCount()) std::abort();
  return 0;
}
