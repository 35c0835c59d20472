// `dp`: depth peeling (Everitt 2001) and `ddp`: dual depth peeling (Bavoil & Myers 2008).
//
// Exact multi-pass transparency with memory that does not grow with depth complexity: every
// geometry pass rasterizes all binned triangles again and peels, per pixel, the nearest fragment
// strictly behind the last one peeled (dp), or the nearest and the farthest fragment strictly
// inside the range the earlier passes left (ddp). Fragments are 64-bit (depth, triangle id)
// words, so equal depths peel in id order and the result is exact. The peeled layers are blended
// in the same launch into per-pixel accumulators ("under" from the front, "over" from the back).
//
// Termination is the occlusion-query loop of the papers: each pass adds the fragments it peeled
// to ST_COUNTER_PASS_FRAGMENTS, the host reads that counter back after every pass (a blocking
// read, the method's nature) and stops after a pass that peeled nothing. The counter is not reset
// between passes: it accumulates, and an unchanged value is a pass that peeled nothing (so after
// the frame it holds every fragment peeled, which equals the fragment count).
//
// The first pass also lists the tiles that have triangles (read back with the counter); later
// passes launch one work-group per listed tile, since a tile no triangle touches has nothing to
// peel and a work-group's fixed cost is a large part of a pass on a CPU. Every pass still
// rasterizes every binned triangle.
//
// Passes: dp runs max_depth_complexity + 1 (the last one finds nothing); ddp peels two layers per
// pixel and pass, so it runs ceil(max_depth_complexity / 2) + 1.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

class DepthPeelingMethod final : public ClMethod {
 public:
  explicit DepthPeelingMethod(bool dual) : dual_(dual) {}

  void init(ClPipeline& p) override {
    peel_.create(p, dual_ ? "peeling_ddp_peel" : "peeling_dp_peel");
    resolve_ = p.kernel(dual_ ? "peeling_ddp_resolve" : "peeling_dp_resolve");
  }

  void prepare(ClPipeline& p, const FrameSettings&) override {
    // No clears: the first pass starts every pixel from the full range and fresh accumulators.
    if (dual_) {
      p.ensure(bounds_, p.pixels() * 16, "dual depth peeling ranges");
      p.ensure(front_, p.pixels() * 16, "dual depth peeling front accumulator");
      p.ensure(back_, p.pixels() * 16, "dual depth peeling back accumulator");
    } else {
      p.ensure(bounds_, p.pixels() * 8, "depth peeling last-peeled words");
      p.ensure(front_, p.pixels() * 16, "depth peeling accumulator");
      back_ = DeviceBuffer();
    }
    p.ensure(tile_list_, size_t(p.tilesX()) * p.tilesY() * 4, "depth peeling tile list");
  }

  void enqueue(ClPipeline& p) override {
    cl::CommandQueue& queue = p.runtime().queue();
    const cl_int capture = p.captureDepthComplexity() ? 1 : 0;
    uint64_t peeled_before = 0, listed_tiles = 0;
    passes_ = 0;
    const bool serial = p.serialTiles();
    cl::Kernel& peel = peel_.forFrame(p);
    for (;;) {
      const cl_int first = passes_ == 0 ? 1 : 0;
      if (dual_) {
        setArgs(peel, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
                cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
                bounds_.buffer, front_.buffer, back_.buffer, p.triangleColors().buffer,
                p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.counters().buffer,
                tile_list_.buffer, p.depthComplexity().buffer, capture, first);
      } else {
        setArgs(peel, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
                cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
                bounds_.buffer, front_.buffer, p.triangleColors().buffer, p.texTriangles().buffer,
                p.atlas().buffer, p.view().buffer, p.counters().buffer, tile_list_.buffer,
                p.depthComplexity().buffer, capture, first);
      }
      // The first pass covers every tile (it initializes every pixel) and lists the tiles with
      // triangles; later passes cover the listed tiles only (a work-group, or with the serial
      // form a work-item, each).
      if (first) {
        p.launchTiles("peel", peel, serial);
      } else {
        const size_t side = serial ? 1 : ST_TILE_SIZE;
        p.timer().launch("peel", peel, cl::NDRange(size_t(listed_tiles) * side, side),
                         cl::NDRange(side, side));
      }
      ++passes_;

      // The occlusion query: counters MAX_DEPTH .. METHOD_0 in one blocking read.
      static_assert(ST_COUNTER_PASS_FRAGMENTS > ST_COUNTER_MAX_DEPTH &&
                        ST_COUNTER_METHOD_0 > ST_COUNTER_PASS_FRAGMENTS,
                    "counter layout");
      uint64_t c[ST_COUNTER_METHOD_0 - ST_COUNTER_MAX_DEPTH + 1] = {};
      queue.enqueueReadBuffer(p.counters().buffer, CL_TRUE, ST_COUNTER_MAX_DEPTH * sizeof(uint64_t),
                              sizeof(c), c);
      const uint64_t peeled = c[ST_COUNTER_PASS_FRAGMENTS - ST_COUNTER_MAX_DEPTH];
      listed_tiles = c[ST_COUNTER_METHOD_0 - ST_COUNTER_MAX_DEPTH];
      if (peeled == peeled_before) break;
      peeled_before = peeled;
      // Every pass peels at least one layer from every unfinished pixel, so the pass count is
      // bounded by the depth complexity the first pass measured; more means a kernel bug.
      const uint64_t max_depth = c[0];
      if (passes_ > expectedPasses(max_depth))
        throw Error("depth peeling did not converge: " + std::to_string(passes_) +
                    " passes for depth complexity " + std::to_string(max_depth));
    }

    if (dual_)
      setArgs(resolve_, front_.buffer, back_.buffer, p.view().buffer, p.image().buffer);
    else
      setArgs(resolve_, front_.buffer, p.view().buffer, p.image().buffer);
    p.timer().launch("resolve", resolve_, p.tilesGlobal(), p.tileLocal());
  }

  void addStats(ClPipeline& p, const uint64_t*, FrameStats& st) override {
    st.fragment_bytes = bounds_.bytes + front_.bytes + back_.bytes;
    st.geometry_passes = passes_;
    st.triangles_read = passes_ * uint64_t(p.triangleCount());
  }

  uint64_t deviceBytes() const override {
    return bounds_.bytes + front_.bytes + back_.bytes + tile_list_.bytes;
  }

 private:
  // Passes the method needs for a frame whose deepest pixel has `max_depth` fragments.
  uint64_t expectedPasses(uint64_t max_depth) const {
    return (dual_ ? (max_depth + 1) / 2 : max_depth) + 1;
  }

  bool dual_;
  TileKernel peel_;
  cl::Kernel resolve_;
  DeviceBuffer bounds_;     // dp: last peeled word + 1 per pixel; ddp: (lo, hi) inclusive range
  DeviceBuffer front_;      // front-to-back accumulator (colour, transmittance)
  DeviceBuffer back_;       // ddp: back-to-front accumulator
  DeviceBuffer tile_list_;  // tiles with triangles, listed by the first pass
  uint64_t passes_ = 0;
};

}  // namespace

std::unique_ptr<ClMethod> makeDepthPeelingMethod(bool dual) {
  return std::make_unique<DepthPeelingMethod>(dual);
}

}  // namespace strata
