// Report writers of `strata bench`: JSON and CSV for machines, Markdown tables laid out like the
// papers' tables, and a self-contained HTML page (tables, inline SVG charts, images embedded as
// data URIs) that opens in a browser with no network.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

#include "engine/report/bench.h"
#include "engine/report/stats_json.h"

namespace strata {

namespace fs = std::filesystem;

namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

std::string mb(uint64_t bytes) { return fmt("%.1f", double(bytes) / (1024.0 * 1024.0)); }

// A case group: one scene at one size (its views are averaged).
std::string groupOf(const BenchCase& c) {
  return c.label + " " + std::to_string(c.width) + "x" + std::to_string(c.height);
}

struct Cell {
  int runs = 0, failed = 0, views = 0;
  double sum_ms = 0.0, sum_fps = 0.0, min_within_2 = 1.0;
  int moving_runs = 0;  // views whose moving-camera run succeeded
  double sum_moving_ms = 0.0, sum_still_ms_of_moving = 0.0;
  uint64_t device_bytes = 0, fragment_bytes = 0, lost = 0, bytes_needed = 0, triangles = 0,
           max_depth = 0, passes = 0;
  std::string error;
};

// Aggregates rows by (group, method), groups in order of appearance.
struct Table {
  std::vector<std::string> groups;
  std::map<std::string, const BenchCase*> group_case;
  std::map<std::pair<std::string, std::string>, Cell> cells;
};

Table aggregate(const BenchResult& r) {
  Table t;
  for (const BenchRow& row : r.rows) {
    const std::string g = groupOf(row.bench_case);
    if (!t.group_case.count(g)) {
      t.groups.push_back(g);
      t.group_case[g] = &row.bench_case;
    }
    Cell& c = t.cells[{g, row.method}];
    ++c.views;
    if (!row.ok) {
      ++c.failed;
      c.error = row.error;
      continue;
    }
    ++c.runs;
    c.sum_ms += row.stats.frame_ms.median;
    c.sum_fps += row.stats.frame_ms.median > 0.0 ? 1000.0 / row.stats.frame_ms.median : 0.0;
    c.min_within_2 = std::min(c.min_within_2, row.diff.within_2);
    c.device_bytes = std::max(c.device_bytes, row.stats.device_bytes);
    c.fragment_bytes = std::max(c.fragment_bytes, row.stats.fragment_bytes);
    c.lost += row.stats.fragments_lost;
    c.bytes_needed = std::max(c.bytes_needed, row.stats.bytes_needed);
    c.triangles = row.stats.triangles;
    c.max_depth = std::max(c.max_depth, row.stats.max_depth_complexity);
    c.passes = std::max(c.passes, row.stats.geometry_passes);
    if (row.moving_ok) {
      ++c.moving_runs;
      c.sum_moving_ms += row.moving.frame_ms.mean;  // the frames that order a view included
      c.sum_still_ms_of_moving += row.stats.frame_ms.median;
    }
  }
  return t;
}

std::string shortError(const std::string& e) { return e.size() > 60 ? e.substr(0, 57) + "..." : e; }

// A table cell for frame time / fps: the value, or why there is none.
std::string timeCell(const Cell& c, bool fps) {
  if (c.runs == 0 && c.error == kNotRunBySuite) return "-";
  if (c.runs == 0)
    return c.bytes_needed ? "does not fit (needs " + mb(c.bytes_needed) + " MB)"
                          : "fails: " + shortError(c.error);
  std::string s = fps ? fmt("%.1f", c.sum_fps / c.runs) : fmt("%.1f", c.sum_ms / c.runs);
  if (c.lost) s += " (lost " + std::to_string(c.lost) + ")";
  return s;
}

std::string escapeCsv(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (char ch : s) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

std::string escapeHtml(const std::string& s) {
  std::string out;
  for (char ch : s) {
    switch (ch) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

// Standard base64 (RFC 4648) for data URIs; small enough to write here.
std::string base64(const std::string& in) {
  static const char* abc = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v =
        (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8 | (unsigned char)in[i + 2];
    out += {abc[v >> 18], abc[(v >> 12) & 63], abc[(v >> 6) & 63], abc[v & 63]};
  }
  if (i + 1 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16;
    out += {abc[v >> 18], abc[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == in.size()) {
    const unsigned v = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8;
    out += {abc[v >> 18], abc[(v >> 12) & 63], abc[(v >> 6) & 63], '='};
  }
  return out;
}

// The first `count` rows of a Markdown/HTML table: (header, rows).
struct TextTable {
  std::string title, note;
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
};

// A table of one row per scene and one column per method, each cell cell(c) of that scene and
// method.
TextTable methodTable(const Table& t, const BenchResult& r, std::string title,
                      const std::function<std::string(const Cell&)>& cell) {
  TextTable out;
  out.title = std::move(title);
  out.header = {"scene"};
  for (const std::string& m : r.methods) out.header.push_back(m);
  for (const std::string& g : t.groups) {
    std::vector<std::string> row = {g};
    for (const std::string& m : r.methods) row.push_back(cell(t.cells.at({g, m})));
    out.rows.push_back(row);
  }
  return out;
}

// Every method's frame time against `base`'s, per scene: base / method when `base_over` (the
// method's speedup over base), else method / base (base's speedup over the method).
TextTable ratioTable(const Table& t, const BenchResult& r, const std::string& base, bool base_over,
                     std::string title) {
  TextTable ratio;
  ratio.title = std::move(title);
  ratio.header = {"scene"};
  for (const std::string& m : r.methods)
    if (m != base) ratio.header.push_back(m);
  for (const std::string& g : t.groups) {
    const Cell& b = t.cells.at({g, base});
    std::vector<std::string> row = {g};
    for (const std::string& m : r.methods) {
      if (m == base) continue;
      const Cell& c = t.cells.at({g, m});
      const double bm = b.sum_ms / b.runs, cm = c.sum_ms / c.runs;
      row.push_back(b.runs && c.runs ? fmt("%.2fx", base_over ? bm / cm : cm / bm) : "-");
    }
    ratio.rows.push_back(row);
  }
  return ratio;
}

TextTable speedTable(const Table& t, const BenchResult& r, bool multi_view) {
  TextTable speed;
  speed.title = multi_view ? "Frames per second (mean over the views of each model)"
                           : "Frame time (median ms)";
  speed.header = {"scene", "triangles", "max depth"};
  for (const std::string& m : r.methods) speed.header.push_back(m);
  for (const std::string& g : t.groups) {
    uint64_t tris = 0, depth = 0;
    for (const std::string& m : r.methods) {
      auto it = t.cells.find({g, m});
      if (it != t.cells.end()) {
        tris = std::max(tris, it->second.triangles);
        depth = std::max(depth, it->second.max_depth);
      }
    }
    std::vector<std::string> row = {g, std::to_string(tris), std::to_string(depth)};
    for (const std::string& m : r.methods) row.push_back(timeCell(t.cells.at({g, m}), multi_view));
    speed.rows.push_back(row);
  }
  speed.note = "\"lost N\": fragments a fixed-budget method dropped (its image is not exact).";
  return speed;
}

// The raster core's stages alone, per triangle and per fragment (every suite records them;
// the raster suite's scenes isolate triangle sizes).
TextTable rasterStagesTable(const BenchResult& r) {
  TextTable stages;
  stages.title =
      "Raster stages: ns per triangle (front end: transform and setup; binning) and per "
      "fragment (fine raster), median frame";
  stages.header = {
      "scene",   "method", "px / triangle", "front end ns/tri", "bin ns/tri", "fine raster ns/frag",
      "frame ms"};
  auto stage = [](const FrameStats& st, std::initializer_list<const char*> names) {
    double ms = 0.0;
    for (const char* n : names) {
      auto it = st.stage_ms.find(n);
      if (it != st.stage_ms.end()) ms += it->second;
    }
    return ms;
  };
  for (const BenchRow& row : r.rows) {
    if (!row.ok) continue;
    const FrameStats& st = row.stats;
    const double tris = double(std::max<uint64_t>(st.triangles, 1));
    const double frags = double(std::max<uint64_t>(st.fragments, 1));
    const double front = stage(st, {"transform", "setup"});
    const double bin = stage(st, {"bin"});
    const double fine = stage(st, {"raster", "raster+resolve", "composite", "trace"});
    stages.rows.push_back({row.bench_case.label, row.method, fmt("%.1f", frags / tris),
                           front > 0 ? fmt("%.1f", front * 1e6 / tris) : "-",
                           bin > 0 ? fmt("%.1f", bin * 1e6 / tris) : "-",
                           fine > 0 ? fmt("%.2f", fine * 1e6 / frags) : "-",
                           fmt("%.1f", st.frame_ms.median)});
  }
  stages.note =
      "The fine raster is the method's tile stage (opaque and ppll: raster; abuffer: "
      "raster+resolve; cells: composite; embree: trace), divided by every fragment it "
      "produced, so it includes per-pixel resolve work; px / triangle is fragments per "
      "triangle (all layers).";
  return stages;
}

std::vector<TextTable> tables(const BenchResult& r) {
  const Table t = aggregate(r);
  std::vector<TextTable> out;
  bool multi_view = false;
  for (const auto& [key, c] : t.cells) multi_view |= c.views > 1;
  auto has = [&](const std::string& m) {
    return std::find(r.methods.begin(), r.methods.end(), m) != r.methods.end();
  };
  out.push_back(speedTable(t, r, multi_view));

  // Speedup of the headline method over each other method, as in the paper's Table 1.
  const std::string base = has("cells") ? "cells" : "ppll";
  if (has(base)) {
    out.push_back(ratioTable(t, r, base, false,
                             "Speedup of " + base + " over each method (frame time ratio)"));
    if (base != "cells")
      out.back().note = "`cells` was not in this run, so ratios are against ppll.";
  }
  // The octree paper's Table 1: every method against depth peeling on the same scene.
  const bool has_octree = std::any_of(r.methods.begin(), r.methods.end(), [](const std::string& m) {
    return m.rfind("octree", 0) == 0;
  });
  if (has_octree && has("dp"))
    out.push_back(ratioTable(t, r, "dp", true, "Speedup over dp (dp's frame time / the method's)"));

  // The moving camera: each frame a new view (the still table's frames reuse per-view work).
  float orbit = 0.0f;
  for (const BenchRow& row : r.rows)
    if (row.moving_ok) orbit = row.moving.orbit_deg;
  if (orbit != 0.0f) {
    out.push_back(methodTable(
        t, r,
        "Moving camera (" + fmt("%g", orbit) +
            " degrees per frame): mean frame time in ms (over the frames of each view's run, "
            "then over views), and moving / still",
        [](const Cell& c) {
          return c.moving_runs ? fmt("%.1f", c.sum_moving_ms / c.moving_runs) + " (" +
                                     fmt("%.2fx", c.sum_moving_ms / c.sum_still_ms_of_moving) + ")"
                               : std::string("-");
        }));
    out.back().note =
        "Every frame of the moving run is a new view, so its time includes all per-view work "
        "(the cells order, texturing records); the still frames reuse it. cells may draw a view "
        "with the order of one a few frames before (checked and repaired as it composites): the "
        "mean counts the frames that make an order too.";
  }
  if (r.suite.name == "raster") out.push_back(rasterStagesTable(r));

  out.push_back(methodTable(
      t, r, "Device memory (MB): working set / of which fragment storage", [](const Cell& c) {
        if (!c.runs) return std::string("-");
        return mb(c.device_bytes) + " / " + mb(c.fragment_bytes) +
               (c.bytes_needed > c.fragment_bytes ? " (needs " + mb(c.bytes_needed) + ")" : "");
      }));
  out.back().note = "embree: host memory of its per-thread hit lists (the BVH is not counted).";

  out.push_back(
      methodTable(t, r, "Accuracy against embree: worst view's share of pixels within 2/255",
                  [](const Cell& c) {
                    return c.runs ? fmt("%.2f%%", 100.0 * c.min_within_2) : std::string("-");
                  }));
  out.back().note =
      "Exact methods must reach 99.5%; the approximate ones report their error. "
      "opaque is compared with Embree's nearest hit.";
  return out;
}

// Series for the charts: per method, (depth layers, value) over the cases with known layers.
std::map<std::string, std::vector<std::pair<double, double>>> series(const BenchResult& r,
                                                                     bool memory, int size) {
  std::map<std::string, std::vector<std::pair<double, double>>> out;
  for (const BenchRow& row : r.rows) {
    if (!row.ok || row.bench_case.layers == 0 || row.bench_case.width != size) continue;
    const double v =
        memory ? double(row.stats.device_bytes) / (1024.0 * 1024.0) : row.stats.frame_ms.median;
    out[row.method].emplace_back(row.bench_case.layers, v);
  }
  for (auto& [m, pts] : out) std::sort(pts.begin(), pts.end());
  return out;
}

const char* kColors[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                         "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#000000"};

std::string lineChart(const std::string& title, const std::string& ylabel,
                      const std::map<std::string, std::vector<std::pair<double, double>>>& s,
                      const std::string& xlabel = "depth layers") {
  double xmin = 1e30, xmax = -1e30, ymax = 0.0;
  for (const auto& [m, pts] : s)
    for (auto [x, y] : pts) {
      xmin = std::min(xmin, x);
      xmax = std::max(xmax, x);
      ymax = std::max(ymax, y);
    }
  if (s.empty()) return "";
  if (xmax <= xmin) {  // a single depth: centre its points
    xmin -= 1.0;
    xmax += 1.0;
  }
  if (ymax <= 0.0) ymax = 1.0;
  ymax *= 1.1;
  const double W = 640, H = 320, L = 70, R = 150, T = 30, B = 40;
  auto px = [&](double x) { return L + (x - xmin) / (xmax - xmin) * (W - L - R); };
  auto py = [&](double y) { return H - B - y / ymax * (H - T - B); };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' class='chart'>";
  o << "<text x='" << L << "' y='18' font-weight='bold'>" << escapeHtml(title) << "</text>";
  o << "<line x1='" << L << "' y1='" << H - B << "' x2='" << W - R << "' y2='" << H - B
    << "' stroke='#333'/>";
  o << "<line x1='" << L << "' y1='" << T << "' x2='" << L << "' y2='" << H - B
    << "' stroke='#333'/>";
  for (int i = 0; i <= 4; ++i) {
    const double y = ymax * i / 4.0;
    o << "<text x='" << L - 6 << "' y='" << py(y) + 4 << "' text-anchor='end' font-size='11'>"
      << fmt("%.0f", y) << "</text>";
    o << "<line x1='" << L << "' y1='" << py(y) << "' x2='" << W - R << "' y2='" << py(y)
      << "' stroke='#eee'/>";
  }
  std::set<double> xs;
  for (const auto& [m, pts] : s)
    for (auto [x, y] : pts) xs.insert(x);
  for (double x : xs)
    o << "<text x='" << px(x) << "' y='" << H - B + 16 << "' text-anchor='middle' font-size='11'>"
      << fmt("%.0f", x) << "</text>";
  o << "<text x='" << (L + W - R) / 2 << "' y='" << H - 6
    << "' text-anchor='middle' font-size='12'>" << escapeHtml(xlabel) << "</text>";
  o << "<text x='14' y='" << (T + H - B) / 2 << "' font-size='12' transform='rotate(-90 14 "
    << (T + H - B) / 2 << ")' text-anchor='middle'>" << escapeHtml(ylabel) << "</text>";
  int i = 0;
  for (const auto& [m, pts] : s) {
    const char* color = kColors[i % 11];
    o << "<polyline fill='none' stroke='" << color << "' stroke-width='2' points='";
    for (auto [x, y] : pts) o << px(x) << "," << py(y) << " ";
    o << "'/>";
    for (auto [x, y] : pts)
      o << "<circle cx='" << px(x) << "' cy='" << py(y) << "' r='3' fill='" << color << "'/>";
    o << "<text x='" << W - R + 10 << "' y='" << T + 14 * i + 10 << "' fill='" << color
      << "' font-size='12'>" << escapeHtml(m) << "</text>";
    ++i;
  }
  o << "</svg>";
  return o.str();
}

std::string barChart(const std::string& title,
                     const std::vector<std::pair<std::string, double>>& bars) {
  if (bars.empty()) return "";
  double vmax = 0.0;
  for (auto& [m, v] : bars) vmax = std::max(vmax, v);
  if (vmax <= 0.0) return "";
  const double W = 640, row = 20, L = 90, T = 30;
  const double H = T + row * bars.size() + 10;
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H
    << "' class='chart'>";
  o << "<text x='" << L << "' y='18' font-weight='bold'>" << escapeHtml(title) << "</text>";
  int i = 0;
  for (auto& [m, v] : bars) {
    const double y = T + row * i;
    const double w = v / vmax * (W - L - 90);
    o << "<text x='" << L - 6 << "' y='" << y + 14 << "' text-anchor='end' font-size='12'>"
      << escapeHtml(m) << "</text>";
    o << "<rect x='" << L << "' y='" << y + 3 << "' width='" << w << "' height='" << row - 6
      << "' fill='" << kColors[i % 11] << "'/>";
    o << "<text x='" << L + w + 4 << "' y='" << y + 14 << "' font-size='11'>" << fmt("%.1f", v)
      << " ms</text>";
    ++i;
  }
  o << "</svg>";
  return o.str();
}

std::string fileDataUri(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) return "";
  std::ostringstream ss;
  ss << in.rdbuf();
  return "data:image/png;base64," + base64(ss.str());
}

// A smaller copy for the page (box filter), so big suites keep the HTML reasonable.
Image thumbnail(const Image& img, int max_side) {
  const int f = std::max(1, (std::max(img.width, img.height) + max_side - 1) / max_side);
  if (f == 1) return img;
  Image t(img.width / f, img.height / f);
  for (int y = 0; y < t.height; ++y)
    for (int x = 0; x < t.width; ++x)
      for (int c = 0; c < 4; ++c) {
        int sum = 0;
        for (int dy = 0; dy < f; ++dy)
          for (int dx = 0; dx < f; ++dx) sum += img.pixel(x * f + dx, y * f + dy)[c];
        t.pixel(x, y)[c] = uint8_t(sum / (f * f));
      }
  return t;
}

std::string embeddedImage(const fs::path& out_dir, const std::string& file) {
  const fs::path full = out_dir / file;
  std::error_code ec;
  if (!fs::exists(full, ec)) return "";
  const Image img = readImage(full.string());
  if (std::max(img.width, img.height) <= 256) return fileDataUri(full);
  const fs::path thumb = out_dir / "images" / "thumbs" / fs::path(file).filename();
  fs::create_directories(thumb.parent_path(), ec);
  writeImage(thumbnail(img, 256), thumb.string());
  return fileDataUri(thumb);
}

}  // namespace

std::string benchJson(const BenchResult& r) {
  nlohmann::json j;
  j["suite"] = r.suite.name;
  j["description"] = r.suite.description;
  j["device"] = r.device;
  j["methods"] = r.methods;
  nlohmann::json rows = nlohmann::json::array();
  for (const BenchRow& row : r.rows) {
    nlohmann::json o;
    o["scene"] = row.bench_case.scene;
    o["label"] = row.bench_case.label;
    o["width"] = row.bench_case.width;
    o["height"] = row.bench_case.height;
    if (row.bench_case.view) {
      o["azimuth"] = row.bench_case.view->azimuth_deg;
      o["elevation"] = row.bench_case.view->elevation_deg;
    }
    o["layers"] = row.bench_case.layers;
    o["k"] = row.bench_case.k;
    o["method"] = row.method;
    o["ok"] = row.ok;
    o["exact_expected"] = row.exact_expected;
    if (!row.ok) o["error"] = row.error;
    if (row.ok) {
      o["stats"] = statsToJson(row.stats, row.bench_case.scene);
      o["error_vs_embree"] = {
          {"within_1", row.diff.within_1},
          {"within_2", row.diff.within_2},
          {"max_abs", row.diff.max_abs},
          {"mean_abs", row.diff.mean_abs},
          {"psnr_db",
           std::isinf(row.diff.psnr) ? nlohmann::json("inf") : nlohmann::json(row.diff.psnr)}};
      o["image"] = row.image_file;
      o["diff_image"] = row.diff_file;
      if (row.moving_ok)
        o["moving"] = statsToJson(row.moving, row.bench_case.scene);
      else if (!row.moving_error.empty())
        o["moving_error"] = row.moving_error;
    }
    rows.push_back(o);
  }
  j["rows"] = rows;
  return j.dump(2) + "\n";
}

std::string benchCsv(const BenchResult& r) {
  std::ostringstream o;
  o << "suite,scene,label,width,height,azimuth,elevation,layers,k,method,ok,error,median_ms,min_ms,"
       "max_ms,fps,triangles,triangles_read,geometry_passes,fragments,max_depth_complexity,"
       "device_bytes,fragment_bytes,fragments_lost,bytes_needed,within_1,within_2,max_abs_error,"
       "image,moving_median_ms,moving_order_ms,moving_mean_ms\n";
  for (const BenchRow& row : r.rows) {
    const BenchCase& c = row.bench_case;
    const FrameStats& s = row.stats;
    o << r.suite.name << "," << escapeCsv(c.scene) << "," << escapeCsv(c.label) << "," << c.width
      << "," << c.height << "," << (c.view ? fmt("%g", c.view->azimuth_deg) : "") << ","
      << (c.view ? fmt("%g", c.view->elevation_deg) : "") << "," << c.layers << "," << c.k << ","
      << row.method << "," << (row.ok ? 1 : 0) << "," << escapeCsv(row.error) << ",";
    if (row.ok)
      o << fmt("%.3f", s.frame_ms.median) << "," << fmt("%.3f", s.frame_ms.min) << ","
        << fmt("%.3f", s.frame_ms.max) << ","
        << fmt("%.2f", s.frame_ms.median > 0 ? 1000.0 / s.frame_ms.median : 0.0) << ","
        << s.triangles << "," << s.triangles_read << "," << s.geometry_passes << "," << s.fragments
        << "," << s.max_depth_complexity << "," << s.device_bytes << "," << s.fragment_bytes << ","
        << s.fragments_lost << "," << s.bytes_needed << "," << fmt("%.6f", row.diff.within_1) << ","
        << fmt("%.6f", row.diff.within_2) << "," << row.diff.max_abs << "," << row.image_file << ","
        << (row.moving_ok ? fmt("%.3f", row.moving.frame_ms.median) : "") << ","
        << (row.moving_ok && row.moving.method == "cells" ? fmt("%.3f", row.moving.order_ms) : "")
        << "," << (row.moving_ok ? fmt("%.3f", row.moving.frame_ms.mean) : "");
    else
      o << std::string(19, ',');  // the 20 fields after `error`, empty
    o << "\n";
  }
  return o.str();
}

std::string benchMarkdown(const BenchResult& r) {
  std::ostringstream o;
  o << "# strata bench: " << r.suite.name << "\n\n" << r.suite.description << "\n\n";
  o << "Device: " << (r.device.empty() ? "(no OpenCL method ran)" : r.device) << "  \n";
  o << "Methods: ";
  for (size_t i = 0; i < r.methods.size(); ++i) o << (i ? ", " : "") << r.methods[i];
  o << "\n\n";
  for (const TextTable& t : tables(r)) {
    o << "## " << t.title << "\n\n|";
    for (const std::string& h : t.header) o << " " << h << " |";
    o << "\n|";
    for (size_t i = 0; i < t.header.size(); ++i) o << (i ? "---:|" : "---|");
    o << "\n";
    for (const auto& row : t.rows) {
      o << "|";
      for (const std::string& cell : row) o << " " << cell << " |";
      o << "\n";
    }
    if (!t.note.empty()) o << "\n" << t.note << "\n";
    o << "\n";
  }
  return o.str();
}

namespace {

// The suite's tables, as in the Markdown report.
void htmlTables(std::ostringstream& o, const BenchResult& r) {
  for (const TextTable& t : tables(r)) {
    o << "<h2>" << escapeHtml(t.title) << "</h2><table><tr>";
    for (const std::string& h : t.header) o << "<th>" << escapeHtml(h) << "</th>";
    o << "</tr>";
    for (const auto& row : t.rows) {
      o << "<tr>";
      for (const std::string& cell : row) o << "<td>" << escapeHtml(cell) << "</td>";
      o << "</tr>";
    }
    o << "</table>";
    if (!t.note.empty()) o << "<p>" << escapeHtml(t.note) << "</p>";
    o << "\n";
  }
}

// Charts: against depth where the suite varies it, against scene size and depth where its
// scenes differ in both (the octree suite), and the mean frame time per method.
void htmlCharts(std::ostringstream& o, const BenchResult& r) {
  o << "<h2>Charts</h2>\n";
  std::set<int> sizes;
  for (const BenchRow& row : r.rows)
    if (row.bench_case.layers) sizes.insert(row.bench_case.width);
  for (int size : sizes) {
    const std::string sz = std::to_string(size) + "x" + std::to_string(size);
    o << lineChart("Frame time against depth (" + sz + ")", "median frame time (ms)",
                   series(r, false, size));
    o << lineChart("Device memory against depth (" + sz + ")", "device memory (MB)",
                   series(r, true, size));
  }
  // Scenes of different sizes and depths (the octree suite): frame time against both.
  if (sizes.empty()) {
    std::map<std::string, std::vector<std::pair<double, double>>> by_size, by_depth;
    std::set<std::string> scenes;
    for (const BenchRow& row : r.rows) {
      if (!row.ok) continue;
      scenes.insert(row.bench_case.scene);
      by_size[row.method].emplace_back(double(row.stats.triangles) / 1e6,
                                       row.stats.frame_ms.median);
      by_depth[row.method].emplace_back(double(row.stats.max_depth_complexity),
                                        row.stats.frame_ms.median);
    }
    for (auto* s : {&by_size, &by_depth})
      for (auto& [m, pts] : *s) std::sort(pts.begin(), pts.end());
    if (scenes.size() > 2) {
      o << lineChart("Frame time against scene size", "median frame time (ms)", by_size,
                     "triangles (millions)");
      o << lineChart("Frame time against depth complexity", "median frame time (ms)", by_depth,
                     "max depth complexity");
    }
  }
  {
    std::vector<std::pair<std::string, double>> bars;
    for (const std::string& m : r.methods) {
      double sum = 0.0;
      int n = 0;
      for (const BenchRow& row : r.rows)
        if (row.method == m && row.ok) {
          sum += row.stats.frame_ms.median;
          ++n;
        }
      if (n) bars.emplace_back(m, sum / n);
    }
    o << barChart("Mean frame time over all cases", bars);
  }
}

// Per case, the reference, every method and its difference image (x8).
void htmlImages(std::ostringstream& o, const BenchResult& r, const std::string& out_dir) {
  o << "<h2>Images</h2>\n";
  const fs::path out(out_dir);
  std::string last_case;
  for (const BenchRow& row : r.rows) {
    const BenchCase& c = row.bench_case;
    std::string id = groupOf(c);
    if (c.view) id += fmt(" az %.0f", c.view->azimuth_deg) + fmt(" el %.0f", c.view->elevation_deg);
    if (id != last_case) {
      if (!last_case.empty()) o << "</div>\n";
      o << "<h3>" << escapeHtml(id) << "</h3><div>";
      o << "<figure><img alt='embree reference' src='" << embeddedImage(out, row.reference_file)
        << "'>reference (embree)</figure>";
      last_case = id;
    }
    if (!row.ok) {
      o << "<figure class='fail'>" << escapeHtml(row.method) << ": " << escapeHtml(row.error)
        << "</figure>";
      continue;
    }
    o << "<figure><img alt='" << escapeHtml(row.method) << "' src='"
      << embeddedImage(out, row.image_file) << "'>" << escapeHtml(row.method) << " "
      << fmt("%.1f ms", row.stats.frame_ms.median) << "<br>"
      << fmt("%.2f%% within 2/255", 100.0 * row.diff.within_2) << "</figure>";
    o << "<figure><img alt='" << escapeHtml(row.method) << " difference' src='"
      << embeddedImage(out, row.diff_file) << "'>|" << escapeHtml(row.method)
      << " - embree| x8<br>max " << row.diff.max_abs << "/255</figure>";
  }
  if (!last_case.empty()) o << "</div>\n";
}

}  // namespace

std::string benchHtml(const BenchResult& r, const std::string& out_dir) {
  std::ostringstream o;
  o << "<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>strata bench: "
    << escapeHtml(r.suite.name)
    << "</title><style>body{font-family:sans-serif;margin:2em;max-width:1400px}"
       "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;"
       "text-align:right}td:first-child,th:first-child{text-align:left}th{background:#f4f4f4}"
       "figure{display:inline-block;margin:4px;text-align:center;font-size:12px}"
       "figure img{display:block;image-rendering:pixelated}.fail{color:#b00}.chart{margin:1em 0}"
       "</style></head><body>\n";
  o << "<h1>strata bench: " << escapeHtml(r.suite.name) << "</h1><p>"
    << escapeHtml(r.suite.description) << "</p>";
  o << "<p>Device: " << escapeHtml(r.device) << "</p>\n";
  htmlTables(o, r);
  htmlCharts(o, r);
  htmlImages(o, r, out_dir);
  o << "</body></html>\n";
  return o.str();
}

}  // namespace strata
