// `wboit`: weighted blended order-independent transparency (McGuire and Bavoil, JCGT 2013), an
// approximate method: one geometry pass that sums each pixel's weighted colours, weighted
// coverage and revealage in the tile's local memory, and a resolve in the same launch
// (kernels/wboit.cl gives the weight and the blend). No per-pixel fragment storage: the only
// memory beyond the front end's is the tile's sums, so it loses no fragment at any depth.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class WboitMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override {
    kernel_ = p.kernel("wboit_accumulate_resolve");
    kernel_serial_ = p.kernel("wboit_accumulate_resolve_serial");
  }

  void prepare(ClPipeline&, const FrameSettings&) override {}

  void enqueue(ClPipeline& p) override {
    // The kernel's two forms take the same arguments.
    cl::Kernel& kernel = p.serialTiles() ? kernel_serial_ : kernel_;
    setArgs(kernel, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), p.triangleColors().buffer,
            p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0));
    p.launchTiles("accumulate+resolve", kernel, p.serialTiles());
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = 0;  // the sums live in the tile's local memory
  }

  uint64_t deviceBytes() const override { return 0; }

 private:
  cl::Kernel kernel_, kernel_serial_;
};

}  // namespace

std::unique_ptr<ClMethod> makeWboitMethod() { return std::make_unique<WboitMethod>(); }

}  // namespace strata
