// `mboit`: moment-based order-independent transparency (Münstermann, Krumpen, Klein and Peters,
// I3D 2018) with four power moments, an approximate method: one launch per frame that walks
// each tile three times in drawing order (each pixel's depth range, its optical depth and
// moments, then every fragment through the transmittance the moments bound in front of it) and
// resolves (kernels/mboit.cl). Its tables are the tile's local memory: nothing in global memory
// beyond the front end's, nothing lost at any depth.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class MboitMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override { kernel_.create(p, "mboit_moments_resolve"); }

  void prepare(ClPipeline&, const FrameSettings&) override {}

  void enqueue(ClPipeline& p) override {
    setArgs(kernel_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), p.triangleColors().buffer,
            p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0));
    kernel_.launch(p, "moments+resolve");
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = 0;  // the moments live in the tile's local memory
  }

  uint64_t deviceBytes() const override { return 0; }

  // The sums' float order: drawing order in both kernel forms, so the forms give one image.
  bool needsDrawingOrder() const override { return true; }

 private:
  TileKernel kernel_;
};

}  // namespace

std::unique_ptr<ClMethod> makeMboitMethod() { return std::make_unique<MboitMethod>(); }

}  // namespace strata
