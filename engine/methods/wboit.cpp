// `wboit`: weighted blended order-independent transparency (McGuire and Bavoil, JCGT 2013), an
// approximate method: one geometry pass that sums each pixel's weighted colours, weighted
// coverage and revealage in the tile's local memory, and a resolve in the same launch
// (kernels/wboit.cl gives the weights and the blend; WboitOptions::weight picks the paper's
// weight function). No per-pixel fragment storage: the only
// memory beyond the front end's is the tile's sums, so it loses no fragment at any depth.
#include "engine/frontend/cl_pipeline.h"
#include "preprocess/core/enum_table.h"

namespace strata {

namespace {

constexpr const char* kWeightNames[] = {"eq7", "eq8", "eq9", "eq10"};
static_assert(int(WboitWeight::Eq7) == ST_WBOIT_EQ7 && int(WboitWeight::Eq8) == ST_WBOIT_EQ8 &&
              int(WboitWeight::Eq9) == ST_WBOIT_EQ9 && int(WboitWeight::Eq10) == ST_WBOIT_EQ10);

class WboitMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override { kernel_.create(p, "wboit_accumulate_resolve"); }

  void prepare(ClPipeline&, const FrameSettings& s) override { weight_ = int(s.wboit.weight); }

  void enqueue(ClPipeline& p) override {
    setArgs(kernel_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), p.triangleColors().buffer,
            p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0), cl_int(weight_));
    kernel_.launch(p, "accumulate+resolve");
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = 0;  // the sums live in the tile's local memory
  }

  uint64_t deviceBytes() const override { return 0; }

 private:
  TileKernel kernel_;
  int weight_ = ST_WBOIT_EQ10;
};

}  // namespace

const char* optionName(WboitWeight value) { return enumLookup(value, kWeightNames, "eq10"); }

WboitWeight parseWboitWeight(const std::string& name) {
  if (auto weight = enumFromName<WboitWeight>(name, kWeightNames)) return *weight;
  throw Error("unknown wboit weight '" + name + "' (eq7, eq8, eq9 or eq10)");
}

std::unique_ptr<ClMethod> makeWboitMethod() { return std::make_unique<WboitMethod>(); }

}  // namespace strata
