// `strata bench`: methods x scenes x views, several frames each, every image checked against the
// Embree reference; results as JSON, CSV, Markdown and a self-contained HTML report.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/renderer.h"
#include "preprocess/image_io.h"

namespace strata {

// One scene at one size from one view.
struct BenchCase {
  std::string scene;  // file path or builtin:NAME
  std::string label;  // short name for tables (model file stem, "spheres:32", ...)
  int width = 512, height = 512;
  std::optional<OrbitView> view;  // unset: the scene's own view
  int layers = 0;                 // depth layers of builtin:spheres:N (0 for other scenes)
  int k = 32;                     // per-pixel budget for the fixed-size methods
  // The methods this case runs, of the suite's (empty: all of them): a scene too large for a
  // method's memory or time is left out rather than tried.
  std::vector<std::string> only;
};

struct BenchSuite {
  std::string name;  // smoke, paper-table1, paper-table2, paper-table3
  std::string description;
  std::vector<BenchCase> cases;
  // Default methods (all registered when empty). "octree/VARIANT" is the octree method with
  // that variant (OctreeMethodOptions), so variants compare side by side.
  std::vector<std::string> methods;
  int frames = 5;
};

std::vector<std::string> benchSuiteNames();
// Builds a suite; models_dir holds the shared models (teapot.obj, horse.ply, ...).
BenchSuite makeBenchSuite(const std::string& name, const std::string& models_dir);

// The error of a row the suite leaves out for its scene (BenchCase::only).
inline constexpr const char* kNotRunBySuite = "not run on this scene by the suite (memory or time)";

struct BenchRow {
  BenchCase bench_case;
  std::string method;
  bool ok = false;  // rendered; false: `error` says why (e.g. does not fit in memory)
  std::string error;
  FrameStats stats;
  ImageDiff diff;              // against the Embree reference of the same case
  bool exact_expected = true;  // method claims exactness (bdp, mdts32 report their error)
  // The same case with a moving camera (BenchOptions::orbit_deg per frame, as many frames):
  // every frame a new view, so its time includes all per-view work. moving_ok false: not run
  // (orbit 0) or failed (moving_error).
  bool moving_ok = false;
  std::string moving_error;
  FrameStats moving;
  std::string reference_file;  // the case's Embree image, relative to the output folder
  std::string image_file;      // relative to the output folder
  std::string diff_file;
};

struct BenchOptions {
  std::string suite = "smoke";
  std::vector<std::string> methods;  // overrides the suite's
  std::string out_dir = "bench-out";
  std::string models_dir;
  int frames = 0;  // 0: the suite's default
  // The moving-camera run of every case: degrees of azimuth per frame (0: still views only).
  float orbit_deg = 1.0f;
  DeviceOptions device;
  // Draw units of the OpenCL front end (results.json carries their counters per row).
  Batch batch = Batch::Static;
  DrawSort sort = DrawSort::None;
  AtlasChoice atlas = AtlasChoice::Packed;  // textured scenes
  std::string tile_kernels = "auto";        // the form of the per-tile kernels (FrameSettings)
  // Progress: (done, total, what is running now).
  std::function<void(int, int, const std::string&)> on_progress;
};

struct BenchResult {
  BenchSuite suite;
  std::vector<std::string> methods;
  std::vector<BenchRow> rows;
  std::string device;
};

// Runs the suite and writes results.json, results.csv, results.md and report.html (each through
// a temporary file and a rename) plus the images under out_dir/images.
BenchResult runBench(const BenchOptions& options);

// The report writers (exposed for tests).
std::string benchJson(const BenchResult& r);
std::string benchCsv(const BenchResult& r);
std::string benchMarkdown(const BenchResult& r);
std::string benchHtml(const BenchResult& r, const std::string& out_dir);

}  // namespace strata
