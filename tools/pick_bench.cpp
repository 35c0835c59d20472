// ID-picking latency benchmark: the OpenCL ID buffer (engine/features/picking.h IdPicker: update()
// rasterizes one frame's ID buffer, pick() gathers only the asked pixels) against the Embree ray
// pick (engine/reference/embree_reference.h EmbreeRayPicker: one ray per asked pixel), front-most only and
// all layers / all hits, for 1, 100 and 10,000 random pixels (fixed seed).
//
//   strata_pick_bench [--scene SPEC]... [--size N] [--points 1,100,10000] [--reps R]
//                     [--cold-reps C] [--seed S] [--embree-threads T] [--json FILE]
//
// Defaults: tests/models/horse.ply and builtin:crowd:1000 at 1024x1024, the tests' view
// (azimuth 30, elevation 20, auto-framed), 15 repetitions, seed 99, Embree on every hardware
// thread. Every number is a median over repetitions, and the measurements are interleaved: each
// repetition runs, for every (layers, points) pair in a rotating order, update(), pick() and the
// Embree pick back to back, so drift on a shared machine hits both sides alike. One "update +
// pick" sample is the sum of an update() and the pick() that follows it in the same repetition.
//
// Embree's BVH: EmbreeRayPicker keeps it across calls while the triangles are the same (a memcmp
// of Embree's copies against the geometry on every call). It is measured separately: a fresh
// picker's construction (the Embree device), its first pick of one pixel (BVH build + one ray)
// and its second pick of the same pixel (steady state); build = first - second, per fresh picker.
// The steady-state per-call times in the table never include a build.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/reference/embree_reference.h"
#include "engine/features/picking.h"
#include "engine/renderer.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/core/files.h"
#include "preprocess/scene/camera.h"
#include "preprocess/scene/world_geometry.h"

namespace {

using namespace strata;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const double pos = q * double(v.size() - 1);
  const size_t lo = size_t(std::floor(pos)), hi = std::min(v.size() - 1, lo + 1);
  return v[lo] + (pos - double(lo)) * (v[hi] - v[lo]);
}

nlohmann::json summary(const std::vector<double>& v) {
  return {{"median", median(v)},
          {"p25", quantile(v, 0.25)},
          {"p75", quantile(v, 0.75)},
          {"min", v.empty() ? 0.0 : *std::min_element(v.begin(), v.end())},
          {"max", v.empty() ? 0.0 : *std::max_element(v.begin(), v.end())},
          {"runs", v.size()}};
}

std::vector<glm::ivec2> randomPixels(int width, int height, int count, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> x(0, width - 1), y(0, height - 1);
  std::vector<glm::ivec2> out;
  out.reserve(size_t(count));
  for (int i = 0; i < count; ++i) out.emplace_back(x(rng), y(rng));
  return out;
}

std::vector<int> parseList(const std::string& text) {
  std::vector<int> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const int v = std::atoi(item.c_str());
    if (v <= 0) throw Error("--points: '" + item + "' is not a positive count");
    out.push_back(v);
  }
  if (out.empty()) throw Error("--points: empty list");
  return out;
}

// A file path as given if it exists, else relative to the source tree (so the defaults work from
// any folder); builtin: specs unchanged.
std::string resolveScene(const std::string& spec) {
  if (spec.rfind("builtin:", 0) == 0 || std::filesystem::exists(spec)) return spec;
  const std::filesystem::path in_tree = std::filesystem::path(STRATA_SOURCE_DIR) / spec;
  return std::filesystem::exists(in_tree) ? in_tree.string() : spec;
}

std::string fmtMs(double ms) {
  char buf[32];
  if (ms < 1.0)
    std::snprintf(buf, sizeof(buf), "%.3f", ms);
  else if (ms < 100.0)
    std::snprintf(buf, sizeof(buf), "%.2f", ms);
  else
    std::snprintf(buf, sizeof(buf), "%.1f", ms);
  return buf;
}

struct Options {
  std::vector<std::string> scenes;
  int size = 1024;
  std::vector<int> points = {1, 100, 10000};
  int reps = 15;
  int cold_reps = 5;
  unsigned seed = 99;
  int embree_threads = 0;
  std::string json;
};

Options parseArgs(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw Error(a + " needs a value");
      return argv[++i];
    };
    if (a == "--scene")
      o.scenes.push_back(value());
    else if (a == "--size")
      o.size = std::atoi(value().c_str());
    else if (a == "--points")
      o.points = parseList(value());
    else if (a == "--reps")
      o.reps = std::atoi(value().c_str());
    else if (a == "--cold-reps")
      o.cold_reps = std::atoi(value().c_str());
    else if (a == "--seed")
      o.seed = unsigned(std::strtoul(value().c_str(), nullptr, 10));
    else if (a == "--embree-threads")
      o.embree_threads = std::atoi(value().c_str());
    else if (a == "--json")
      o.json = value();
    else if (a == "-h" || a == "--help") {
      std::printf(
          "strata_pick_bench [--scene SPEC]... [--size N] [--points 1,100,10000] [--reps R]\n"
          "                  [--cold-reps C] [--seed S] [--embree-threads T] [--json FILE]\n");
      std::exit(0);
    } else {
      throw Error("unknown argument '" + a + "' (see --help)");
    }
  }
  if (o.scenes.empty()) o.scenes = {"tests/models/horse.ply", "builtin:crowd:1000"};
  if (o.size < 16 || o.size > 8192) throw Error("--size must be 16..8192");
  if (o.reps < 3) throw Error("--reps must be at least 3");
  if (o.cold_reps < 1) throw Error("--cold-reps must be at least 1");
  return o;
}

struct Cell {  // one (layers, points) pair
  bool layers = false;
  int points = 0;
  std::vector<double> update, pick, total, embree, paired_ratio;
  uint64_t id_hits = 0, ray_hits = 0, id_fragments = 0, ray_fragments = 0, front_agree = 0;
};

// The counts a table row reports about one result, so no pick is optimized away and the two
// methods can be compared (front-most triangle agreement).
void tally(Cell& c, const PickResult& id, const std::vector<std::vector<EmbreeRayHit>>& ray) {
  c.id_hits = c.ray_hits = c.id_fragments = c.ray_fragments = c.front_agree = 0;
  for (size_t i = 0; i < id.pixels.size(); ++i) {
    const PickedPixel& p = id.pixels[i];
    const bool id_hit = p.status == PickStatus::Hit;
    const bool ray_hit = !ray[i].empty();
    c.id_hits += id_hit;
    c.ray_hits += ray_hit;
    c.id_fragments += c.layers ? p.layers.size() : size_t(id_hit);
    c.ray_fragments += ray[i].size();
    if (id_hit == ray_hit && (!id_hit || p.front.triangle == ray[i].front().triangle))
      ++c.front_agree;
  }
}

// Where the ID buffer starts to win: the first measured count where its "update + pick" median
// is below Embree's, with the crossing interpolated linearly from the count before it; if it
// never wins, a linear extrapolation through the two largest counts.
nlohmann::json crossover(const std::vector<const Cell*>& cells, int max_points) {
  auto diff = [](const Cell* c) { return median(c->total) - median(c->embree); };
  auto cross = [&](const Cell* a, const Cell* b) -> double {  // zero of the line through a, b
    const double da = diff(a), db = diff(b);
    if (da == db) return -1.0;
    return double(a->points) + da * double(b->points - a->points) / (da - db);
  };
  char buf[192];
  for (size_t k = 0; k < cells.size(); ++k) {
    if (diff(cells[k]) >= 0.0) continue;
    if (k == 0) {
      std::snprintf(buf, sizeof(buf), "wins at every measured count (from %d)", cells[k]->points);
      return {{"measured", true}, {"points", cells[k]->points}, {"text", buf}};
    }
    const double n = cross(cells[k - 1], cells[k]);
    std::snprintf(buf, sizeof(buf), "wins from ~%.0fk (measured: loses at %d, wins at %d)",
                  n / 1000.0, cells[k - 1]->points, cells[k]->points);
    return {{"measured", true}, {"points", std::llround(n)}, {"text", buf}};
  }
  if (cells.size() < 2)
    return {{"measured", false},
            {"points", nullptr},
            {"text", "not reached up to " + std::to_string(cells.back()->points)}};
  const Cell* a = cells[cells.size() - 2];
  const Cell* b = cells.back();
  const double n = cross(a, b);
  if (n <= double(b->points))
    return {{"measured", false},
            {"points", nullptr},
            {"text", "not reached up to " + std::to_string(b->points) +
                         " (the gap widens between the two largest counts)"}};
  if (n > double(max_points))
    std::snprintf(buf, sizeof(buf),
                  "not reached up to %d (straight line: ~%.0fk, more than the %dk pixels of the "
                  "image)",
                  b->points, n / 1000.0, max_points / 1000);
  else
    std::snprintf(buf, sizeof(buf),
                  "not reached up to %d (straight line through %d and %d: ~%.0fk; measure it with "
                  "--points)",
                  b->points, a->points, b->points, n / 1000.0);
  return {{"measured", false}, {"points", std::llround(n)}, {"text", buf}};
}

int run(const Options& o) {
  nlohmann::json out;
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  const int ray_threads = o.embree_threads > 0 ? o.embree_threads : int(hw);
  {
    IdPicker probe;
    out["device"] = probe.device();
  }
  out["hardware_threads"] = hw;
  out["embree_ray_threads"] = ray_threads;
  out["embree_build_threads"] = o.embree_threads > 0 ? o.embree_threads : int(hw);
  out["size"] = o.size;
  out["reps"] = o.reps;
  out["cold_reps"] = o.cold_reps;
  out["seed"] = o.seed;
  out["points"] = o.points;
  out["view"] = {{"azimuth_deg", 30.0}, {"elevation_deg", 20.0}};
  std::printf("device: %s\n", out["device"].get<std::string>().c_str());
  std::printf(
      "embree: rays on up to %d threads (one per 64 pixels asked), BVH build on %d; "
      "%d hardware threads\n",
      ray_threads, out["embree_build_threads"].get<int>(), hw);
  std::printf("%dx%d, %d interleaved repetitions, medians; seed %u\n\n", o.size, o.size, o.reps,
              o.seed);

  for (const std::string& spec : o.scenes) {
    const std::string path = resolveScene(spec);
    const Scene scene = loadScene(path);
    const WorldGeometry g = WorldGeometry::fromScene(scene);
    FrameSettings s;
    s.width = s.height = o.size;
    OrbitView v = scene.default_view.value_or(OrbitView{});
    v.azimuth_deg = 30.0f;
    v.elevation_deg = 20.0f;
    s.camera = Camera::orbit(scene.boundingSphere(), v);

    std::map<int, std::vector<glm::ivec2>> pixels;
    for (int n : o.points) pixels[n] = randomPixels(o.size, o.size, n, o.seed);

    nlohmann::json js;
    js["scene"] = spec;
    js["triangles"] = g.triangleCount();

    // Embree cold start: device creation, first call (BVH build + 1 ray), second call.
    std::vector<double> construct, first, second, build;
    for (int r = 0; r < o.cold_reps; ++r) {
      const std::vector<glm::ivec2> one = {pixels.begin()->second.front()};
      auto t0 = Clock::now();
      EmbreeRayPicker fresh(o.embree_threads);
      construct.push_back(msSince(t0));
      t0 = Clock::now();
      fresh.pick(g, s, one, false);
      first.push_back(msSince(t0));
      t0 = Clock::now();
      fresh.pick(g, s, one, false);
      second.push_back(msSince(t0));
      build.push_back(first.back() - second.back());
    }
    const bool bvh_cached = median(second) < 0.25 * median(first);
    js["embree_cold"] = {{"construct_ms", summary(construct)},
                         {"first_call_ms", summary(first)},
                         {"second_call_ms", summary(second)},
                         {"bvh_build_ms", summary(build)},
                         {"bvh_cached_between_calls", bvh_cached}};

    // The raster pass alone, by the pipeline's own frame timer (the opaque method: the same
    // visibility raster as a front-most update, plus a resolve; no scene upload or image
    // readback), one frame per repetition, interleaved with the rest, for context.
    auto opaque = makeRenderer(Method::Opaque);
    std::vector<double> opaque_frame;
    auto opaqueFrame = [&] {
      const RenderResult rr = opaque->render(g, s);
      js["fragments_per_frame"] = rr.stats.fragments;
      js["max_depth_complexity"] = rr.stats.max_depth_complexity;
      return rr.stats.frame_ms.median;
    };
    opaqueFrame();  // the first render of this pipeline pays the kernel build

    IdPicker picker;
    EmbreeRayPicker ray(o.embree_threads);
    // Warm-up: kernel builds, buffer growth for the largest set, the BVH.
    for (bool layers : {false, true})
      for (int k = 0; k < 2; ++k) {
        picker.update(g, s, layers);
        for (const auto& [n, px] : pixels) {
          picker.pick(px);
          ray.pick(g, s, px, layers);
        }
      }

    std::vector<Cell> cells;
    for (bool layers : {false, true})
      for (int n : o.points) {
        Cell c;
        c.layers = layers;
        c.points = n;
        cells.push_back(c);
      }
    for (int r = 0; r < o.reps; ++r) {
      for (size_t k = 0; k < cells.size(); ++k) {
        Cell& c = cells[(k + size_t(r)) % cells.size()];
        const std::vector<glm::ivec2>& px = pixels[c.points];
        PickResult id;
        std::vector<std::vector<EmbreeRayHit>> hits;
        double u = 0, p = 0, e = 0;
        auto gpu = [&] {
          auto t0 = Clock::now();
          picker.update(g, s, c.layers);
          u = msSince(t0);
          t0 = Clock::now();
          id = picker.pick(px);
          p = msSince(t0);
        };
        auto cpu = [&] {
          const auto t0 = Clock::now();
          hits = ray.pick(g, s, px, c.layers);
          e = msSince(t0);
        };
        if (r % 2) {
          cpu();
          gpu();
        } else {
          gpu();
          cpu();
        }
        c.update.push_back(u);
        c.pick.push_back(p);
        c.total.push_back(u + p);
        c.embree.push_back(e);
        c.paired_ratio.push_back((u + p) / e);
        if (r == 0) tally(c, id, hits);
      }
      opaque_frame.push_back(opaqueFrame());
    }

    std::vector<double> update_front, update_all;
    for (const Cell& c : cells)
      (c.layers ? update_all : update_front)
          .insert((c.layers ? update_all : update_front).end(), c.update.begin(), c.update.end());
    js["update_ms"] = {{"front", summary(update_front)}, {"all_layers", summary(update_all)}};
    js["opaque_frame_ms"] = summary(opaque_frame);

    std::printf("== %s: %u triangles, %llu fragments/frame, max depth %llu\n", spec.c_str(),
                g.triangleCount(), (unsigned long long)js["fragments_per_frame"].get<uint64_t>(),
                (unsigned long long)js["max_depth_complexity"].get<uint64_t>());
    std::printf(
        "   ID-buffer update(): front-most %s ms, all layers %s ms (opaque raster frame "
        "alone: %s ms)\n",
        fmtMs(median(update_front)).c_str(), fmtMs(median(update_all)).c_str(),
        fmtMs(median(opaque_frame)).c_str());
    std::printf(
        "   Embree: device %s ms, BVH build %s ms (first call %s ms, second %s ms: BVH %s)\n",
        fmtMs(median(construct)).c_str(), fmtMs(median(build)).c_str(),
        fmtMs(median(first)).c_str(), fmtMs(median(second)).c_str(),
        bvh_cached ? "cached between calls" : "NOT cached");
    std::printf("   %-6s %7s | %9s %9s %12s | %9s | %8s %7s %8s | %s\n", "layers", "points",
                "update", "pick", "update+pick", "embree", "ratio", "winner", "pick/emb",
                "hits id/ray, front agree");
    nlohmann::json rows = nlohmann::json::array();
    for (const Cell& c : cells) {
      const double total = median(c.total), e = median(c.embree);
      std::printf("   %-6s %7d | %9s %9s %12s | %9s | %7.2fx %7s %7.2fx | %llu/%llu, %.1f%%\n",
                  c.layers ? "all" : "front", c.points, fmtMs(median(c.update)).c_str(),
                  fmtMs(median(c.pick)).c_str(), fmtMs(total).c_str(), fmtMs(e).c_str(), total / e,
                  total < e ? "id-buf" : "embree", median(c.pick) / e,
                  (unsigned long long)c.id_hits, (unsigned long long)c.ray_hits,
                  100.0 * double(c.front_agree) / c.points);
      rows.push_back({{"layers", c.layers ? "all" : "front"},
                      {"points", c.points},
                      {"update_ms", summary(c.update)},
                      {"pick_ms", summary(c.pick)},
                      {"update_plus_pick_ms", summary(c.total)},
                      {"embree_ms", summary(c.embree)},
                      {"ratio_of_medians", total / e},
                      {"median_paired_ratio", median(c.paired_ratio)},
                      {"pick_only_ratio", median(c.pick) / e},
                      {"id_hits", c.id_hits},
                      {"ray_hits", c.ray_hits},
                      {"id_fragments", c.id_fragments},
                      {"ray_fragments", c.ray_fragments},
                      {"front_agree", c.front_agree}});
    }
    js["rows"] = rows;
    for (bool layers : {false, true}) {
      std::vector<const Cell*> mode;
      for (const Cell& c : cells)
        if (c.layers == layers) mode.push_back(&c);
      std::sort(mode.begin(), mode.end(),
                [](const Cell* a, const Cell* b) { return a->points < b->points; });
      const nlohmann::json x = crossover(mode, o.size * o.size);
      js["crossover"][layers ? "all_layers" : "front"] = x;
      std::printf("   crossover (%s): %s\n", layers ? "all" : "front",
                  x["text"].get<std::string>().c_str());
    }
    std::printf("\n");
    out["scenes"].push_back(js);
  }
  std::printf(
      "ratio = median(update + pick) / median(embree pick) (< 1: the ID buffer wins); "
      "pick/emb = median(pick) / median(embree pick), a frame already rasterized.\n");

  if (!o.json.empty()) {
    writeFileAtomically(o.json, "results", out.dump(2) + "\n");
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(parseArgs(argc, argv));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "strata_pick_bench: %s\n", e.what());
    return 1;
  }
}
