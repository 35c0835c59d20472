#include "engine/report/soak.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include <nlohmann/json.hpp>

#include "engine/renderer.h"
#include "engine/report/stats_json.h"
#include "preprocess/builtin_scenes.h"
#include "strata/error.h"

namespace strata {

namespace {

// The current resident set (not getrusage's peak, which can only grow and would hide a return
// to the baseline).
uint64_t residentBytes() {
  std::ifstream statm("/proc/self/statm");
  uint64_t size = 0, resident = 0;
  statm >> size >> resident;
  return resident * uint64_t(sysconf(_SC_PAGESIZE));
}

double spread(const std::vector<SoakSample>& samples, uint64_t SoakSample::*field) {
  if (samples.empty()) return 0.0;
  uint64_t lo = samples.front().*field, hi = lo;
  for (const SoakSample& s : samples) {
    lo = std::min(lo, s.*field);
    hi = std::max(hi, s.*field);
  }
  return lo == 0 ? (hi == 0 ? 0.0 : 1.0) : double(hi - lo) / double(lo);
}

std::string mib(uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.2f", double(bytes) / (1024.0 * 1024.0));
  return text;
}

}  // namespace

std::vector<SoakRun> runSoak(const SoakOptions& opt) {
  checkFrameCount(opt.frames, "--frames");
  if (opt.sample_every < 1 || opt.sample_every > opt.frames)
    throw Error("the soak's sampling interval must be between 1 and the frame count");
  const std::vector<std::string> methods = opt.methods.empty() ? methodNames() : opt.methods;
  for (const std::string& m : methods) parseMethod(m);  // fail before any work
  std::error_code ec;
  std::filesystem::create_directories(opt.out_dir, ec);
  if (ec) throw Error(opt.out_dir + ": cannot create the output folder (" + ec.message() + ")");

  const Scene scene = loadScene(opt.scene);
  const WorldGeometry geometry = WorldGeometry::fromScene(scene);
  std::vector<SoakRun> runs;
  for (const std::string& m : methods) {
    SoakRun run;
    run.method = m;
    FrameSettings settings;
    settings.width = opt.width;
    settings.height = opt.height;
    settings.frames = opt.frames;
    settings.orbit_deg = opt.orbit_deg;
    settings.k = 64;
    settings.camera =
        Camera::orbit(scene.boundingSphere(), scene.default_view.value_or(OrbitView{}),
                      scene.default_projection.value_or(Projection::Perspective));
    using Clock = std::chrono::steady_clock;
    Clock::time_point last = Clock::now();
    int last_frame = 0;
    settings.on_frame = [&](int done, int total) {
      if (done % opt.sample_every == 0 || done == total) {
        const Clock::time_point now = Clock::now();
        SoakSample s;
        s.frame = done;
        s.host_rss = residentBytes();
        s.device_bytes = deviceBytesInUse();
        s.ms_per_frame = std::chrono::duration<double, std::milli>(now - last).count() /
                         std::max(1, done - last_frame);
        run.samples.push_back(s);
        last = now;
        last_frame = done;
      }
      if (opt.on_progress) opt.on_progress(m, done, total);
    };
    try {
      std::unique_ptr<MethodRenderer> renderer = makeRenderer(parseMethod(m), opt.device);
      renderer->render(geometry, settings);
      run.ok = true;
    } catch (const Error& e) {
      run.error = e.what();
    }
    // The first sample is taken after sample_every frames: warm-up (programs, first buffers)
    // is over by then.
    run.host_rss_spread = spread(run.samples, &SoakSample::host_rss);
    run.device_bytes_spread = spread(run.samples, &SoakSample::device_bytes);
    runs.push_back(std::move(run));
  }

  nlohmann::json j = {{"scene", opt.scene},
                      {"width", opt.width},
                      {"height", opt.height},
                      {"frames", opt.frames},
                      {"sample_every", opt.sample_every},
                      {"orbit_deg", opt.orbit_deg},
                      {"flat_spread", kSoakFlatSpread}};
  for (const SoakRun& r : runs) {
    const bool flat =
        r.ok && r.host_rss_spread <= kSoakFlatSpread && r.device_bytes_spread <= kSoakFlatSpread;
    nlohmann::json jr = {{"method", r.method},
                         {"ok", r.ok},
                         {"host_rss_spread", r.host_rss_spread},
                         {"device_bytes_spread", r.device_bytes_spread},
                         {"flat", flat}};
    if (!r.ok) jr["error"] = r.error;
    for (const SoakSample& s : r.samples)
      jr["samples"].push_back({{"frame", s.frame},
                               {"host_rss", s.host_rss},
                               {"device_bytes", s.device_bytes},
                               {"ms_per_frame", s.ms_per_frame}});
    j["runs"].push_back(jr);
  }
  const std::filesystem::path out(opt.out_dir);
  writeTextFileAtomically((out / "soak.json").string(), j.dump(2) + "\n");
  writeTextFileAtomically((out / "soak.md").string(), soakMarkdown(opt, runs));
  return runs;
}

std::string soakMarkdown(const SoakOptions& opt, const std::vector<SoakRun>& runs) {
  std::ostringstream md;
  md << "# strata bench --soak\n\n"
     << opt.frames << " frames of " << opt.scene << " at " << opt.width << "x" << opt.height
     << ", the camera turning " << opt.orbit_deg << " degrees per frame; host RSS and device "
     << "buffers sampled every " << opt.sample_every << " frames. Flat: the samples' spread "
     << "((largest - smallest) / smallest) within " << kSoakFlatSpread * 100.0 << "%.\n\n"
     << "| method | host RSS MiB (first .. last) | spread | device MiB (first .. last) | spread "
        "| ms/frame (first .. last) | flat |\n"
     << "|---|---:|---:|---:|---:|---:|---|\n";
  char pct[2][32];
  for (const SoakRun& r : runs) {
    if (!r.ok || r.samples.empty()) {
      md << "| " << r.method << " | failed: " << r.error << " | | | | | no |\n";
      continue;
    }
    const SoakSample &a = r.samples.front(), &b = r.samples.back();
    std::snprintf(pct[0], sizeof(pct[0]), "%.3f%%", r.host_rss_spread * 100.0);
    std::snprintf(pct[1], sizeof(pct[1]), "%.3f%%", r.device_bytes_spread * 100.0);
    char ms[64];
    std::snprintf(ms, sizeof(ms), "%.2f .. %.2f", a.ms_per_frame, b.ms_per_frame);
    const bool flat =
        r.host_rss_spread <= kSoakFlatSpread && r.device_bytes_spread <= kSoakFlatSpread;
    md << "| " << r.method << " | " << mib(a.host_rss) << " .. " << mib(b.host_rss) << " | "
       << pct[0] << " | " << mib(a.device_bytes) << " .. " << mib(b.device_bytes) << " | " << pct[1]
       << " | " << ms << " | " << (flat ? "yes" : "**no**") << " |\n";
  }
  return md.str();
}

}  // namespace strata
