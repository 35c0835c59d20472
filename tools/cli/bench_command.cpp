// strata bench: a benchmark suite (methods x scenes x views, every image checked against
// embree, reports written), the distributed scaling table, or a soak run.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "engine/report/bench.h"
#include "engine/report/soak.h"
#include "tools/cli/cli.h"
#include "tools/distributed_render.h"

namespace strata::cli {

namespace {

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

}  // namespace

Command addBenchCommand(CLI::App& app) {
  struct BenchArgs {
    BenchOptions bo;
    std::string methods, batch = "static", sort = "none", atlas = "packed";
    bool distributed = false, soak = false;
    std::string processes = "1,2,3,4", scenes, size = "640x480";
    std::string device, atomics;
  };
  auto args = std::make_shared<BenchArgs>();
  BenchOptions& bo = args->bo;
  std::string &bench_methods = args->methods, &bench_batch = args->batch, &bench_sort = args->sort,
              &bench_atlas = args->atlas;
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
  addDeviceOptions(bench, args->device, args->atomics);
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
  bool &bench_distributed = args->distributed, &bench_soak = args->soak;
  std::string &bench_processes = args->processes, &bench_scenes = args->scenes,
              &bench_size = args->size;
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
  Command c;
  c.app = bench;
  c.run = [args, bench] {
    BenchArgs& a = *args;
    BenchOptions& bo = a.bo;
    if (bench->count("--frames") > 0 && bo.frames < 1) bo.frames = -1;  // given as 0: refused
    if (a.distributed) {
      DistributedBench db;
      db.out_dir = bo.out_dir;
      db.device = deviceSpec(a.device);
      if (bo.frames != 0) checkFrameCount(bo.frames, "--frames");  // 0: the default
      if (bo.frames > 0) db.frames = bo.frames;
      parseSize(a.size, db.width, db.height);
      db.processes = parseIntList(a.processes, 0, "--processes", "P,P,... (process counts)");
      if (!a.scenes.empty()) {
        db.scenes.clear();
        std::stringstream ss(a.scenes);
        for (std::string sc; std::getline(ss, sc, ',');)
          if (!sc.empty()) db.scenes.push_back(sc);
      }
      return runDistributedBench(db);
    }
    if (a.soak) {
      if (a.distributed) throw Error("--soak and --distributed are separate runs");
      SoakOptions so;
      so.out_dir = bo.out_dir;
      so.device = deviceOptions(a.device, a.atomics);
      if (bo.frames != 0) checkFrameCount(bo.frames, "--frames");  // 0: the default
      if (bo.frames > 0) so.frames = bo.frames;
      so.sample_every = std::min(so.sample_every, so.frames);
      if (bench->count("--size") > 0) parseSize(a.size, so.width, so.height);
      if (!(std::fabs(bo.orbit_deg) <= 360.0f))
        throw Error("--orbit must be between -360 and 360 degrees per frame");
      so.orbit_deg = bo.orbit_deg;
      std::stringstream ms(a.methods);
      for (std::string m; std::getline(ms, m, ',');)
        if (!m.empty()) so.methods.push_back(m);
      if (!a.scenes.empty()) so.scene = a.scenes.substr(0, a.scenes.find(','));
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
    bo.device = deviceOptions(a.device, a.atomics);
    return runBenchCommand(bo, a.methods, a.batch, a.sort, a.atlas);
  };
  c.subject = [] { return std::string("strata bench"); };
  return c;
}

}  // namespace strata::cli
