// Per-view cost of the cells method's ordering (engine/cells/cell_order.cpp) alone: each scene's cells
// are built (through the cache) and ordered for a camera turning
// --orbit degrees per view, as `render --orbit` does, and the time per view is printed with a
// fingerprint of the orders, so two builds can be compared view for view (the same fingerprint
// means the same groups, passes and tile segments, hence the same images). The steps' columns are
// the medians over the views of CellOrder's own step times (project, pairs, graph, segments,
// device); the tile segments are listed unless --no-segments (the renderer's moving camera and
// its serial composite skip them: --no-segments is their order);
// cpu_ms is the process's CPU time per view (all threads; on a machine whose cores also run the
// device, as PoCL's do, this is what a moving camera's frames pay). With --masks device the
// cells' pixel masks are computed by the OpenCL device's kernel (the same order: the same
// fingerprint), the rest on the host; the `device` column is the part of project and pairs spent
// in the device's calls (uploads, kernels, downloads).
//
//   strata_order_bench [--size WxH] [--views N] [--orbit DEG] [--rounds R] [--json]
//                      [--masks host|device] [--device SPEC] [--threads N] SCENE...
#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "engine/cells/cell_masks_device.h"
#include "engine/cells/cell_order.h"
#include "preprocess/builtin_scenes.h"
#include "strata/error.h"

namespace {

using namespace strata;

// FNV-1a over the parts of an order the device sees.
struct Fingerprint {
  uint64_t h = 1469598103934665603ull;
  void add(const std::vector<uint32_t>& v) {
    for (uint32_t x : v)
      for (int b = 0; b < 4; ++b) h = (h ^ ((x >> (8 * b)) & 0xFFu)) * 1099511628211ull;
  }
};

// CPU time of the whole process (every thread), ms.
double processCpuMs() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"strata_order_bench: the cells method's per-view ordering alone"};
  std::vector<std::string> scenes;
  std::string size = "1024x1024";
  int views = 20, rounds = 1;
  float orbit = 1.0f;
  bool json = false;
  app.add_option("scenes", scenes, "scenes (files or builtin:NAME)")->required();
  app.add_option("--size,-s", size, "WxH image size")->capture_default_str();
  app.add_option("--views", views, "views per round, the camera turned --orbit degrees each")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--orbit", orbit, "DEG: azimuth step between views")->capture_default_str();
  app.add_option("--rounds", rounds, "rounds over the same views (the minimum per view is kept)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_flag("--json", json, "one JSON object per scene instead of a table row");
  bool no_segments = false;
  app.add_flag("--no-segments", no_segments,
               "skip the tile segments (the order the serial composite draws)");
  std::string masks = "host", device_spec;
  app.add_option("--masks", masks, "where the cells' pixel masks are computed: host or device")
      ->capture_default_str()
      ->check(CLI::IsMember({"host", "device"}));
  app.add_option("--device", device_spec,
                 "OpenCL device for --masks device: index or name (default: STRATA_DEVICE, else "
                 "the first GPU, else the first device)");
  unsigned threads = 0;
  app.add_option("--threads", threads,
                 "threads the order uses at most (0: the default, the cores up to eight)")
      ->capture_default_str()
      ->check(CLI::Range(0u, 256u));
  CLI11_PARSE(app, argc, argv);
  try {
    setCellOrderThreads(threads);
    int width = 0, height = 0;
    if (std::sscanf(size.c_str(), "%dx%d", &width, &height) != 2 || width <= 0 || height <= 0 ||
        width > 16384 || height > 16384)
      throw Error("--size '" + size + "': expected WxH, each 1..16384");
    if (!json)
      std::printf("%-22s %7s %7s %6s %6s %8s %9s %8s %7s | %7s %7s %7s %8s %7s  %s\n", "scene",
                  "cells", "groups", "passes", "merged", "min_ms", "median_ms", "max_ms", "cpu_ms",
                  "project", "pairs", "graph", "segments", "device", "fingerprint");
    std::shared_ptr<ClRuntime> runtime;
    if (masks == "device") {
      const char* env = std::getenv("STRATA_DEVICE");
      runtime = ClRuntime::acquire(!device_spec.empty() ? device_spec : env ? env : "");
      if (!json) std::printf("masks on %s\n", runtime->info().label().c_str());
    }
    if (!json) {
      std::printf("order threads: %u of %u hardware threads\n", cellOrderThreads(),
                  std::thread::hardware_concurrency());
    }
    for (const std::string& spec : scenes) {
      const Scene scene = loadScene(spec);
      const WorldGeometry geometry = WorldGeometry::fromScene(scene);
      const CellScene cells = CellScene::build(geometry, DecomposeOptions{}, defaultCellCacheDir());
      std::unique_ptr<ClCellMasks> device_masks;
      if (runtime) device_masks = std::make_unique<ClCellMasks>(*runtime, cells);
      const Camera start =
          Camera::orbit(scene.boundingSphere(), scene.default_view.value_or(OrbitView{}),
                        scene.default_projection.value_or(Projection::Perspective), 40.0f);
      std::vector<double> best(size_t(views), 1e300), best_cpu(size_t(views), 1e300);
      // Per view, the steps of its fastest run: project, pairs, graph, segments, device.
      std::vector<std::array<double, 5>> steps(static_cast<size_t>(views));
      Fingerprint print;
      CellOrder last;
      for (int r = 0; r < rounds; ++r) {
        for (int v = 0; v < views; ++v) {
          const Camera camera = start.turned(float(v) * orbit);
          const double cpu0 = processCpuMs();
          const auto t0 = std::chrono::steady_clock::now();
          CellOrder order =
              orderCells(cells, camera, width, height, !no_segments, device_masks.get());
          const double ms =
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count();
          best_cpu[size_t(v)] = std::min(best_cpu[size_t(v)], processCpuMs() - cpu0);
          if (ms < best[size_t(v)]) {
            best[size_t(v)] = ms;
            steps[size_t(v)] = {order.project_ms, order.pairs_ms, order.graph_ms, order.segments_ms,
                                order.device_ms};
          }
          if (r == 0) {
            print.add(order.cells);
            print.add(order.group_first);
            print.add(order.group_pass);
            print.add(order.tile_break_first);
            print.add(order.tile_breaks);
          }
          last = std::move(order);
        }
      }
      auto median = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        return v[v.size() / 2];
      };
      std::array<double, 5> step_ms{};
      for (size_t k = 0; k < step_ms.size(); ++k) {
        std::vector<double> one;
        for (const auto& st : steps) one.push_back(st[k]);
        step_ms[k] = median(one);
      }
      const double lo = *std::min_element(best.begin(), best.end());
      const double hi = *std::max_element(best.begin(), best.end());
      const double mid = median(best);
      const double cpu_mid = median(best_cpu);
      char hex[17];
      std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(print.h));
      if (json) {
        nlohmann::json j = {{"scene", spec},
                            {"width", width},
                            {"height", height},
                            {"orbit_deg", orbit},
                            {"views", views},
                            {"rounds", rounds},
                            {"cells", cells.cellCount()},
                            {"groups", last.groupCount()},
                            {"passes", last.passes},
                            {"merged_groups", last.merged_groups},
                            {"pairs_tested", last.pairs_tested},
                            {"masks", masks},
                            {"device_mask_cells", last.device_mask_cells},
                            {"device_pairs", last.device_pairs},
                            {"order_ms", {{"min", lo}, {"median", mid}, {"max", hi}}},
                            {"cpu_ms_median", cpu_mid},
                            {"step_median_ms",
                             {{"project", step_ms[0]},
                              {"pairs", step_ms[1]},
                              {"graph", step_ms[2]},
                              {"segments", step_ms[3]},
                              {"device", step_ms[4]}}},
                            {"threads", cellOrderThreads()},
                            {"fingerprint", hex}};
        std::cout << j.dump() << "\n";
      } else {
        std::printf(
            "%-22s %7u %7u %6u %6u %8.3f %9.3f %8.3f %7.3f | %7.3f %7.3f %7.3f %8.3f %7.3f  %s\n",
            std::filesystem::path(spec).filename().string().c_str(), cells.cellCount(),
            last.groupCount(), last.passes, last.merged_groups, lo, mid, hi, cpu_mid, step_ms[0],
            step_ms[1], step_ms[2], step_ms[3], step_ms[4], hex);
      }
      std::fflush(stdout);
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "strata_order_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
