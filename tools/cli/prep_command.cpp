// strata prep: a scene's convex cells for the cells method (cached, or written with -o and
// exported as a coloured mesh), or with --octree its octree and the octree scene file.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/cells/cell_order.h"
#include "engine/report/stats_json.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/cell_export.h"
#include "preprocess/core/files.h"
#include "preprocess/octree.h"
#include "preprocess/octree_scene.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace {

struct PrepArgs {
  std::string scene, output, decompose = "strict", cache;
  std::string export_ply;  // --export: the cells as a mesh coloured per cell
  bool json = false;
  bool octree = false;  // --octree: the octree method's tree instead of the cells
  uint32_t leaf_tris = kDefaultLeafTriangles;
};

// prep --octree: the octree of the whole scene (its world-space triangles as one soup).
int runPrepOctree(const PrepArgs& a) {
  if (!a.export_ply.empty())
    throw Error("--export writes convex cells; it does not apply to --octree");
  if (!a.output.empty() && std::filesystem::path(a.output).extension() != ".octree")
    throw Error("-o " + a.output +
                ": an octree scene's name must end in .octree (render and "
                "the other commands know it by that)");
  checkWritable(a.output, "the octree scene");
  OctreeOptions options;
  options.leaf_triangles = a.leaf_tris;
  if (options.leaf_triangles == 0) throw Error("--leaf-tris must be at least 1");
  const Scene scene = loadScene(a.scene);
  const WorldGeometry geometry = inCore(WorldGeometry::fromScene(scene));
  if (!a.output.empty() && geometry.textured())
    throw Error(a.scene + ": a textured scene cannot be written as an octree scene (-o)");
  const MeshView world = worldMesh(geometry);
  bool from_cache = false;
  const Octree tree =
      loadOrBuildOctree(world, options, a.cache, &from_cache, progressBar("octree"));
  if (!a.output.empty())
    writeOctreeScene(a.output, scene, geometry, tree, progressBar("octree scene"));
  const OctreeStats& st = tree.stats;
  const uint64_t placed = st.triangles - st.skipped;
  nlohmann::json j;
  j["scene"] = a.scene;
  j["triangles"] = st.triangles;
  j["skipped_triangles"] = st.skipped;
  j["leaf_tris"] = options.leaf_triangles;
  j["nodes"] = st.nodes;
  j["leaves"] = st.leaves;
  j["empty_leaves"] = st.empty_leaves;
  j["refs"] = st.refs;
  j["duplicated_refs"] = st.refs - std::min(st.refs, placed);
  j["largest_leaf"] = st.largest_leaf;
  j["depth"] = st.depth;
  j["build_ms"] = st.build_ms;
  j["from_cache"] = from_cache;
  j["cache_file"] = octreeCachePath(world, options, a.cache);
  if (!a.output.empty()) j["output"] = a.output;
  if (a.json) {
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf(
        "%s: %llu triangles -> octree of %llu leaves (%llu empty), depth %u, %llu references "
        "(%.2f per triangle), largest leaf %llu (limit %u), built in %.1f ms%s\n",
        a.scene.c_str(), (unsigned long long)st.triangles, (unsigned long long)st.leaves,
        (unsigned long long)st.empty_leaves, st.depth, (unsigned long long)st.refs,
        placed ? double(st.refs) / double(placed) : 0.0, (unsigned long long)st.largest_leaf,
        options.leaf_triangles, st.build_ms, from_cache ? " (read from the cache)" : "");
    if (!a.output.empty())
      std::printf(
          "%s: octree scene written (the tree and every leaf's triangles; render it "
          "with strata render %s -m octree)\n",
          a.output.c_str(), a.output.c_str());
    if (st.skipped)
      std::printf("%s: %llu triangles with a non-finite corner or a bad index are in no leaf\n",
                  a.scene.c_str(), (unsigned long long)st.skipped);
  }
  return 0;
}

int runPrep(const PrepArgs& a) {
  if (a.octree) return runPrepOctree(a);
  DecomposeOptions options;
  options.mode = parseDecomposeMode(a.decompose);
  checkWritable(a.output, "the cell file");
  if (!a.export_ply.empty()) checkCellExportPath(a.export_ply);
  checkWritable(a.export_ply, "the cell export");
  const Scene scene = loadScene(a.scene);
  const WorldGeometry geometry = inCore(WorldGeometry::fromScene(scene));
  const CellScene cells = CellScene::build(geometry, options, a.cache);
  std::vector<uint32_t> sizes;
  for (uint32_t c = 0; c < cells.cellCount(); ++c)
    sizes.push_back(cells.cell_first[c + 1] - cells.cell_first[c]);
  std::sort(sizes.begin(), sizes.end());
  const uint32_t median = sizes.empty() ? 0 : sizes[sizes.size() / 2];
  std::set<uint32_t> meshes;
  for (const GeometryPart& p : geometry.parts) meshes.insert(p.mesh);
  if (!a.output.empty()) {
    if (meshes.size() != 1)
      throw Error(a.scene + ": -o writes one mesh's cell file, but the scene has " +
                  std::to_string(meshes.size()) + " meshes; use --cache DIR to keep them all");
    const GeometryPart& part = geometry.parts.front();
    std::vector<uint32_t> local;
    bool object_space = false;
    const MeshView view = cellMeshView(geometry, part, local, &object_space);
    const std::string from = cellCachePath(view, options, a.cache);
    std::ifstream in(from, std::ios::binary);
    if (!in) throw Error(from + ": the cell file was not written (is the cache folder writable?)");
    std::stringstream data;
    data << in.rdbuf();
    writeTextFileAtomically(a.output, data.str());
  }
  if (!a.export_ply.empty()) {  // every instance of every mesh, in world space
    const MeshView world = worldMesh(geometry);
    exportCellsPly(a.export_ply, world, cells.cell_first.data(), cells.cellCount(),
                   cells.cell_triangles.data());
  }
  nlohmann::json j;
  j["scene"] = a.scene;
  j["decompose"] = a.decompose;
  j["triangles"] = geometry.triangleCount();
  j["meshes"] = meshes.size();
  j["cells"] = cells.cellCount();
  j["median_cell_triangles"] = median;
  j["separable_pairs"] = cells.separable_pairs;
  j["inseparable_pairs"] = cells.inseparable_pairs;
  j["copy_cells"] = cells.copy_cells;
  j["unpaired_parts"] = cells.unpaired_parts;
  j["grid"] = {cells.grid.dims.x, cells.grid.dims.y, cells.grid.dims.z};
  j["preprocess_ms"] = cells.preprocess_ms;
  j["from_cache"] = cells.from_cache;
  j["cache_dir"] = a.cache.empty() ? defaultCellCacheDir() : a.cache;
  if (!a.export_ply.empty()) j["export"] = a.export_ply;
  if (a.json) {
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    const std::string copies = cells.copy_cells
                                   ? " " + std::to_string(cells.copy_cells) +
                                         " copies of coincident triangles ordered with their first,"
                                   : "";
    std::printf(
        "%s: %u triangles in %zu mesh(es) -> %u convex cells (%s test, median %u triangles), "
        "%llu of %llu neighbour pairs separable,%s grid %dx%dx%d, %.1f ms%s\n",
        a.scene.c_str(), geometry.triangleCount(), meshes.size(), cells.cellCount(),
        a.decompose.c_str(), median, (unsigned long long)cells.separable_pairs,
        (unsigned long long)(cells.separable_pairs + cells.inseparable_pairs), copies.c_str(),
        cells.grid.dims.x, cells.grid.dims.y, cells.grid.dims.z, cells.preprocess_ms,
        cells.from_cache ? " (read from the cache)" : "");
    if (cells.unpaired_parts)
      std::printf(
          "%s: %u instance(s) of meshes whose overlapping cells pass the pair bound (64 per "
          "cell and 2^20): each drawn as one merged group, a sorted list per pixel\n",
          a.scene.c_str(), cells.unpaired_parts);
    if (!a.export_ply.empty())
      std::printf("%s: %u cells written as a mesh coloured per cell\n", a.export_ply.c_str(),
                  cells.cellCount());
  }
  return 0;
}

}  // namespace

Command addPrepCommand(CLI::App& app) {
  auto args = std::make_shared<PrepArgs>();
  PrepArgs& pa = *args;
  CLI::App* prep = app.add_subcommand("prep",
                                      "decompose a scene's meshes into convex cells for the cells "
                                      "method, or (--octree) build the scene's octree for the "
                                      "octree method (both cached; render --method cells makes "
                                      "its cells on demand)");
  prep->add_option("scene", pa.scene, "a mesh file or builtin:NAME")->required();
  prep->add_option("-o,--output", pa.output,
                   "also write the mesh's cell file here (scenes of one mesh); with --octree the "
                   "octree scene (FILE.octree)");
  prep->add_option("--decompose", pa.decompose, "strict (exact) or paper (the paper's local test)")
      ->capture_default_str();
  prep->add_option("--cache", pa.cache,
                   "folder of the cache files (default: $XDG_CACHE_HOME/strata/cells, or "
                   "$XDG_CACHE_HOME/strata/octree with --octree)");
  prep->add_flag("--json", pa.json, "print JSON");
  prep->add_flag(
      "--octree", pa.octree,
      "build the octree (leaves of at most --leaf-tris triangle references, except where "
      "no split separates them, as with coincident faces; a triangle is referenced by "
      "every leaf it meets) instead of the cells; with -o FILE.octree "
      "also writes the octree scene: the tree with every leaf's triangles and the "
      "materials in one file, which render --method octree streams from disk leaf by "
      "leaf (the scene never has to fit in host memory)");
  prep->add_option("--leaf-tris", pa.leaf_tris, "--octree: the face limit of a leaf")
      ->capture_default_str();
  prep->add_option("--export", pa.export_ply,
                   "also write the cells as a binary PLY mesh, every instance in world space, each "
                   "cell in its own colour (face and vertex colours, e.g. for MeshLab)");
  Command c;
  c.app = prep;
  c.run = [args] { return runPrep(*args); };
  c.subject = [args] { return args->scene; };
  return c;
}

}  // namespace strata::cli
