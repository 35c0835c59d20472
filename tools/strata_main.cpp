// strata: the command-line program. Subcommands: info, render, prep, export, diff, bench, pick.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <new>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "engine/cell_order.h"
#include "engine/picking.h"
#include "engine/renderer.h"
#include "engine/report/bench.h"
#include "engine/report/device_report.h"
#include "engine/report/soak.h"
#include "engine/report/stats_json.h"
#include "engine/texture_shading.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/cell_export.h"
#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/image_io.h"
#include "preprocess/mesh_writer.h"
#include "preprocess/octree.h"
#include "preprocess/octree_scene.h"
#include "tools/distributed_render.h"

using namespace strata;
namespace fs = std::filesystem;

namespace {

// The device option: --device, else STRATA_DEVICE (the library itself reads no environment).
std::string deviceSpec(const std::string& option) {
  if (!option.empty()) return option;
  const char* env = std::getenv("STRATA_DEVICE");
  return env ? env : "";
}

// --method's help: every registered method with its one-line summary.
std::string methodHelp() {
  std::string text = "a method, a comma-separated list, or all:";
  for (const MethodTraits& m : methodRegistry()) {
    text += std::string("\n  ") + m.name + ": " + m.summary;
    if (m.renders(Effect::Translucency)) text += " [translucency]";
    if (m.takes_k) text += " [--k]";
  }
  return text;
}

std::vector<float> parseFloatList(const std::string& text, const std::string& option) {
  std::vector<float> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    size_t used = 0;
    float v = 0.0f;
    try {
      v = std::stof(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || !std::isfinite(v))
      throw Error(option + " '" + text + "': '" + item + "' is not a number");
    out.push_back(v);
  }
  return out;
}

void parseSize(const std::string& text, int& w, int& h) {
  const size_t x = text.find_first_of("xX");
  try {
    size_t a = 0, b = 0;
    if (x == std::string::npos) throw std::invalid_argument("");
    const std::string ws = text.substr(0, x), hs = text.substr(x + 1);
    w = std::stoi(ws, &a);
    h = std::stoi(hs, &b);
    if (a != ws.size() || b != hs.size()) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw Error("--size '" + text + "': expected WIDTHxHEIGHT, e.g. 512x512");
  }
}

Background parseBackground(const std::string& text) {
  Background bg;
  if (text == "checker") return bg;
  bg.checker = false;
  const std::string expected =
      "--background '" + text + "': expected checker, #rrggbb or r,g,b in 0..1";
  if (!text.empty() && text[0] == '#') {
    if (text.size() != 7 || !std::all_of(text.begin() + 1, text.end(), [](char c) {
          return std::isxdigit(static_cast<unsigned char>(c)) != 0;
        }))
      throw Error(expected);
    const unsigned v = unsigned(std::stoul(text.substr(1), nullptr, 16));
    bg.color = glm::vec3((v >> 16) & 255, (v >> 8) & 255, v & 255) / 255.0f;
    return bg;
  }
  const std::vector<float> c = parseFloatList(text, "--background");
  if (c.size() != 3 ||
      !std::all_of(c.begin(), c.end(), [](float v) { return v >= 0.0f && v <= 1.0f; }))
    throw Error(expected);
  bg.color = {c[0], c[1], c[2]};
  return bg;
}

// Fails early, before a long render, if an output file could not be written.
void checkWritable(const std::string& path, const std::string& what) {
  if (path.empty()) return;
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw Error(path + ": cannot write " + what + ": folder " + dir.string() + " does not exist");
  if (access(dir.c_str(), W_OK) != 0)
    throw Error(path + ": cannot write " + what + ": folder " + dir.string() + " is not writable");
  if (fs::is_directory(path, ec)) throw Error(path + ": cannot write " + what + ": it is a folder");
}

std::string withSuffix(const std::string& path, const std::string& suffix) {
  const fs::path p(path);
  return (p.parent_path() / (p.stem().string() + "-" + suffix + p.extension().string())).string();
}

// The camera of `render` and `pick`: the scene's own view, or --view AZ,EL[,DIST], framed
// afresh; --ortho / --perspective override the scene's projection.
Camera sceneCamera(const Scene& scene, const std::string& view_text, bool ortho, bool perspective,
                   float fov) {
  OrbitView view = scene.default_view.value_or(OrbitView{});
  if (!view_text.empty()) {
    const std::vector<float> v = parseFloatList(view_text, "--view");
    if (v.size() < 2 || v.size() > 3)
      throw Error("--view '" + view_text + "': expected AZ,EL[,DIST]");
    view.azimuth_deg = v[0];
    view.elevation_deg = v[1];
    view.distance_radii.reset();
    view.ortho_height.reset();  // a chosen view is framed afresh
    if (v.size() == 3) {
      if (v[2] <= 0.0f) throw Error("--view: DIST must be positive (in bounding-sphere radii)");
      view.distance_radii = v[2];
    }
  }
  if (ortho && perspective) throw Error("--ortho and --perspective exclude each other");
  const Projection projection = ortho ? Projection::Orthographic
                                : perspective
                                    ? Projection::Perspective
                                    : scene.default_projection.value_or(Projection::Perspective);
  return Camera::orbit(scene.boundingSphere(), view, projection, fov);
}

struct RenderArgs {
  std::string scene = "builtin:demo";
  std::string methods = "ppll";
  std::string size = "512x512";
  std::string view;
  std::string output;
  std::string stats;
  std::string background = "checker";
  std::string device;
  float alpha = -1.0f;
  float fov = 40.0f;
  bool ortho = false;
  bool perspective = false;
  bool alpha_given = false;
  int frames = 1;
  float orbit = 0.0f;  // --orbit: degrees of azimuth per frame
  int k = 16;
  std::string effect = "transparency";
  float sigma = 0.0f;
  bool sigma_given = false;  // unset: 1 / bounding-sphere radius
  std::string decompose = "strict";
  std::string order_ahead = "on";
  int order_reuse = int(CellsOptions{}.order_reuse);
  int64_t cells_batch = int64_t(CellsOptions{}.batch_triangles);
  std::string cells_composite = "auto";
  std::string order_masks = "auto";
  std::string tile_segments = "auto";
  std::string tile_kernels = "auto";
  std::string cache;
  std::string batch = "static";
  std::string sort = "none";
  std::string atlas = "packed";
  std::string texture;  // --texture: for meshes with texture coordinates and no material file
  OctreeMethodOptions octree;
  double memory_budget_mb = 0.0;
  bool distributed = false;  // --distributed: one process of an mpirun job
  bool method_given = false;
  int fail_rank = -1, fail_rank_late = -1;
  double rank_timeout = 60.0;
};

int runRender(const RenderArgs& a) {
  FrameSettings settings;
  parseSize(a.size, settings.width, settings.height);
  settings.frames = a.frames;
  checkFrameCount(a.frames, "--frames");
  if (!(std::fabs(a.orbit) <= 360.0f))
    throw Error("--orbit must be between -360 and 360 degrees per frame");
  settings.orbit_deg = a.orbit;
  if (a.k < 1 || a.k > 256) throw Error("--k must be between 1 and 256");
  settings.k = a.k;
  if (a.alpha_given && !(a.alpha >= 0.0f && a.alpha <= 1.0f))
    throw Error("--alpha must be in 0..1");
  if (!(a.fov > 1.0f && a.fov < 179.0f)) throw Error("--fov must be between 1 and 179 degrees");
  settings.background = parseBackground(a.background);
  settings.effect = parseEffect(a.effect);
  parseDecomposeMode(a.decompose);
  settings.decompose = a.decompose;
  if (a.order_ahead != "on" && a.order_ahead != "off")
    throw Error("--order-ahead must be on or off");
  settings.cells.order_ahead = a.order_ahead == "on";
  if (a.order_reuse < 0 || a.order_reuse > 1000) throw Error("--order-reuse must be 0..1000");
  settings.cells.order_reuse = uint32_t(a.order_reuse);
  if (a.cells_batch < 1 || a.cells_batch > (int64_t(1) << 30))
    throw Error("--cells-batch must be 1..1073741824 triangles");
  settings.cells.batch_triangles = size_t(a.cells_batch);
  if (a.cells_composite != "auto" && a.cells_composite != "group" && a.cells_composite != "serial")
    throw Error("--cells-composite must be auto, group or serial");
  settings.cells.composite = a.cells_composite;
  if (a.order_masks != "auto" && a.order_masks != "host" && a.order_masks != "device")
    throw Error("--order-masks must be auto, host or device");
  settings.cells.order_masks = a.order_masks;
  if (a.tile_segments != "auto" && a.tile_segments != "on" && a.tile_segments != "off")
    throw Error("--tile-segments must be auto, on or off");
  settings.cells.tile_segments = a.tile_segments;
  checkTileKernels(a.tile_kernels);
  settings.tile_kernels = a.tile_kernels;
  settings.cell_cache_dir = a.cache;
  settings.octree = a.octree;
  if (!(a.memory_budget_mb >= 0.0 && a.memory_budget_mb < 1e9))
    throw Error("--memory-budget must be a number of megabytes >= 0");
  settings.memory_budget = uint64_t(a.memory_budget_mb * 1024.0 * 1024.0);
  if (a.octree.leaf_triangles < 1) throw Error("--leaf-tris must be at least 1");
  settings.batch = parseBatch(a.batch);
  settings.sort = parseDrawSort(a.sort);
  if (a.sigma_given && !(a.sigma >= 0.0f && std::isfinite(a.sigma)))
    throw Error("--sigma must be a finite number >= 0 (absorption per world unit)");

  if (a.distributed) {
    if (a.method_given && a.methods != "octree")
      throw Error("--distributed renders with the octree method (-m octree)");
    if (a.orbit != 0.0f) throw Error("--orbit: a distributed render has a still view");
    DistributedJob job;
    job.scene = a.scene;
    job.output = a.output;
    job.stats = a.stats;
    job.cache = a.cache;
    job.alpha = a.alpha;
    job.sigma_given = a.sigma_given;
    if (a.sigma_given) settings.sigma = a.sigma;
    job.settings = settings;
    job.camera = [&a](const Scene& scene) {
      return sceneCamera(scene, a.view, a.ortho, a.perspective, a.fov);
    };
    job.view_options = a.view + (a.ortho ? " ortho" : "") + (a.perspective ? " perspective" : "") +
                       " fov " + std::to_string(a.fov);
    job.device = DeviceOptions{deviceSpec(a.device)};
    job.fail_rank = a.fail_rank;
    job.fail_rank_late = a.fail_rank_late;
    if (!(a.rank_timeout == 0.0 || (a.rank_timeout >= 1.0 && a.rank_timeout <= 1e6)))
      throw Error("--rank-timeout must be 0 (wait forever) or between 1 and 1000000 seconds");
    job.rank_timeout_s = a.rank_timeout;
    checkWritable(a.output, "the image");
    checkWritable(a.stats, "the statistics");
    checkSettings(methodInfo(Method::Octree), settings);
    return runDistributedRender(job);
  }

  std::vector<Method> methods;
  if (a.methods == "all") {
    for (const std::string& m : methodNames()) methods.push_back(parseMethod(m));
  } else {
    std::stringstream ss(a.methods);
    for (std::string m; std::getline(ss, m, ',');) methods.push_back(parseMethod(m));
  }
  if (methods.empty()) throw Error("--method: no method given");
  // Runs: every method, with every --atlas mode given (a comma list compares them side by side).
  std::vector<AtlasChoice> atlases;
  {
    std::stringstream ss(a.atlas);
    for (std::string m; std::getline(ss, m, ',');) atlases.push_back(parseAtlasChoice(m));
    if (atlases.empty()) throw Error("--atlas: no mode given");
  }
  struct Run {
    Method method;
    AtlasChoice atlas;
    std::string label;
  };
  std::vector<Run> runs;
  for (Method m : methods)
    for (AtlasChoice at : atlases)
      runs.push_back(
          {m, at, atlases.size() == 1 ? methodName(m) : methodName(m) + "-" + atlasChoiceName(at)});
  std::vector<std::string> outputs;
  for (const Run& r : runs)
    outputs.push_back(a.output.empty()   ? ""
                      : runs.size() == 1 ? a.output
                                         : withSuffix(a.output, r.label));
  for (const std::string& o : outputs) checkWritable(o, "the image");
  checkWritable(a.stats, "the statistics");

  Scene scene = loadScene(a.scene);
  if (!a.texture.empty()) applyTexture(scene, a.texture);
  const WorldGeometry geometry = WorldGeometry::fromScene(scene, a.alpha);
  settings.camera = sceneCamera(scene, a.view, a.ortho, a.perspective, a.fov);
  settings.sigma = a.sigma_given ? a.sigma : 1.0f / std::max(scene.boundingSphere().radius, 1e-6f);
  for (Method m : methods) {
    try {
      checkSettings(methodInfo(m), settings);  // before any loading or rendering
    } catch (const Error& e) {
      // checkSettings names the method itself ("ppll: ..."); the option is named before it.
      const std::string message = e.what();
      throw Error("--method " + (message.rfind(methodName(m) + ":", 0) == 0
                                     ? message
                                     : methodName(m) + ": " + message));
    }
  }
  const LoadReport& r = scene.report;
  if (r.dropped_nonfinite || r.dropped_out_of_range || r.dropped_degenerate)
    std::cerr << "strata: " << printableMessage(a.scene) << ": dropped " << r.dropped_nonfinite
              << " non-finite, " << r.dropped_out_of_range << " out-of-range and "
              << r.dropped_degenerate << " zero-area triangles\n";
  for (const std::string& w : r.warnings)
    std::cerr << "strata: " << printableMessage(a.scene + ": " + w) << "\n";

  nlohmann::json all_stats = nlohmann::json::array();
  std::printf("%-8s %10s %10s %10s %10s %12s %10s  %s\n", "method", "median_ms", "mean_ms",
              "min_ms", "max_ms", "fragments", "max_depth", "output");
  const bool show_progress = isatty(STDERR_FILENO);
  for (size_t i = 0; i < runs.size(); ++i) {
    std::unique_ptr<MethodRenderer> renderer =
        makeRenderer(runs[i].method, DeviceOptions{deviceSpec(a.device)});
    settings.atlas = runs[i].atlas;
    if (show_progress) {
      // A progress bar on the terminal only; redirected output stays clean.
      const std::string name = runs[i].label;
      settings.on_frame = [name](int done, int total) {
        const int width = 30, filled = done * width / total;
        std::fprintf(stderr, "\r%-8s [%s%s] %d/%d frames", name.c_str(),
                     std::string(filled, '#').c_str(), std::string(width - filled, '.').c_str(),
                     done, total);
        if (done == total) std::fprintf(stderr, "\r%*s\r", 60, "");
        std::fflush(stderr);
      };
    }
    RenderResult result;
    try {
      result = renderer->render(geometry, settings);
    } catch (const Error& e) {
      // A method's complaint about the scene (or a memory it cannot have) names the scene.
      if (std::string(e.what()).rfind(a.scene + ":", 0) == 0) throw;
      const std::string message = a.scene + ": " + e.what();
      if (dynamic_cast<const OutOfMemory*>(&e)) throw OutOfMemory(message);
      throw Error(message);
    }
    if (!outputs[i].empty()) writeImage(result.image, outputs[i]);
    const FrameStats& s = result.stats;
    std::printf("%-8s %10.2f %10.2f %10.2f %10.2f %12llu %10llu  %s\n", runs[i].label.c_str(),
                s.frame_ms.median, s.frame_ms.mean, s.frame_ms.min, s.frame_ms.max,
                (unsigned long long)s.fragments, (unsigned long long)s.max_depth_complexity,
                outputs[i].c_str());
    std::fflush(stdout);
    if (s.fragments_lost > 0)
      std::cerr << "strata: warning: " << runs[i].label << " dropped " << s.fragments_lost
                << (runs[i].method == Method::Octree
                        ? " fragments in tiles whose walks reached --octree-tile-reads"
                        : " fragments at pixels deeper than it could hold")
                << ", so its image is not exact there (fragments_lost in --stats)\n";
    all_stats.push_back(statsToJson(s, a.scene));
  }
  if (!a.stats.empty())
    writeTextFileAtomically(a.stats,
                            (all_stats.size() == 1 ? all_stats[0] : all_stats).dump(2) + "\n");
  return 0;
}

struct PrepArgs {
  std::string scene, output, decompose = "strict", cache;
  std::string export_ply;  // --export: the cells as a mesh coloured per cell
  bool json = false;
  bool octree = false;  // --octree: the octree method's tree instead of the cells
  uint32_t leaf_tris = kDefaultLeafTriangles;
};

// Every instance's triangles in world space, as one mesh.
MeshView worldMesh(const WorldGeometry& g) {
  return {g.positions.data(), g.positions.size(), g.indices.data(), g.triangleCount()};
}

// A progress bar on the terminal only; redirected output stays clean.
std::function<void(double)> progressBar(const std::string& what) {
  if (!isatty(STDERR_FILENO)) return {};
  return [what, last = -1](double f) mutable {
    const int percent = int(f * 100.0);
    if (percent == last) return;
    last = percent;
    const int width = 30, filled = percent * width / 100;
    std::fprintf(stderr, "\r%s [%s%s] %3d%%", what.c_str(), std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), percent);
    if (percent >= 100) std::fprintf(stderr, "\r%*s\r", int(what.size()) + 40, "");
    std::fflush(stderr);
  };
}

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
    const std::string copies =
        cells.copy_cells ? " " + std::to_string(cells.copy_cells) +
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

// export: the scene's triangles in world space, every instance, as one PLY or OBJ mesh.
int runExport(const std::string& scene_spec, const std::string& output) {
  checkWritable(output, "the mesh");
  const Scene scene = loadScene(scene_spec);
  const WorldGeometry geometry = inCore(WorldGeometry::fromScene(scene));
  const MeshView world = worldMesh(geometry);
  writeMeshFile(output, world);
  std::printf("%s: %u triangles, %zu vertices written to %s\n", scene_spec.c_str(),
              geometry.triangleCount(), geometry.positions.size(), output.c_str());
  return 0;
}

int runDiff(const std::string& a_path, const std::string& b_path, bool json,
            const std::string& out) {
  checkWritable(out, "the difference image");
  const Image a = readImage(a_path), b = readImage(b_path);
  const ImageDiff d = compareImages(a, b);
  if (!out.empty()) writeImage(differenceImage(a, b), out);
  if (json) {
    nlohmann::json j;
    j["a"] = a_path;
    j["b"] = b_path;
    j["pixels"] = d.pixels;
    j["psnr_db"] = std::isinf(d.psnr) ? nlohmann::json("inf") : nlohmann::json(d.psnr);
    j["max_abs_error"] = d.max_abs;
    j["mean_abs_error"] = d.mean_abs;
    j["within_1"] = d.within_1;
    j["within_2"] = d.within_2;
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("pixels          %llu\n", (unsigned long long)d.pixels);
    if (std::isinf(d.psnr))
      std::printf("psnr            inf (identical)\n");
    else
      std::printf("psnr            %.2f dB\n", d.psnr);
    std::printf(
        "max abs error   %d/255\nmean abs error  %.4f/255\nwithin 1/255    %.4f%%\n"
        "within 2/255    %.4f%%\n",
        d.max_abs, d.mean_abs, 100.0 * d.within_1, 100.0 * d.within_2);
  }
  return 0;
}

// The benchmark's meshes: beside an installed program (PREFIX/share/strata/models, as `cmake
// --install` puts them), else in the source tree it was built from.
std::string defaultModelsDir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const std::filesystem::path installed = exe.parent_path().parent_path() / "share/strata/models";
    if (std::filesystem::is_directory(installed, ec)) return installed.string();
  }
  return STRATA_SOURCE_DIR "/tests/models";
}

int runBenchCommand(BenchOptions bo, const std::string& methods, const std::string& batch,
                    const std::string& sort, const std::string& atlas) {
  bo.batch = parseBatch(batch);
  bo.atlas = parseAtlasChoice(atlas);
  bo.sort = parseDrawSort(sort);
  checkTileKernels(bo.tile_kernels);
  std::stringstream ss(methods);
  for (std::string m; std::getline(ss, m, ',');)
    if (!m.empty()) bo.methods.push_back(m);
  if (bo.models_dir.empty()) {
    const char* env = std::getenv("STRATA_MODELS_DIR");
    bo.models_dir = env && *env ? env : defaultModelsDir();
  }
  if (bo.frames != 0) checkFrameCount(bo.frames, "--frames");  // 0: the suite's own
  if (!(std::fabs(bo.orbit_deg) <= 360.0f))
    throw Error("--orbit must be between -360 and 360 degrees per frame (0: still views only)");
  if (isatty(STDERR_FILENO)) {
    bo.on_progress = [](int done, int total, const std::string& what) {
      const int width = 30, filled = total ? done * width / total : width;
      std::fprintf(stderr, "\r\033[K[%s%s] %d/%d %s", std::string(filled, '#').c_str(),
                   std::string(width - filled, '.').c_str(), done, total, what.c_str());
      std::fflush(stderr);
    };
  }
  const BenchResult r = runBench(bo);
  if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\r\033[K");
  std::cout << benchMarkdown(r);
  std::cout << "wrote " << bo.out_dir << "/results.json, results.csv, results.md, report.html\n";
  return 0;
}

// ---- pick ----------------------------------------------------------------------------------

struct PickArgs {
  std::string scene;
  std::vector<std::string> at;
  std::string rect;
  std::string size = "512x512";
  std::string view;
  std::string device;
  float fov = 40.0f;
  float alpha = -1.0f;
  bool alpha_given = false;
  bool ortho = false;
  bool perspective = false;
  bool all_layers = false;
  bool json = false;
};

// Whole numbers separated by commas ("X,Y"), exactly `count` of them.
// Comma-separated whole numbers; exactly `count` of them (0: any number, at least one).
std::vector<int> parseIntList(const std::string& text, size_t count, const std::string& option,
                              const std::string& form) {
  std::vector<int> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    size_t used = 0;
    long v = 0;
    try {
      v = std::stol(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != item.size() || v < -1000000000L || v > 1000000000L)
      throw Error(option + " '" + text + "': expected " + form);
    out.push_back(int(v));
  }
  if ((count ? out.size() != count : out.empty()) || (!text.empty() && text.back() == ','))
    throw Error(option + " '" + text + "': expected " + form);
  return out;
}

// The camera `render` uses for the same scene, --view, --ortho/--perspective and --fov.
Camera pickCamera(const Scene& scene, const PickArgs& a) {
  return sceneCamera(scene, a.view, a.ortho, a.perspective, a.fov);
}

nlohmann::json vecJson(const glm::vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

nlohmann::json fragmentJson(const PickFragment& f, bool layer) {
  nlohmann::json j;
  j["object"] = f.object;
  j["name"] = f.name;
  j["triangle"] = f.triangle;
  j["depth"] = f.depth;
  j["position"] = vecJson(f.position);
  j["normal"] = vecJson(f.normal);
  j["facing"] = f.front_facing ? "front" : "back";
  if (layer) {
    j["opacity"] = f.opacity;
    j["transmittance"] = f.transmittance;
  }
  return j;
}

std::string vecText(const glm::vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "(%.4g, %.4g, %.4g)", v.x, v.y, v.z);
  return buf;
}

int runPick(const PickArgs& a) {
  FrameSettings settings;
  parseSize(a.size, settings.width, settings.height);
  if (!(a.fov > 1.0f && a.fov < 179.0f)) throw Error("--fov must be between 1 and 179 degrees");
  if (a.alpha_given && !(a.alpha >= 0.0f && a.alpha <= 1.0f))
    throw Error("--alpha must be in 0..1");
  if (a.at.empty() && a.rect.empty())
    throw Error("pick: nothing to pick: give --at X,Y (one or more) or --rect X0,Y0,X1,Y1");
  std::vector<glm::ivec2> pixels;
  for (const std::string& text : a.at) {
    const std::vector<int> v = parseIntList(text, 2, "--at", "X,Y (whole pixel numbers)");
    if (v[0] < 0 || v[1] < 0 || v[0] >= settings.width || v[1] >= settings.height)
      throw Error("--at " + text + " is outside the " + std::to_string(settings.width) + "x" +
                  std::to_string(settings.height) + " image (x 0.." +
                  std::to_string(settings.width - 1) + ", y 0.." +
                  std::to_string(settings.height - 1) + ")");
    pixels.emplace_back(v[0], v[1]);
  }
  PickRect rect;
  if (!a.rect.empty()) {
    const std::vector<int> v =
        parseIntList(a.rect, 4, "--rect", "X0,Y0,X1,Y1 (whole pixel numbers)");
    rect = {v[0], v[1], v[2], v[3]};
    try {
      validatePickRect(rect, settings.width, settings.height);
    } catch (const Error& e) {
      throw Error(std::string("--rect: ") + e.what());
    }
  }

  const Scene scene = loadScene(a.scene);
  const WorldGeometry geometry =
      inCore(WorldGeometry::fromScene(scene, a.alpha_given ? a.alpha : -1.0f));
  settings.camera = pickCamera(scene, a);
  const ObjectNames names = objectNames(scene);
  IdPicker picker(DeviceOptions{deviceSpec(a.device)});
  picker.update(geometry, settings, a.all_layers);
  const PickResult picked = picker.pick(pixels, &names);
  std::vector<uint32_t> in_rect;
  if (!a.rect.empty()) in_rect = picker.objectsInRect(rect);
  const auto nameOf = [&](uint32_t id) {
    const auto it = names.find(id);
    return it == names.end() ? std::string() : it->second;
  };

  if (a.json) {
    nlohmann::json j;
    j["scene"] = a.scene;
    j["size"] = {settings.width, settings.height};
    j["device"] = picker.device();
    j["picks"] = nlohmann::json::array();
    for (const PickedPixel& p : picked.pixels) {
      nlohmann::json pj;
      pj["pixel"] = {p.pixel.x, p.pixel.y};
      pj["hit"] = p.status == PickStatus::Hit;
      pj["status"] = pickStatusName(p.status);
      if (p.status == PickStatus::Hit) pj["front"] = fragmentJson(p.front, false);
      if (a.all_layers) {
        pj["layers"] = nlohmann::json::array();
        for (const PickFragment& f : p.layers) pj["layers"].push_back(fragmentJson(f, true));
      }
      j["picks"].push_back(pj);
    }
    if (!a.rect.empty()) {
      nlohmann::json rj;
      rj["rect"] = {rect.x0, rect.y0, rect.x1, rect.y1};
      rj["objects"] = nlohmann::json::array();
      for (uint32_t id : in_rect) rj["objects"].push_back({{"object", id}, {"name", nameOf(id)}});
      j["rect"] = rj;
    }
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }

  for (const PickedPixel& p : picked.pixels) {
    const std::string at = std::to_string(p.pixel.x) + "," + std::to_string(p.pixel.y);
    if (p.status != PickStatus::Hit) {
      std::printf("%-11s no object (background)\n", at.c_str());
      continue;
    }
    const PickFragment& f = p.front;
    std::printf(
        "%-11s object %u \"%s\"  triangle %u  depth %.6g  position %s  normal %s  %s-facing\n",
        at.c_str(), f.object, f.name.c_str(), f.triangle, f.depth, vecText(f.position).c_str(),
        vecText(f.normal).c_str(), f.front_facing ? "front" : "back");
    if (!a.all_layers) continue;
    std::printf("  %5s %10s %-20s %10s %12s %6s %8s %13s\n", "layer", "object", "name", "triangle",
                "depth", "facing", "opacity", "transmittance");
    for (size_t k = 0; k < p.layers.size(); ++k) {
      const PickFragment& l = p.layers[k];
      std::printf("  %5zu %10u %-20s %10u %12.6g %6s %8.3f %13.6f\n", k, l.object, l.name.c_str(),
                  l.triangle, l.depth, l.front_facing ? "front" : "back", l.opacity,
                  l.transmittance);
    }
  }
  if (!a.rect.empty()) {
    std::printf("rect %d,%d,%d,%d: %zu object%s\n", rect.x0, rect.y0, rect.x1, rect.y1,
                in_rect.size(), in_rect.size() == 1 ? "" : "s");
    for (uint32_t id : in_rect) std::printf("  object %u \"%s\"\n", id, nameOf(id).c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Ctrl-C or a kill during a long render or write leaves no temporary files behind.
  strata::removeTemporaryFilesOnSignals();
  CLI::App app{
      "strata: exact order-independent transparency with OpenCL kernels (PoCL on CPUs, "
      "any OpenCL GPU), checked against an Embree reference"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("strata ") + STRATA_VERSION);

  std::string device;
  CLI::App* info = app.add_subcommand(
      "info", "OpenCL platforms and devices, the chosen device, extensions used");
  info->add_option(
      "--device", device,
      "device index or name substring (default: STRATA_DEVICE, else a GPU, else the first device)");

  RenderArgs ra;
  CLI::App* render = app.add_subcommand("render", "render a scene with one or more methods");
  render
      ->add_option("scene", ra.scene,
                   "a mesh file (OBJ+MTL, PLY, OFF, STL, glTF 1.0/2.0, GLB), an octree scene "
                   "(FILE.octree from prep --octree -o: octree streams it from disk, "
                   "other methods read it whole) or builtin:demo, builtin:spheres:N, "
                   "builtin:crowd:N, builtin:textured:N, builtin:hairball:N, builtin:city:N, "
                   "builtin:shells:N, builtin:soup:N, builtin:grid:N")
      ->capture_default_str();
  render->add_option("-m,--method", ra.methods, methodHelp())->capture_default_str();
  render->add_option("-s,--size", ra.size, "image size WIDTHxHEIGHT")->capture_default_str();
  render->add_option("--view", ra.view,
                     "AZ,EL[,DIST]: degrees around the scene's bounding sphere, DIST in its radii "
                     "(default: the scene's own view, auto-framed)");
  render->add_option(
      "-o,--output", ra.output,
      "output image (PNG, EXR, ... by extension); several methods write NAME-METHOD.EXT");
  render->add_option("--stats", ra.stats, "write frame statistics as JSON to this file");
  render->add_option("--frames", ra.frames, "frames to render; times are over all of them")
      ->capture_default_str();
  render->add_option("--orbit", ra.orbit,
                     "DEG: a moving camera, turned DEG degrees of azimuth per frame about the "
                     "scene's vertical axis (distance and elevation kept), so each of --frames is "
                     "a new view and its time includes all per-view work; the image is the last "
                     "frame's (default 0: a still view)");
  render
      ->add_option("--k", ra.k,
                   "per-pixel layer budget of abuffer, mdts and mdts32 (fragments past it are "
                   "counted as lost)")
      ->capture_default_str();
  render->add_option("--alpha", ra.alpha,
                     "opacity of every material, 0..1 (default: per material, 0.5)");
  render->add_option("--background", ra.background, "checker, #rrggbb or r,g,b")
      ->capture_default_str();
  render->add_option("--fov", ra.fov, "vertical field of view in degrees")->capture_default_str();
  render->add_flag("--ortho", ra.ortho, "orthographic projection (default for builtin:spheres:N)");
  render->add_flag("--perspective", ra.perspective,
                   "perspective projection (default for every other scene)");
  render->add_option("--device", ra.device,
                     "OpenCL device index or name substring (also STRATA_DEVICE)");
  render
      ->add_option("--effect", ra.effect,
                   "transparency (every method) or translucency (the methods marked [translucency] "
                   "under --method): Beer-Lambert absorption between entering and leaving "
                   "fragments with Schlick Fresnel")
      ->capture_default_str();
  render->add_option("--sigma", ra.sigma,
                     "translucency: absorption coefficient per world unit (default: 1 / the "
                     "scene's bounding radius)");
  render
      ->add_option("--decompose", ra.decompose,
                   "cells: convex decomposition test, strict (exact) or paper (the paper's local "
                   "test, for comparison)")
      ->capture_default_str();
  render
      ->add_option("--order-ahead", ra.order_ahead,
                   "cells with --orbit: on: order the next frame's view on a host thread while "
                   "the device draws the current one (same images; off: each frame orders its "
                   "own view first)")
      ->capture_default_str();
  render
      ->add_option("--order-reuse", ra.order_reuse,
                   "cells with --orbit: N: a frame may be drawn with the order of a view up to N "
                   "frames before its own, checked pixel by pixel as it is composited and its "
                   "failing pixels composited again with every fragment sorted (exact either way; "
                   "0: every frame orders its own view)")
      ->capture_default_str();
  render
      ->add_option("--cells-batch", ra.cells_batch,
                   "cells: triangles set up, binned and composited per batch, in visibility "
                   "order (each batch about 150 bytes of device memory per triangle; a frame of "
                   "several batches carries each pixel's result between them, and only a frame "
                   "of one batch may reuse an earlier view's order)")
      ->capture_default_str();
  render
      ->add_option("--order-masks", ra.order_masks,
                   "cells: where the per-view order finds which cells share a pixel centre "
                   "(their pixel masks and pairs): host, device (kernels; cells spanning more "
                   "than 32 pixels keep their masks on the host) or auto (the host: the "
                   "device's were not faster on a GPU); the same order either way")
      ->capture_default_str();
  render
      ->add_option("--tile-segments", ra.tile_segments,
                   "cells, group composite: on: the order lists, per view and screen tile, the "
                   "runs of passes that share no pixel there, each composited as one segment; "
                   "off: each pass a segment of its own (less work per view, more composite "
                   "steps); auto: off with --orbit, else on. Same images")
      ->capture_default_str();
  render
      ->add_option("--tile-kernels", ra.tile_kernels,
                   "how per-tile kernels run where a method has both forms: group (a "
                   "work-group per tile, for GPUs), serial (a work-item alone per tile, no "
                   "barriers, for CPUs) or auto (serial on PoCL's CPU devices); the images and "
                   "counts are the same (abuffer: while no pixel has more than k fragments)")
      ->capture_default_str();
  render
      ->add_option("--cells-composite", ra.cells_composite,
                   "cells: the composite kernel, group (a work-group per block of tiles, for "
                   "GPUs), serial (a work-item per block, no barriers, for CPUs) or auto (as "
                   "--tile-kernels); the images are the same")
      ->capture_default_str();
  render->add_option("--cache", ra.cache,
                     "cells and octree: folder of their cache files (default: "
                     "$XDG_CACHE_HOME/strata/cells and $XDG_CACHE_HOME/strata/octree)");
  render
      ->add_option("--octree-variant", ra.octree.variant,
                   "octree: kbuffer (each leaf's fragments k at a time), blocks-histogram (per "
                   "leaf a coverage walk, then exactly that many peels: the paper's method), "
                   "blocks (per leaf, peel until nothing is left), histogram and dp (the whole "
                   "scene as one block, for comparison)")
      ->capture_default_str();
  render->add_option("--leaf-tris", ra.octree.leaf_triangles, "octree: the face limit of a leaf")
      ->capture_default_str();
  render->add_option("--memory-budget", ra.memory_budget_mb,
                     "device memory a frame may use in MB, scene and image included (0: no "
                     "bound): octree and cells keep within it, streaming their triangles in "
                     "batches sized to it; the other OpenCL methods fail with what they needed");
  render->add_flag("--distributed", ra.distributed,
                   "one process of an MPI job (mpirun -np P strata render ... --distributed): the "
                   "scene's octree split into P boxes of balanced triangles, each process "
                   "rendering its own box's leaves with the octree method (reading only those "
                   "from the octree scene, which rank 0 writes into the cache for a mesh), the "
                   "shares composited in visibility order by MPI collectives; rank 0 writes the "
                   "image and per-rank statistics (transparency and translucency)");
  render->add_option("--rank-timeout", ra.rank_timeout,
                     "--distributed: seconds a rank may go without answering while another "
                     "waits for it (a busy rank still answers); then every rank gives up with one "
                     "line naming it (0: wait forever)")
      ->capture_default_str();
  render->add_option("--fail-rank", ra.fail_rank, "testing: this rank fails during its render")
      ->group("");
  render->add_option("--fail-rank-late", ra.fail_rank_late,
                     "testing: this rank alone fails before the composite")
      ->group("");
  render->add_flag("--octree-early-out", ra.octree.early_out,
                   "octree: stop at a pixel once less than 0.5/255 of the light gets through, "
                   "and skip leaves behind tiles of such pixels (image within 1/255; fragment "
                   "counts are then those composited)");
  render
      ->add_option("--octree-tile-reads", ra.octree.tile_reads,
                   "octree: the most triangle references the walks of one 8x8 screen tile may "
                   "read; past it each leaf takes only its nearest k fragments per pixel and the "
                   "ones behind are counted lost, with a warning. Only leaves the tree cannot "
                   "split (thousands of coincident or stacked faces) come near it (0: no bound)")
      ->capture_default_str();
  render->add_flag("--octree-stream", ra.octree.stream,
                   "octree: stream the triangles per batch even when they fit (to measure it)");
  render
      ->add_option("--octree-k", ra.octree.k,
                   "octree kbuffer: fragments per pixel a walk over a leaf takes (1..64); "
                   "never loses fragments, deeper pixels take more walks")
      ->capture_default_str();
  render
      ->add_option("--batch", ra.batch,
                   "draw units of the OpenCL front end: none (one per instance and material), "
                   "static (merged per material), instanced (mesh once + per-instance buffer), "
                   "auto (instanced when a mesh has many instances); never changes the image")
      ->capture_default_str();
  render->add_option(
      "--texture", ra.texture,
      "an image (PNG, JPEG, ...) used as the base-colour texture of every untextured material "
      "whose mesh has texture coordinates, e.g. spot.obj with spot_texture.png");
  render
      ->add_option("--atlas", ra.atlas,
                   "textured scenes: packed (stb_rect_pack into shared pages), uniform (equal "
                   "slots), off (a page per texture and one front-end launch per texture, for "
                   "comparison); a comma list renders each, side by side; never changes the image")
      ->capture_default_str();
  render
      ->add_option("--sort", ra.sort,
                   "order the draw units are drawn in: none | material | depth | gray | key; never "
                   "changes the image")
      ->capture_default_str();

  std::string diff_a, diff_b, diff_out;
  bool diff_json = false;
  PrepArgs pa;
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

  std::string export_scene, export_output;
  CLI::App* export_cmd = app.add_subcommand(
      "export", "write a scene's triangles (every instance, world space) as one .ply or .obj mesh");
  export_cmd->add_option("scene", export_scene, "a mesh file or builtin:NAME")->required();
  export_cmd->add_option("-o,--output", export_output, "the mesh file (.ply: binary; .obj: text)")
      ->required();

  CLI::App* diff = app.add_subcommand(
      "diff", "compare two images: PSNR, max/mean error, pixels within 1 and 2 of 255");
  diff->add_option("a", diff_a, "first image")->required();
  diff->add_option("b", diff_b, "second image")->required();
  diff->add_flag("--json", diff_json, "print JSON");
  diff->add_option("--out", diff_out, "write a difference image (|a-b| x 8)");

  BenchOptions bo;
  std::string bench_methods, bench_batch = "static", bench_sort = "none", bench_atlas = "packed";
  CLI::App* bench = app.add_subcommand(
      "bench",
      "run a benchmark suite: methods x scenes x views, every image checked against embree; writes "
      "results.json, results.csv, results.md and report.html");
  bench
      ->add_option(
          "--suite", bo.suite,
          "smoke | paper-table1 | paper-table2 | paper-table3 | textures | octree | raster")
      ->capture_default_str();
  bench->add_option(
      "--methods", bench_methods,
      "comma-separated methods, octree/VARIANT for an octree variant (default: the suite's)");
  bench->add_option("--out", bo.out_dir, "output folder")->capture_default_str();
  bench->add_option("--frames", bo.frames, "frames per case (default: the suite's)");
  bench
      ->add_option("--orbit", bo.orbit_deg,
                   "DEG: every case also rendered with a moving camera turning DEG degrees per "
                   "frame (the 'moving' column; 0: still views only)")
      ->capture_default_str();
  bench->add_option("--models", bo.models_dir,
                    "folder of the shared models (default: STRATA_MODELS_DIR, else "
                    "PREFIX/share/strata/models beside an installed strata, else the source "
                    "tree's tests/models)");
  bench->add_option("--device", bo.device,
                    "OpenCL device index or name substring (also STRATA_DEVICE)");
  bench
      ->add_option("--batch", bench_batch,
                   "draw units: none | static | instanced | auto (as for render)")
      ->capture_default_str();
  bench
      ->add_option("--sort", bench_sort,
                   "draw order: none | material | depth | gray | key (as for render)")
      ->capture_default_str();
  bench
      ->add_option("--tile-kernels", bo.tile_kernels,
                   "per-tile kernels: auto | group | serial (as for render)")
      ->capture_default_str();
  bool bench_distributed = false, bench_soak = false;
  std::string bench_processes = "1,2,3,4", bench_scenes, bench_size = "640x480";
  bench->add_flag("--distributed", bench_distributed,
                  "the distributed scaling table instead of a suite: each scene rendered by "
                  "mpirun -np P strata render --distributed for every P (docs/distributed.md)");
  bench->add_flag("--soak", bench_soak,
                  "a soak run instead of a suite: --frames (default 10000) frames of a moving "
                  "camera (--orbit) per method on the first of --scenes (default builtin:demo) at "
                  "--size (default 128x128), host RSS and device buffers sampled every 100 "
                  "frames; writes soak.json and soak.md (docs/robustness.md)");
  bench->add_option("--processes", bench_processes, "--distributed: process counts")
      ->capture_default_str();
  bench->add_option("--scenes", bench_scenes,
                    "--distributed: comma-separated scenes (default: builtin:hairball, "
                    "builtin:city, builtin:shells); --soak: its scene");
  bench->add_option("--size", bench_size, "--distributed, --soak: image size WIDTHxHEIGHT")
      ->capture_default_str();
  bench->add_option("--atlas", bench_atlas, "textures: packed | uniform | off (as for render)")
      ->capture_default_str();

  PickArgs pk;
  CLI::App* pick = app.add_subcommand(
      "pick",
      "ID picking: the front-most object at pixels (object id and name, triangle, depth, world "
      "position, normal), every fragment under them, or the objects seen in a rectangle");
  pick->add_option("scene", pk.scene, "a mesh file or builtin:NAME")->required();
  pick->add_option("--at", pk.at, "X,Y: a pixel (0,0 is the top-left); repeat for more")
      ->allow_extra_args(false);
  pick->add_option(
      "--rect", pk.rect,
      "X0,Y0,X1,Y1: also list the objects front-most in this rectangle (corners inclusive)");
  pick->add_flag("--all-layers", pk.all_layers,
                 "every fragment under each pixel, nearest first (object, triangle, depth, facing, "
                 "opacity, transmittance in front)");
  pick->add_flag("--json", pk.json, "print JSON");
  pick->add_option("-s,--size", pk.size, "image size WIDTHxHEIGHT (as for render)")
      ->capture_default_str();
  pick->add_option("--view", pk.view, "AZ,EL[,DIST] (as for render)");
  pick->add_option("--fov", pk.fov, "vertical field of view in degrees")->capture_default_str();
  pick->add_option("--alpha", pk.alpha, "opacity of every material, 0..1 (default: per material)");
  pick->add_flag("--ortho", pk.ortho, "orthographic projection");
  pick->add_flag("--perspective", pk.perspective, "perspective projection");
  pick->add_option("--device", pk.device,
                   "OpenCL device index or name substring (also STRATA_DEVICE)");

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);  // --help
    // One line, as every other error.
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    std::cerr << "strata: error: " << printableMessage(what)
              << " (strata --help lists the options)\n";
    return 1;
  }
  pk.alpha_given = pick->count("--alpha") > 0;
  ra.alpha_given = render->count("--alpha") > 0;
  ra.method_given = render->count("--method") > 0;
  if (bench->count("--frames") > 0 && bo.frames < 1) bo.frames = -1;  // given as 0: refused
  ra.sigma_given = render->count("--sigma") > 0;
  try {
    if (*info) return printDeviceReport(deviceSpec(device));
    if (*render) return runRender(ra);
    if (*prep) return runPrep(pa);
    if (*export_cmd) return runExport(export_scene, export_output);
    if (*diff) return runDiff(diff_a, diff_b, diff_json, diff_out);
    if (*bench && bench_distributed) {
      DistributedBench db;
      db.out_dir = bo.out_dir;
      db.device = deviceSpec(bo.device);
      if (bo.frames != 0) checkFrameCount(bo.frames, "--frames");  // 0: the default
      if (bo.frames > 0) db.frames = bo.frames;
      parseSize(bench_size, db.width, db.height);
      db.processes = parseIntList(bench_processes, 0, "--processes", "P,P,... (process counts)");
      if (!bench_scenes.empty()) {
        db.scenes.clear();
        std::stringstream ss(bench_scenes);
        for (std::string sc; std::getline(ss, sc, ',');)
          if (!sc.empty()) db.scenes.push_back(sc);
      }
      return runDistributedBench(db);
    }
    if (*bench && bench_soak) {
      if (bench_distributed) throw Error("--soak and --distributed are separate runs");
      SoakOptions so;
      so.out_dir = bo.out_dir;
      so.device = deviceSpec(bo.device);
      if (bo.frames != 0) checkFrameCount(bo.frames, "--frames");  // 0: the default
      if (bo.frames > 0) so.frames = bo.frames;
      so.sample_every = std::min(so.sample_every, so.frames);
      if (bench->count("--size") > 0) parseSize(bench_size, so.width, so.height);
      if (!(std::fabs(bo.orbit_deg) <= 360.0f))
        throw Error("--orbit must be between -360 and 360 degrees per frame");
      so.orbit_deg = bo.orbit_deg;
      std::stringstream ms(bench_methods);
      for (std::string m; std::getline(ms, m, ',');)
        if (!m.empty()) so.methods.push_back(m);
      if (!bench_scenes.empty()) so.scene = bench_scenes.substr(0, bench_scenes.find(','));
      if (isatty(STDERR_FILENO))  // one progress bar per method
        so.on_progress = [bar = std::function<void(double)>(), method = std::string()](
                             const std::string& m, int done, int total) mutable {
          if (m != method) bar = progressBar(method = m);
          if (bar) bar(double(done) / double(total));
        };
      const std::vector<SoakRun> runs = runSoak(so);
      std::fputs(soakMarkdown(so, runs).c_str(), stdout);
      return 0;
    }
    if (*bench) {
      bo.device = deviceSpec(bo.device);
      return runBenchCommand(bo, bench_methods, bench_batch, bench_sort, bench_atlas);
    }
    if (*pick) return runPick(pk);
  } catch (const Error& e) {
    // In an MPI job every process meets the same bad option: rank 0 alone says so.
    if (*render && ra.distributed && !firstMpiProcess()) return 1;
    std::cerr << "strata: error: " << printableMessage(e.what()) << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    // What was being read or rendered, so the message names it.
    const std::string subject = *render       ? ra.scene
                                : *prep       ? pa.scene
                                : *pick       ? pk.scene
                                : *export_cmd ? export_scene
                                              : std::string("strata");
    std::cerr << "strata: error: " << printableMessage(subject)
              << ": out of memory (the scene or the image needs more memory than there is)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "strata: internal error: " << printableMessage(e.what()) << "\n";
    return 2;
  }
  return 0;
}
