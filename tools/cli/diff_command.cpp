// strata diff: two images compared (PSNR, largest and mean error, the share of pixels within 1
// and 2 of 255), and a difference image.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "preprocess/image_io.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace {

int runDiff(const std::string& a_path, const std::string& b_path, bool json,
            const std::string& out) {
  checkWritable(out, "the difference image");
  const Image a = readImage(a_path), b = readImage(b_path);
  const ImageDiff d = compareImages(a, b);
  if (!out.empty()) writeImage(differenceImage(a, b), out);
  if (json) {
    nlohmann::json j;
    j["a"] = a_path;
    j["b"] = b_path;
    j["pixels"] = d.pixels;
    j["psnr_db"] = std::isinf(d.psnr) ? nlohmann::json("inf") : nlohmann::json(d.psnr);
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
    std::printf(
        "max abs error   %d/255\nmean abs error  %.4f/255\nwithin 1/255    %.4f%%\n"
        "within 2/255    %.4f%%\n",
        d.max_abs, d.mean_abs, 100.0 * d.within_1, 100.0 * d.within_2);
  }
  return 0;
}

}  // namespace

Command addDiffCommand(CLI::App& app) {
  struct DiffArgs {
    std::string a, b, out;
    bool json = false;
  };
  auto args = std::make_shared<DiffArgs>();
  std::string &diff_a = args->a, &diff_b = args->b, &diff_out = args->out;
  bool& diff_json = args->json;
  CLI::App* diff = app.add_subcommand(
      "diff", "compare two images: PSNR, max/mean error, pixels within 1 and 2 of 255");
  diff->add_option("a", diff_a, "first image")->required();
  diff->add_option("b", diff_b, "second image")->required();
  diff->add_flag("--json", diff_json, "print JSON");
  diff->add_option("--out", diff_out, "write a difference image (|a-b| x 8)");
  Command c;
  c.app = diff;
  c.run = [args] { return runDiff(args->a, args->b, args->json, args->out); };
  c.subject = [args] { return args->a; };
  return c;
}

}  // namespace strata::cli
