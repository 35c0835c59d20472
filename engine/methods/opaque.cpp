// `opaque`: the nearest fragment per pixel in a 64-bit visibility buffer (depth above triangle
// id, atom_min), then a shading pass.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class OpaqueMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override {
    raster_.create(p, "raster_visibility");
    shade_ = p.kernel("shade_visibility");
  }

  void prepare(ClPipeline& p, const FrameSettings&) override {
    p.ensure(visibility_, p.pixels() * 8, "visibility buffer");
  }

  void enqueue(ClPipeline& p) override {
    p.timer().fill("clear", visibility_.buffer, 0xFFFFFFFFu, visibility_.bytes);
    setArgs(raster_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
            visibility_.buffer, p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0));
    raster_.launch(p, "raster");
    setArgs(shade_, visibility_.buffer, p.triangleColors().buffer, p.texTriangles().buffer,
            p.atlas().buffer, p.view().buffer, p.image().buffer);
    p.timer().launch("shade", shade_, p.tilesGlobal(), p.tileLocal());
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.fragment_bytes = visibility_.bytes;
  }

  uint64_t deviceBytes() const override { return visibility_.bytes; }

 private:
  TileKernel raster_;
  cl::Kernel shade_;
  DeviceBuffer visibility_;
};

}  // namespace

std::unique_ptr<ClMethod> makeOpaqueMethod() { return std::make_unique<OpaqueMethod>(); }

}  // namespace strata
