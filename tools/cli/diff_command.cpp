// strata diff: two images compared (PSNR, RMSE, SSIM, largest and mean error, the share of
// pixels within 1 and 2 of 255), a difference image, and a gate on one metric for the user's own
// CI.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "preprocess/core/enum_table.h"

#include "preprocess/image_io.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace {

// The exit status of a comparison whose metric misses its threshold (errors exit 1).
constexpr int kThresholdMissed = 3;

// The metrics a threshold can gate; for the first three a larger value is better.
enum class Metric { Psnr, Within2, Ssim, Rmse, MaxError, MeanError };
constexpr const char* kMetricNames[] = {"psnr", "within2", "ssim", "rmse", "max", "mean"};

// What the metrics are computed from: the per-pixel differences and the SSIM (NaN for images
// under kSsimMinSize pixels a side).
struct Measured {
  ImageDiff diff;
  double ssim = std::nan("");
};

double metricValue(Metric m, const Measured& measured) {
  const ImageDiff& d = measured.diff;
  switch (m) {
    case Metric::Psnr:
      return d.psnr;
    case Metric::Within2:
      return d.within_2;
    case Metric::Ssim:
      return measured.ssim;
    case Metric::Rmse:
      return d.rmse;
    case Metric::MaxError:
      return d.max_abs;
    case Metric::MeanError:
      return d.mean_abs;
  }
  return 0.0;
}

struct Gate {
  std::string metric;  // empty: no gate
  double threshold = 0.0;
};

// 0 when the gate passes (or there is none), else kThresholdMissed with one line on stderr.
int applyGate(const Gate& gate, const Measured& d, const std::string& a, const std::string& b) {
  if (gate.metric.empty()) return 0;
  const auto metric = enumFromName<Metric>(gate.metric, kMetricNames);
  const double value = metricValue(*metric, d);
  if (std::isnan(value))
    throw Error(a + " vs " + b + ": no " + gate.metric + " for images under " +
                std::to_string(kSsimMinSize) + " pixels a side");
  const bool larger_is_better =
      *metric == Metric::Psnr || *metric == Metric::Within2 || *metric == Metric::Ssim;
  if (larger_is_better ? value >= gate.threshold : value <= gate.threshold) return 0;
  std::fprintf(stderr, "strata diff: %s vs %s: %s %.6g is %s the threshold %.6g\n", a.c_str(),
               b.c_str(), gate.metric.c_str(), value, larger_is_better ? "below" : "above",
               gate.threshold);
  return kThresholdMissed;
}

int runDiff(const std::string& a_path, const std::string& b_path, bool json, const std::string& out,
            const Gate& gate) {
  if (!gate.metric.empty() && !enumFromName<Metric>(gate.metric, kMetricNames))
    throw Error("--metric: unknown metric '" + gate.metric +
                "' (psnr, within2, ssim, rmse, max or mean)");
  checkWritable(out, "the difference image");
  const Image a = readImage(a_path), b = readImage(b_path);
  Measured measured;
  measured.diff = compareImages(a, b);
  const ImageDiff& d = measured.diff;
  if (a.width >= kSsimMinSize && a.height >= kSsimMinSize)
    measured.ssim = structuralSimilarity(a, b);
  if (!out.empty()) writeImage(differenceImage(a, b), out);
  if (json) {
    nlohmann::json j;
    j["a"] = a_path;
    j["b"] = b_path;
    j["pixels"] = d.pixels;
    j["psnr_db"] = std::isinf(d.psnr) ? nlohmann::json("inf") : nlohmann::json(d.psnr);
    j["rmse"] = d.rmse;
    j["ssim"] = std::isnan(measured.ssim) ? nlohmann::json(nullptr) : nlohmann::json(measured.ssim);
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
    std::printf("rmse            %.4f/255\n", d.rmse);
    if (std::isnan(measured.ssim))
      std::printf("ssim            n/a (under %d pixels a side)\n", kSsimMinSize);
    else
      std::printf("ssim            %.6f\n", measured.ssim);
    std::printf(
        "max abs error   %d/255\nmean abs error  %.4f/255\nwithin 1/255    %.4f%%\n"
        "within 2/255    %.4f%%\n",
        d.max_abs, d.mean_abs, 100.0 * d.within_1, 100.0 * d.within_2);
  }
  return applyGate(gate, measured, a_path, b_path);
}

}  // namespace

Command addDiffCommand(CLI::App& app) {
  struct DiffArgs {
    std::string a, b, out;
    bool json = false;
    Gate gate;
  };
  auto args = std::make_shared<DiffArgs>();
  std::string &diff_a = args->a, &diff_b = args->b, &diff_out = args->out;
  bool& diff_json = args->json;
  CLI::App* diff = app.add_subcommand(
      "diff", "compare two images: PSNR, RMSE, SSIM, max/mean error, pixels within 1 and 2 of 255");
  diff->add_option("a", diff_a, "first image")->required();
  diff->add_option("b", diff_b, "second image")->required();
  diff->add_flag("--json", diff_json, "print JSON");
  diff->add_option("--out", diff_out, "write a difference image (|a-b| x 8)");
  CLI::Option* metric =
      diff->add_option("--metric", args->gate.metric,
                       "gate on one metric: psnr (dB), within2 (share 0..1), ssim (structural "
                       "similarity, up to 1), rmse, max or mean (errors in 1/255); with "
                       "--threshold, exit 3 when the images miss it");
  CLI::Option* threshold = diff->add_option(
      "--threshold", args->gate.threshold,
      "the gate's bound: at least this for psnr, within2 and ssim, at most this for the errors");
  metric->needs(threshold);
  threshold->needs(metric);
  Command c;
  c.app = diff;
  c.run = [args] { return runDiff(args->a, args->b, args->json, args->out, args->gate); };
  c.subject = [args] { return args->a; };
  return c;
}

}  // namespace strata::cli
