#include "engine/report/bench.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <sstream>

#include "engine/reference/embree_reference.h"
#include "engine/report/stats_json.h"
#include "kernels/strata_shared.h"
#include "preprocess/builtin_scenes.h"

namespace strata {

namespace fs = std::filesystem;

namespace {

const char* const kSharedModels[] = {"teapot.obj",  "horse.ply",      "stanford-bunny.obj",
                                     "fandisk.obj", "rocker-arm.obj", "cheburashka.obj",
                                     "homer.obj",   "cow.obj",        "spot.obj"};

// Viewpoints spread around a model: evenly in azimuth, alternately above and below it.
std::vector<OrbitView> viewsAround(int count) {
  std::vector<OrbitView> out;
  for (int i = 0; i < count; ++i) {
    OrbitView v;
    v.azimuth_deg = 360.0f * float(i) / float(count);
    v.elevation_deg = (i % 2) ? 35.0f : -20.0f;
    out.push_back(v);
  }
  return out;
}

BenchCase spheresCase(int layers, int size) {
  BenchCase c;
  c.scene = "builtin:spheres:" + std::to_string(layers);
  c.label = "spheres:" + std::to_string(layers);
  c.width = c.height = size;
  c.layers = layers;
  c.k = std::min(layers, ST_MAX_K);  // fixed-budget methods get the budget exactness needs
  return c;
}

BenchCase modelCase(const std::string& models_dir, const std::string& file, int size,
                    const OrbitView& view) {
  BenchCase c;
  c.scene = (fs::path(models_dir) / file).string();
  c.label = fs::path(file).stem().string();
  c.width = c.height = size;
  c.view = view;
  c.k = 32;
  return c;
}

// A bench method: a registered name, or octree/VARIANT.
struct BenchMethod {
  Method method;
  std::string variant;  // octree only; empty: the default
};
BenchMethod parseBenchMethod(const std::string& m) {
  const size_t slash = m.find('/');
  if (slash == std::string::npos) return {parseMethod(m), ""};
  const Method method = parseMethod(m.substr(0, slash));
  if (method != Method::Octree)
    throw Error("bench method '" + m + "': only octree takes a variant (octree/VARIANT)");
  return {method, m.substr(slash + 1)};
}

bool methodIsExact(const std::string& m) { return methodInfo(parseBenchMethod(m).method).exact; }

std::string caseId(const BenchCase& c) {
  std::ostringstream id;
  for (char ch : c.label) id << (std::isalnum((unsigned char)ch) ? ch : '_');
  id << "-" << c.width << "x" << c.height;
  if (c.view)
    id << "-az" << int(std::lround(c.view->azimuth_deg)) << "-el"
       << int(std::lround(c.view->elevation_deg));
  return id.str();
}

// The suites, each filling its cases, description and frames (and methods, where it names them).
void smokeSuite(BenchSuite& s, const std::string& models_dir) {
  s.description = "a few small renders that run in seconds (used by the tests)";
  OrbitView v;
  v.azimuth_deg = 30.0f;
  v.elevation_deg = 20.0f;
  BenchCase demo;
  demo.scene = "builtin:demo";
  demo.label = "demo";
  demo.width = demo.height = 96;
  demo.view = v;
  demo.k = 16;
  s.cases.push_back(demo);
  for (const OrbitView& view : viewsAround(2))
    s.cases.push_back(modelCase(models_dir, "teapot.obj", 96, view));
  // Two depths, so the charts against depth have a line to draw.
  s.cases.push_back(spheresCase(16, 64));
  s.cases.push_back(spheresCase(20, 64));
  s.frames = 2;
}

void paperTable1Suite(BenchSuite& s, const std::string& models_dir) {
  s.description =
      "Table 1: frames per second at 512x512, averaged over 8 viewpoints around each model";
  for (const char* model : kSharedModels)
    for (const OrbitView& view : viewsAround(8))
      s.cases.push_back(modelCase(models_dir, model, 512, view));
  s.frames = 5;
}

void paperTable2Suite(BenchSuite& s, const std::string&) {
  s.description =
      "Table 2: frame time against depth, builtin:spheres:N at 1024x1024 along the stacking axis";
  for (int layers = 16; layers <= 96; layers += 16) s.cases.push_back(spheresCase(layers, 1024));
  s.frames = 3;
}

void paperTable3Suite(BenchSuite& s, const std::string&) {
  s.description = "Table 3: device memory at 512x512 and 1024x1024 for 20 and 60 layers";
  for (int size : {512, 1024})
    for (int layers : {20, 60}) s.cases.push_back(spheresCase(layers, size));
  s.frames = 1;
}

void texturesSuite(BenchSuite& s, const std::string&) {
  s.description =
      "textured materials: builtin:textured:16 and :64 at 1024x1024 from 4 views (compare "
      "--atlas off, uniform, packed)";
  for (int n : {16, 64})
    for (const OrbitView& view : viewsAround(4)) {
      BenchCase c;
      c.scene = "builtin:textured:" + std::to_string(n);
      c.label = "textured:" + std::to_string(n);
      c.width = c.height = 1024;
      OrbitView v = view;
      v.distance_radii = 1.85f;  // the scene's own framing (its floor reaches past auto-framing)
      c.view = v;
      c.k = 32;
      s.cases.push_back(c);
    }
  s.frames = 3;
}

void octreeSuite(BenchSuite& s, const std::string& models_dir) {
  s.description =
      "the octree paper's Table 1 at 640x480: the massive built-ins (opacity 0.5, the shell "
      "stack 0.2) and the horse; the octree variants as ratios to depth peeling, the other "
      "methods where they fit, and a 10M-triangle hairball";
  s.methods = {"octree/kbuffer", "octree/blocks-histogram",
               "octree/blocks",  "octree/histogram",
               "octree/dp",      "dp",
               "ppll",           "abuffer",
               "cells",          "embree"};
  const OrbitView view{30.0f, 20.0f, std::nullopt, std::nullopt};
  auto massive = [&](const std::string& scene, const std::string& label) {
    BenchCase c;
    c.scene = scene;
    c.label = label;
    c.width = 640;
    c.height = 480;
    c.view = view;
    c.k = ST_MAX_K;
    // cells needs a decomposition of every part: too slow on thousands of tubes or soup
    c.only = s.methods;
    c.only.erase(std::find(c.only.begin(), c.only.end(), "cells"));
    return c;
  };
  BenchCase horse = modelCase(models_dir, "horse.ply", 640, view);
  horse.height = 480;
  s.cases.push_back(horse);
  s.cases.push_back(massive("builtin:shells", "shells"));
  s.cases.back().only.push_back("cells");  // closed shells decompose
  s.cases.push_back(massive("builtin:city", "city"));
  s.cases.push_back(massive("builtin:soup", "soup"));
  s.cases.push_back(massive("builtin:hairball", "hairball"));
  BenchCase big = massive("builtin:hairball:4200", "hairball:4200");
  big.only = {"octree/kbuffer", "embree"};  // 10M triangles: depth peeling takes minutes
  s.cases.push_back(big);
  s.frames = 2;
}

void rasterSuite(BenchSuite& s, const std::string& models_dir) {
  s.description =
      "the raster core's stages alone: builtin:grid layers of small (~2 px), medium (~50 px) and "
      "large (~5000 px) triangles at 1024x1024, then horse, spheres:32 and spheres:96; ns per "
      "triangle for the front end and binning, ns per fragment for the fine raster";
  s.methods = {"opaque", "abuffer", "ppll", "cells", "embree"};
  const std::pair<int, const char*> grids[] = {{466, "small"}, {93, "medium"}, {9, "large"}};
  for (const auto& [n, size] : grids) {
    BenchCase c;
    c.scene = "builtin:grid:" + std::to_string(n);
    c.label = std::string("grid:") + size;
    c.width = c.height = 1024;
    c.k = 8;
    s.cases.push_back(c);
  }
  s.cases.push_back(modelCase(models_dir, "horse.ply", 1024, OrbitView{}));
  s.cases.push_back(spheresCase(32, 1024));
  s.cases.push_back(spheresCase(96, 1024));
  s.frames = 3;
}

struct SuiteBuilder {
  const char* name;
  void (*build)(BenchSuite& s, const std::string& models_dir);
};
const SuiteBuilder kSuites[] = {
    {"smoke", smokeSuite},        {"paper-table1", paperTable1Suite},
    {"paper-table2", paperTable2Suite}, {"paper-table3", paperTable3Suite},
    {"textures", texturesSuite},  {"octree", octreeSuite},
    {"raster", rasterSuite}};

// One method on one case: rendered (the same frames as the reference, and with a moving camera
// when asked), compared with the reference, its image and difference written under `out`.
// Renderers are made once per method and kept in `renderers`; device is set from the first
// OpenCL row.
BenchRow runRow(const BenchCase& c, const std::string& m, const std::string& id,
                const FrameSettings& settings, const WorldGeometry& geometry,
                const RenderResult& ref, const std::string& reference_file,
                const BenchOptions& opt,
                std::map<std::string, std::unique_ptr<MethodRenderer>>& renderers,
                MethodRenderer& reference, std::unique_ptr<MethodRenderer>& opaque_reference,
                const fs::path& out, std::string& device) {
  BenchRow row;
  row.bench_case = c;
  row.method = m;
  row.exact_expected = methodIsExact(m);
  row.reference_file = reference_file;
  try {
    RenderResult r;
    MethodRenderer* renderer = &reference;
    FrameSettings method_settings = settings;
    if (m == "embree") {
      r = ref;  // the reference itself, timed over the same frames
    } else {
      auto& made = renderers[m];
      const BenchMethod bm = parseBenchMethod(m);
      if (!made) made = makeRenderer(bm.method, opt.device);
      renderer = made.get();
      if (!bm.variant.empty()) method_settings.octree.variant = bm.variant;
      r = renderer->render(geometry, method_settings);
    }
    row.ok = true;
    row.stats = r.stats;
    if (opt.orbit_deg != 0.0f) {
      method_settings.orbit_deg = opt.orbit_deg;
      try {
        row.moving = renderer->render(geometry, method_settings).stats;
        row.moving_ok = true;
      } catch (const Error& e) {
        row.moving_error = e.what();
      }
    }
    Image opaque_ref;
    if (m == "opaque") {
      if (!opaque_reference) opaque_reference = makeEmbreeRenderer(EmbreeMode::Opaque);
      FrameSettings once = settings;
      once.frames = 1;
      opaque_ref = opaque_reference->render(geometry, once).image;
    }
    const Image& against = m == "opaque" ? opaque_ref : ref.image;
    row.diff = compareImages(r.image, against);
    std::string file_m = m;  // octree/VARIANT: no folder in the file name
    std::replace(file_m.begin(), file_m.end(), '/', '-');
    row.image_file = "images/" + id + "-" + file_m + ".png";
    row.diff_file = "images/" + id + "-" + file_m + "-diff.png";
    writeImage(r.image, (out / row.image_file).string());
    writeImage(differenceImage(r.image, against), (out / row.diff_file).string());
    if (device.empty() && m != "embree") device = r.stats.device;
  } catch (const Error& e) {
    row.ok = false;
    row.error = e.what();
  }
  return row;
}

}  // namespace

std::vector<std::string> benchSuiteNames() {
  std::vector<std::string> names;
  for (const SuiteBuilder& b : kSuites) names.push_back(b.name);
  return names;
}

BenchSuite makeBenchSuite(const std::string& name, const std::string& models_dir) {
  BenchSuite s;
  s.name = name;
  const SuiteBuilder* builder = nullptr;
  for (const SuiteBuilder& b : kSuites)
    if (name == b.name) builder = &b;
  if (!builder) {
    std::string known;
    for (const std::string& n : benchSuiteNames()) known += (known.empty() ? "" : ", ") + n;
    throw Error("unknown bench suite '" + name + "' (known: " + known + ")");
  }
  builder->build(s, models_dir);
  for (BenchCase& c : s.cases)
    if (c.scene.rfind("builtin:", 0) != 0 && !fs::exists(c.scene))
      throw Error(c.scene + ": model not found (pass the models folder with --models)");
  return s;
}

BenchResult runBench(const BenchOptions& opt) {
  BenchResult result;
  result.suite = makeBenchSuite(opt.suite, opt.models_dir);
  const BenchSuite& suite = result.suite;
  result.methods = !opt.methods.empty()     ? opt.methods
                   : !suite.methods.empty() ? suite.methods
                                            : methodNames();
  for (const std::string& m : result.methods) parseBenchMethod(m);  // fail before any work
  const int frames = opt.frames > 0 ? opt.frames : suite.frames;

  const fs::path out(opt.out_dir);
  std::error_code ec;
  fs::create_directories(out / "images", ec);
  if (ec) throw Error(opt.out_dir + ": cannot create the output folder (" + ec.message() + ")");

  // Renderers live across cases (programs and buffers are reused); the reference is separate.
  std::map<std::string, std::unique_ptr<MethodRenderer>> renderers;
  std::unique_ptr<MethodRenderer> reference = makeEmbreeRenderer(EmbreeMode::Transparency);
  // `opaque` draws the nearest surface only: its reference is Embree's nearest hit.
  std::unique_ptr<MethodRenderer> opaque_reference;
  const int total = int(suite.cases.size() * result.methods.size());
  int done = 0;
  std::string loaded_scene;
  Scene scene;
  WorldGeometry geometry;
  for (const BenchCase& c : suite.cases) {
    if (c.scene != loaded_scene) {  // cases of one scene are adjacent: load it once
      scene = loadScene(c.scene);
      geometry = WorldGeometry::fromScene(scene);
      loaded_scene = c.scene;
    }
    FrameSettings settings;
    settings.width = c.width;
    settings.height = c.height;
    settings.k = c.k;
    settings.batch = opt.batch;
    settings.sort = opt.sort;
    settings.atlas = opt.atlas;
    settings.tile_kernels = opt.tile_kernels;
    settings.camera = Camera::orbit(scene.boundingSphere(),
                                    c.view.value_or(scene.default_view.value_or(OrbitView{})),
                                    scene.default_projection.value_or(Projection::Perspective));
    const std::string id = caseId(c);
    if (opt.on_progress)
      opt.on_progress(done, total,
                      c.label + " " + std::to_string(c.width) + "x" + std::to_string(c.height) +
                          ": embree reference");
    const bool embree_timed =
        std::find(result.methods.begin(), result.methods.end(), "embree") != result.methods.end();
    settings.frames = embree_timed ? frames : 1;
    RenderResult ref = reference->render(geometry, settings);
    const std::string reference_file = "images/" + id + "-reference.png";
    writeImage(ref.image, (out / reference_file).string());
    settings.frames = frames;

    for (const std::string& m : result.methods) {
      if (!c.only.empty() && std::find(c.only.begin(), c.only.end(), m) == c.only.end()) {
        BenchRow skipped;
        skipped.bench_case = c;
        skipped.method = m;
        skipped.error = kNotRunBySuite;
        result.rows.push_back(skipped);
        ++done;
        continue;
      }
      if (opt.on_progress)
        opt.on_progress(
            done, total,
            c.label + " " + std::to_string(c.width) + "x" + std::to_string(c.height) + ": " + m);
      result.rows.push_back(runRow(c, m, id, settings, geometry, ref, reference_file, opt,
                                   renderers, *reference, opaque_reference, out, result.device));
      ++done;
    }
  }
  if (opt.on_progress) opt.on_progress(done, total, "writing reports");
  writeTextFileAtomically((out / "results.json").string(), benchJson(result));
  writeTextFileAtomically((out / "results.csv").string(), benchCsv(result));
  writeTextFileAtomically((out / "results.md").string(), benchMarkdown(result));
  writeTextFileAtomically((out / "report.html").string(), benchHtml(result, opt.out_dir));
  return result;
}

}  // namespace strata
