// `stochastic`: stochastic transparency (Enderton, Sintorn, Shirley and Luebke, I3D 2010), an
// approximate method: one launch per frame that walks each tile twice in drawing order, first
// covering StochasticOptions::samples samples per pixel with each fragment's random subset (a
// depth per sample in the tile's local memory) and taking the exact total transmittance, then
// compositing every fragment through the share of samples that nothing nearer covers, with the
// paper's alpha correction (kernels/stochastic.cl). Unbiased: the error falls as 1 / sqrt(S).
// The subsets come from a table of random sample orders made here per seed and sample count.
#include <algorithm>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class StochasticMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override { kernel_.create(p, "stochastic_cover_resolve"); }

  void prepare(ClPipeline& p, const FrameSettings& s) override {
    options_ = s.stochastic;
    if (options_.samples < 1 || options_.samples > ST_STOCHASTIC_MAX_SAMPLES)
      throw Error("stochastic: samples = " + std::to_string(options_.samples) +
                  " must be between 1 and " + std::to_string(ST_STOCHASTIC_MAX_SAMPLES));
    requireLocalMemory(p, kFixedLocal + sampleBytes(),
                       "stochastic: " + std::to_string(options_.samples) + " samples");
    if (masks_.bytes == 0 || options_.samples != table_samples_ || options_.seed != table_seed_) {
      // Row r: the prefix masks of a random order of the S samples (entry n covers its first n).
      const uint32_t n = options_.samples;
      std::vector<cl_ulong> table(size_t(ST_STOCHASTIC_MASK_ROWS) * (n + 1));
      std::mt19937 random(options_.seed);
      std::vector<uint32_t> order(n);
      for (size_t r = 0; r < ST_STOCHASTIC_MASK_ROWS; ++r) {
        std::iota(order.begin(), order.end(), 0u);
        std::shuffle(order.begin(), order.end(), random);
        for (uint32_t i = 0; i < n; ++i)
          table[r * (n + 1) + i + 1] = table[r * (n + 1) + i] | (cl_ulong(1) << order[i]);
      }
      p.upload(masks_, table.data(), table.size() * sizeof(cl_ulong), "stochastic masks");
      table_samples_ = options_.samples;
      table_seed_ = options_.seed;
    }
  }

  void enqueue(ClPipeline& p) override {
    setArgs(kernel_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_uint(options_.samples), cl_uint(options_.seed),
            cl_int(options_.alpha_correction ? 1 : 0), masks_.buffer, p.triangleColors().buffer,
            p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0), cl::Local(sampleBytes()));
    kernel_.launch(p, "cover+resolve");
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = 0;  // the samples live in the tile's local memory
  }

  uint64_t deviceBytes() const override { return masks_.bytes; }

  // The sums' float order: drawing order in both kernel forms, so a seed gives one image.
  bool needsDrawingOrder() const override { return true; }

 private:
  size_t sampleBytes() const { return size_t(options_.samples) * ST_TILE_PIXELS * sizeof(float); }

  // Its own local tables: fragment counts, report scratch, the ordered walk's round, the colour
  // and opacity sums and the total transmittance.
  static constexpr size_t kFixedLocal = ST_TILE_PIXELS * (4 + 4 + 4 + 8 + 20);

  TileKernel kernel_;
  StochasticOptions options_;
  DeviceBuffer masks_;  // ST_STOCHASTIC_MASK_ROWS x (samples + 1) prefix masks
  uint32_t table_samples_ = 0, table_seed_ = 0;
};

}  // namespace

std::unique_ptr<ClMethod> makeStochasticMethod() { return std::make_unique<StochasticMethod>(); }

}  // namespace strata
