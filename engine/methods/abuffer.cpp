// `abuffer`: FreePipe's A-buffer scheme (ABS; Liu, Huang, Liu & Wu, I3D 2010). Every pixel has a
// fixed budget of K = settings.k records (float depth and triangle id, 8 bytes) in global memory;
// fragments are appended in arrival order through a per-pixel counter, then each pixel's records
// are sorted in a private array and composited front to back (kernels/abuffer.cl, which also says
// how the tile-owned design differs from the published one). Fragments past the K-th of a pixel
// are lost: counted in stats.fragments_lost, with stats.bytes_needed the record memory that would
// have kept them all; or, with AbufferOptions::tail Blend, blended into a tail behind the K
// sorted ones (order-independently) instead. Exact while K is at least the scene's depth
// complexity. One geometry pass.
#include <string>

#include "engine/frontend/cl_pipeline.h"
#include "preprocess/core/enum_table.h"

namespace strata {

namespace {

constexpr const char* kTailNames[] = {"drop", "blend"};

constexpr size_t kRecordBytes = 8;  // one 64-bit visibility word: depth bits above triangle id

class AbufferMethod final : public ClMethod {
 public:
  void init(ClPipeline& p) override { kernel_.create(p, "abuffer_raster_resolve"); }

  void prepare(ClPipeline& p, const FrameSettings& s) override {
    if (s.k < 1 || s.k > ST_MAX_K)
      throw Error("abuffer: the per-pixel budget k = " + std::to_string(s.k) +
                  " must be between 1 and " + std::to_string(ST_MAX_K));
    k_ = uint32_t(s.k);
    tail_blend_ = s.abuffer.tail == AbufferTail::Blend;
    // Tile-major blocks of K records per pixel, whole tiles (border tiles padded).
    const size_t tile_pixels = size_t(p.tilesX()) * p.tilesY() * ST_TILE_PIXELS;
    p.ensure(records_, tile_pixels * k_ * kRecordBytes, "A-buffer records");
  }

  void enqueue(ClPipeline& p) override {
    // No clear: a pixel's records are read only up to its count, which the kernel starts at 0.
    setArgs(kernel_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_uint(k_), records_.buffer,
            p.triangleColors().buffer, p.texTriangles().buffer, p.atlas().buffer, p.view().buffer,
            p.image().buffer, p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0), cl_int(tail_blend_ ? 1 : 0));
    // Append and resolve share one launch per tile (the records are read back while cached).
    kernel_.launch(p, "raster+resolve");
  }

  void addStats(ClPipeline& p, const uint64_t* counters, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = records_.bytes;  // K records per pixel (the counters are tile-local)
    st.fragments_lost = counters[ST_COUNTER_FRAGMENTS_LOST];  // 0 with a blended tail
    st.bytes_needed = counters[ST_COUNTER_MAX_DEPTH] * p.pixels() * kRecordBytes;
  }

  uint64_t deviceBytes() const override { return records_.bytes; }

 private:
  TileKernel kernel_;
  DeviceBuffer records_;
  uint32_t k_ = 16;
  bool tail_blend_ = false;
};

}  // namespace

const char* optionName(AbufferTail value) { return enumLookup(value, kTailNames, "drop"); }

AbufferTail parseAbufferTail(const std::string& name) {
  if (auto tail = enumFromName<AbufferTail>(name, kTailNames)) return *tail;
  throw Error("unknown abuffer tail '" + name + "' (drop or blend)");
}

std::unique_ptr<ClMethod> makeAbufferMethod() { return std::make_unique<AbufferMethod>(); }

}  // namespace strata
