// `bdp`: bucket depth peeling and `bdp2`: adaptive bucket depth peeling (Liu, Huang, Liu & Wu,
// "Efficient depth peeling via bucket sort", HPG 2009). Approximate: every pixel has
// ST_BDP_BUCKETS (32) buckets of one fragment each; fragments landing in an occupied bucket are
// lost and counted (stats.fragments_lost). The kernels (kernels/bucket.cl) describe the passes:
//   bdp:  bounds pass (min/max depth per pixel), bucket pass (uniform buckets + composite);
//   bdp2: bounds pass, histogram pass (1024-bin occupancy bits per pixel), bucket pass whose bucket
//         is the rank of the fragment's occupied fine bin.
// Every pass is one launch over all tiles that re-reads all binned triangles, so
// geometry_passes = 2 (bdp) or 3 (bdp2) and triangles_read = passes x triangles.
//
// The buckets of the last pass live in local memory, one tile's at a time (16 KB per work-group),
// when the device's local memory holds the kernel's needs; otherwise (or when
// FrameSettings::bucket.global_buckets asks, for comparison and testing) in a global buffer of 32
// words per pixel, the published method's footprint. Both give the same images and counts.
#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

constexpr size_t kFineWords = ST_BUCKET_FINE_WORDS;
constexpr size_t kTileBucketWords = size_t(ST_BDP_BUCKETS) * ST_TILE_PIXELS;

class BucketPeelingMethod final : public ClMethod {
 public:
  explicit BucketPeelingMethod(bool adaptive) : adaptive_(adaptive) {}

  void init(ClPipeline& p) override {
    // Each kernel in its two forms (FrameSettings::tile_kernels), which take the same arguments.
    bounds_kernel_ = p.kernel("bucket_bounds");
    bounds_serial_ = p.kernel("bucket_bounds_serial");
    if (adaptive_) {
      histogram_kernel_ = p.kernel("bucket_histogram");
      histogram_serial_ = p.kernel("bucket_histogram_serial");
    }
    // Local-memory buckets when the kernel fits the device's local memory with all of its
    // __local arguments set.
    local_sort_kernel_ = p.kernel("bucket_sort_local");
    setLocalArgs(local_sort_kernel_, true);
    const cl::Device device = p.runtime().queue().getInfo<CL_QUEUE_DEVICE>();
    const cl_ulong available = device.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
    const cl_ulong needed = local_sort_kernel_.getWorkGroupInfo<CL_KERNEL_LOCAL_MEM_SIZE>(device);
    local_fits_ = needed <= available;
    global_sort_kernel_ = p.kernel("bucket_sort_global");
    setLocalArgs(global_sort_kernel_, false);
    local_sort_serial_ = p.kernel("bucket_sort_local_serial");
    setLocalArgs(local_sort_serial_, true);
    global_sort_serial_ = p.kernel("bucket_sort_global_serial");
    setLocalArgs(global_sort_serial_, false);
  }

  void prepare(ClPipeline& p, const FrameSettings& s) override {
    global_buckets_ = s.bucket.global_buckets || !local_fits_;
    serial_ = p.serialTiles();
    if (serial_)
      sort_kernel_ = global_buckets_ ? global_sort_serial_ : local_sort_serial_;
    else
      sort_kernel_ = global_buckets_ ? global_sort_kernel_ : local_sort_kernel_;
    // Tile-major per-pixel tables cover whole tiles (partial tiles at the border included).
    const size_t tile_pixels = size_t(p.tilesX()) * p.tilesY() * ST_TILE_PIXELS;
    p.ensure(bounds_, tile_pixels * 8, "bucket peeling depth bounds");
    if (adaptive_)
      p.ensure(bitmaps_, tile_pixels * kFineWords * 4, "bucket peeling depth histograms");
    if (global_buckets_)
      p.ensure(buckets_, tile_pixels * ST_BDP_BUCKETS * 8, "bucket peeling buckets");
  }

  void enqueue(ClPipeline& p) override {
    const cl_uint tiles_x = p.tilesX();
    cl::Kernel& bounds = serial_ ? bounds_serial_ : bounds_kernel_;
    cl::Kernel& histogram = serial_ ? histogram_serial_ : histogram_kernel_;
    setArgs(bounds, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer, tiles_x,
            p.binCapacity(), cl_int(p.width()), cl_int(p.height()), bounds_.buffer,
            p.counters().buffer, p.depthComplexity().buffer,
            cl_int(p.captureDepthComplexity() ? 1 : 0));
    p.launchTiles("bounds", bounds, serial_);
    if (adaptive_) {
      setArgs(histogram, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer, tiles_x,
              p.binCapacity(), bounds_.buffer, bitmaps_.buffer);
      p.launchTiles("histogram", histogram, serial_);
    }
    // bdp reads no histogram: any buffer will do for the unused argument.
    const cl::Buffer& bitmaps = adaptive_ ? bitmaps_.buffer : bounds_.buffer;
    setArgs(sort_kernel_, p.records().buffer, p.bins().buffer, p.tileOffsets().buffer, tiles_x,
            p.binCapacity(), bounds_.buffer, bitmaps, cl_int(adaptive_ ? 1 : 0),
            p.triangleColors().buffer, p.texTriangles().buffer, p.atlas().buffer, p.view().buffer,
            p.image().buffer, p.counters().buffer);
    if (global_buckets_) sort_kernel_.setArg(14, buckets_.buffer);
    p.launchTiles("buckets", sort_kernel_, serial_);
  }

  void addStats(ClPipeline& p, const uint64_t* counters, FrameStats& st) override {
    st.geometry_passes = adaptive_ ? 3 : 2;
    st.triangles_read = st.geometry_passes * uint64_t(p.triangleCount());
    st.fragment_bytes = deviceBytes();
    st.fragments_lost = counters[ST_COUNTER_FRAGMENTS_LOST];
    // What an exact fixed-budget method would have needed: the deepest pixel's count at every
    // pixel.
    st.bytes_needed = st.fragments_lost ? st.max_depth_complexity * uint64_t(p.pixels()) * 8 : 0;
  }

  uint64_t deviceBytes() const override {
    return bounds_.bytes + (adaptive_ ? bitmaps_.bytes : 0) +
           (global_buckets_ ? buckets_.bytes : 0);
  }

 private:
  // Sets the __local arguments of a bucket_sort_* kernel (from argument 14 on): the buckets (local
  // variant only), lo, scale, and for bdp2 the occupancy words and their prefix counts.
  void setLocalArgs(cl::Kernel& k, bool local_buckets) {
    const size_t pixels = ST_TILE_PIXELS;
    const size_t fine = adaptive_ ? kFineWords * pixels : 1;
    if (local_buckets) k.setArg(14, cl::Local(kTileBucketWords * 8));
    k.setArg(15, cl::Local(pixels * 4));
    k.setArg(16, cl::Local(pixels * 4));
    k.setArg(17, cl::Local(fine * 4));
    k.setArg(18, cl::Local(fine));
  }

  bool adaptive_;
  bool global_buckets_ = false, local_fits_ = true;
  bool serial_ = false;  // the form of the current render() call
  cl::Kernel bounds_kernel_, histogram_kernel_, sort_kernel_, local_sort_kernel_,
      global_sort_kernel_;
  cl::Kernel bounds_serial_, histogram_serial_, local_sort_serial_, global_sort_serial_;
  DeviceBuffer bounds_, bitmaps_, buckets_;
};

}  // namespace

std::unique_ptr<ClMethod> makeBucketPeelingMethod(bool adaptive) {
  return std::make_unique<BucketPeelingMethod>(adaptive);
}

}  // namespace strata
