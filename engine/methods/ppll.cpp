// `ppll`: exact transparency with per-pixel linked lists (global node pool, atomic head
// exchange), per-pixel sort, front-to-back compositing. The pool starts at 2 nodes per pixel and
// grows to the count the kernels report whenever a frame needs more.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class PpllMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override {
    build_.create(p, "ppll_build");
    resolve_.create(p, "ppll_resolve");
  }

  void prepare(ClPipeline& p, const FrameSettings&) override {
    p.ensure(heads_, p.pixels() * 4, "linked-list heads");
    if (node_capacity_ == 0) node_capacity_ = 2 * p.pixels() + 1024;
    p.ensure(nodes_, node_capacity_ * sizeof(StPpllNode), "linked-list nodes");
  }

  void enqueue(ClPipeline& p) override {
    // No clear of the heads: each tile's owner stores all of its heads.
    setArgs(build_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
            heads_.buffer, nodes_.buffer, cl_ulong(node_capacity_), p.counters().buffer);
    build_.launch(p, "raster");
    setArgs(resolve_.forFrame(p), heads_.buffer, nodes_.buffer, p.triangleColors().buffer,
            p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0));
    resolve_.launch(p, "resolve");
  }

  bool growIfOverflowed(ClPipeline& p, const uint64_t* counters) override {
    if (!growCapacity(node_capacity_, counters[ST_COUNTER_NODES], 1)) return false;
    p.ensure(nodes_, node_capacity_ * sizeof(StPpllNode), "linked-list nodes");
    return true;
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.fragment_bytes = heads_.bytes + nodes_.bytes;
  }

  uint64_t deviceBytes() const override { return heads_.bytes + nodes_.bytes; }

 private:
  TileKernel build_, resolve_;
  DeviceBuffer heads_, nodes_;
  size_t node_capacity_ = 0;
};

}  // namespace

std::unique_ptr<ClMethod> makePpllMethod() { return std::make_unique<PpllMethod>(); }

}  // namespace strata
