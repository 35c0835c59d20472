// strata render: a scene rendered with one or more methods (or one process of a distributed
// render), images, a table of times and the statistics as JSON.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "engine/report/stats_json.h"
#include "engine/frontend/texture_shading.h"
#include "kernels/strata_shared.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/image_io.h"
#include "tools/cli/cli.h"
#include "tools/distributed_render.h"

namespace strata::cli {

namespace {

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

struct RenderArgs {
  std::string scene = "builtin:demo";
  std::string methods = "ppll";
  std::string size = "512x512";
  std::string view;
  std::string output;
  std::string stats;
  std::string background = "checker";
  std::string device, atomics;
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
  std::string wboit_weight = optionName(WboitOptions{}.weight);
  StochasticOptions stochastic;
  std::string tail = optionName(AbufferOptions{}.tail);
  std::string stochastic_correction = "on";
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
  try {
    settings.wboit.weight = parseWboitWeight(a.wboit_weight);
  } catch (const Error& e) {
    throw Error(std::string("--wboit-weight: ") + e.what());
  }
  try {
    settings.abuffer.tail = parseAbufferTail(a.tail);
  } catch (const Error& e) {
    throw Error(std::string("--tail: ") + e.what());
  }
  if (a.stochastic.samples < 1 || a.stochastic.samples > ST_STOCHASTIC_MAX_SAMPLES)
    throw Error("--samples must be between 1 and " + std::to_string(ST_STOCHASTIC_MAX_SAMPLES));
  if (a.stochastic_correction != "on" && a.stochastic_correction != "off")
    throw Error("--alpha-correction must be on or off");
  settings.stochastic = a.stochastic;
  settings.stochastic.alpha_correction = a.stochastic_correction == "on";
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
    job.device = deviceOptions(a.device, a.atomics);
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
      const std::string named = "--method " + (message.rfind(methodName(m) + ":", 0) == 0
                                                   ? message
                                                   : methodName(m) + ": " + message);
      // A view that cannot be framed comes from the scene's size as often as from --view: the
      // scene is named too.
      throw Error(message.find("the view's") != std::string::npos ? a.scene + ": " + named
                                                                   : named);
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
        makeRenderer(runs[i].method, deviceOptions(a.device, a.atomics));
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

}  // namespace

Command addRenderCommand(CLI::App& app) {
  auto args = std::make_shared<RenderArgs>();
  RenderArgs& ra = *args;
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
                   "counted as lost), the layers of mlab (past them merged) and hybrid (past them "
                   "averaged), and adaptive's visibility nodes (past them compressed)")
      ->capture_default_str();
  render->add_option("--alpha", ra.alpha,
                     "opacity of every material, 0..1 (default: per material, 0.5)");
  render->add_option("--background", ra.background, "checker, #rrggbb or r,g,b")
      ->capture_default_str();
  render->add_option("--fov", ra.fov, "vertical field of view in degrees")->capture_default_str();
  render->add_flag("--ortho", ra.ortho, "orthographic projection (default for builtin:spheres:N)");
  render->add_flag("--perspective", ra.perspective,
                   "perspective projection (default for every other scene)");
  addDeviceOptions(render, ra.device, ra.atomics);
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
      ->add_option("--wboit-weight", ra.wboit_weight,
                   "wboit: the paper's weight function w(z, a), eq7, eq8 or eq9 of the view "
                   "distance z in scene units (its constants suit scenes of a few to a few hundred "
                   "units) or eq10 of the depth-buffer value d = 1 - near/z (any scale)")
      ->capture_default_str();
  render
      ->add_option("--tail", ra.tail,
                   "abuffer: what becomes of a pixel's fragments past its k records: drop (lost "
                   "and counted, as published) or blend (blended order-independently into a tail "
                   "behind the k sorted ones)")
      ->capture_default_str();
  render
      ->add_option("--samples", ra.stochastic.samples,
                   "stochastic: coverage samples per pixel, 1..64 (noise falls as 1/sqrt of it)")
      ->capture_default_str();
  render
      ->add_option("--seed", ra.stochastic.seed,
                   "stochastic: the seed of the random coverage masks (a seed gives one image)")
      ->capture_default_str();
  render
      ->add_option("--alpha-correction", ra.stochastic_correction,
                   "stochastic: on: the paper's alpha correction (colour scaled to the exact "
                   "total opacity); off: the plain estimator, exact in expectation")
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
  render
      ->add_option("--rank-timeout", ra.rank_timeout,
                   "--distributed: seconds a rank may go without answering while another "
                   "waits for it (a busy rank still answers); then every rank gives up with one "
                   "line naming it (0: wait forever)")
      ->capture_default_str();
  render->add_option("--fail-rank", ra.fail_rank, "testing: this rank fails during its render")
      ->group("");
  render
      ->add_option("--fail-rank-late", ra.fail_rank_late,
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
  Command c;
  c.app = render;
  c.run = [args, render] {
    args->alpha_given = render->count("--alpha") > 0;
    args->method_given = render->count("--method") > 0;
    args->sigma_given = render->count("--sigma") > 0;
    return runRender(*args);
  };
  c.subject = [args] { return args->scene; };
  c.reports_errors = [args] { return !args->distributed || firstMpiProcess(); };
  return c;
}

}  // namespace strata::cli
