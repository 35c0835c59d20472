// Writes one valid file per cache reader into OUTPUT/<target>/, the seeds the cache targets start
// from (a mutation of a valid file reaches every check; random bytes stop at the magic).
#include <cstdio>
#include <filesystem>
#include <string>

#include "fuzz/fuzz_caches.h"
#include "fuzz/fuzz_support.h"
#include "preprocess/core/files.h"
#include "preprocess/octree_scene.h"
#include "preprocess/scene/world_geometry.h"

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  using namespace strata;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUTPUT_FOLDER\n", argv[0]);
    return 2;
  }
  const fs::path out = argv[1];
  for (const char* target :
       {"fuzz_cell_cache", "fuzz_octree_cache", "fuzz_program_cache", "fuzz_octree_scene"})
    fs::create_directories(out / target);
  const MeshView mesh = fuzz::fuzzMesh().view();

  CellPreprocess cells;
  cells.cells = decomposeConvexCells(mesh, fuzz::fuzzDecomposeOptions());
  findCellPairs(mesh, cells.cells, &cells.grid, &cells.pairs);
  const std::vector<char> cell_file = serializeCellCache(cells, mesh, fuzz::fuzzDecomposeOptions());
  fuzz::writeFile(out / "fuzz_cell_cache" / "torus.cells",
                  std::string_view(cell_file.data(), cell_file.size()));

  writeOctreeFile((out / "fuzz_octree_cache" / "torus.octree").string(), mesh,
                  fuzz::fuzzOctreeOptions());

  // An octree scene file (its own format with per-section checksums), of a small built-in scene.
  const Scene scene = loadScene("builtin:demo");
  const WorldGeometry geometry = inCore(WorldGeometry::fromScene(scene));
  const MeshView world{geometry.positions.data(), geometry.positions.size(),
                       geometry.indices.data(), geometry.indices.size() / 3};
  const Octree tree = buildOctree(world, fuzz::fuzzOctreeOptions());
  writeOctreeScene((out / "fuzz_octree_scene" / "spheres.octree").string(), scene, geometry, tree);

  static constexpr char kMagic[8] = {'S', 'T', 'R', 'A', 'T', 'A', 'P', 'B'};
  fuzz::writeFile(out / "fuzz_program_cache" / "small.bin",
                  frameCachePayload(kMagic,
                                    "\x7f"
                                    "ELF a program binary"));
  std::printf("cell cache: %zu cells, %zu pairs; seeds in %s\n", size_t(cells.cells.cellCount()),
              cells.pairs.size(), out.c_str());
  return 0;
}
