// `strata bench --soak`: many frames of a moving camera per method, host and device memory
// sampled along the way. A leak shows as growth; the report says whether each method stays flat.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "engine/renderer.h"

namespace strata {

struct SoakOptions {
  std::vector<std::string> methods;  // empty: every registered method
  std::string scene = "builtin:demo";
  int width = 128, height = 128;
  int frames = 10000;
  int sample_every = 100;
  float orbit_deg = 1.0f;  // degrees of azimuth per frame: every frame a new view
  DeviceOptions device;
  std::string out_dir = "bench-out";
  // Progress: (method, frames done, frames asked for).
  std::function<void(const std::string&, int, int)> on_progress;
};

struct SoakSample {
  int frame = 0;              // frames finished
  uint64_t host_rss = 0;      // resident set of the process, bytes (not the peak)
  uint64_t device_bytes = 0;  // device buffers alive (deviceBytesInUse)
  double ms_per_frame = 0.0;  // wall time per frame since the previous sample
};

struct SoakRun {
  std::string method;
  bool ok = false;
  std::string error;
  std::vector<SoakSample> samples;
  // (largest - smallest) / smallest over the samples, from the first one (frame sample_every).
  double host_rss_spread = 0.0, device_bytes_spread = 0.0;
};

// Within this relative spread a run counts as flat.
inline constexpr double kSoakFlatSpread = 0.01;

// Runs every method in turn in this process (each its own renderer, released before the next),
// writes soak.json and soak.md into out_dir and returns the runs.
std::vector<SoakRun> runSoak(const SoakOptions& options);
std::string soakMarkdown(const SoakOptions& options, const std::vector<SoakRun>& runs);

}  // namespace strata
