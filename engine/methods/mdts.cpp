// `mdts` and `mdts32`: FreePipe's multi-depth test scheme (MDTS; Liu, Huang, Liu & Wu, I3D 2010).
// Every pixel has K = settings.k slots kept sorted by an atomic-min insertion chain; the K nearest
// fragments survive and the rest are lost (counted in stats.fragments_lost, with
// stats.bytes_needed the slot memory that would have kept them all). One geometry pass; the
// resolve composites the slots in order, with no sort (kernels/mdts.cl).
//   mdts:   64-bit words, full float depth above the triangle id: exact while K >= depth.
//   mdts32: the published 32-bit word, quantised depth above a colour index (24 + 8 bits for small
//           scenes; the depth gets fewer bits when the colour table needs more): not exact, its
//           error against the reference is its result.
// The slots live in local memory, one tile's at a time (K * 64 words per work-group), when the
// device's local memory holds them; otherwise (or when FrameSettings::mdts.global_slots asks,
// for comparison and testing) in a global array of K words per pixel, as published. Both
// placements give the same images and counts. stats.fragment_bytes is the method's footprint,
// K words per pixel, in either placement.
#include <cstdlib>
#include <cstring>
#include <string>

#include "engine/frontend/cl_pipeline.h"

namespace strata {

namespace {

// Bits needed to hold every value 0..n.
uint32_t bitsFor(uint64_t n) {
  uint32_t b = 1;
  while (b < 64 && (n >> b) != 0) ++b;
  return b;
}

class MdtsMethod final : public ClMethod {
 public:
  explicit MdtsMethod(bool packed_32bit) : packed_(packed_32bit) {}

  void init(ClPipeline& p) override {
    kernel_.create(p, packed_ ? "mdts32_raster_resolve" : "mdts_raster_resolve");
    device_ = p.runtime().queue().getInfo<CL_QUEUE_DEVICE>();
  }

  void prepare(ClPipeline& p, const FrameSettings& s) override {
    const char* name = packed_ ? "mdts32" : "mdts";
    if (s.k < 1 || s.k > ST_MAX_K)
      throw Error(std::string(name) + ": the per-pixel budget k = " + std::to_string(s.k) +
                  " must be between 1 and " + std::to_string(ST_MAX_K));
    k_ = uint32_t(s.k);
    if (packed_) {
      // The colour index needs bits for every triangle id plus one spare value, so that no word
      // equals the empty slot; the depth takes the rest, at most the published 24 bits.
      const uint32_t id_bits = std::max<uint32_t>(8, bitsFor(p.triangleCount()));
      if (id_bits > 24)
        throw Error("mdts32: " + std::to_string(p.triangleCount()) +
                    " triangles need more than 24 bits of colour index, leaving fewer than 8 "
                    "bits of depth in the 32-bit word; use mdts");
      depth_bits_ = 32 - id_bits;
    }
    cl::Kernel& kernel = kernel_.forFrame(p);
    // Local slots when the kernel fits the device's local memory with them.
    const size_t tile_slot_bytes = size_t(k_) * ST_TILE_PIXELS * wordBytes();
    kernel.setArg(slotArgIndex(), cl::Local(tile_slot_bytes));
    const cl_ulong available = device_.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
    const cl_ulong needed = kernel.getWorkGroupInfo<CL_KERNEL_LOCAL_MEM_SIZE>(device_);
    global_slots_ = s.mdts.global_slots || needed > available;
    if (global_slots_) {
      kernel.setArg(slotArgIndex(), cl::Local(wordBytes()));  // unused
      const size_t tile_pixels = size_t(p.tilesX()) * p.tilesY() * ST_TILE_PIXELS;
      p.ensure(slots_, tile_pixels * k_ * wordBytes(), "MDTS slots");
    } else {
      p.ensure(slots_, 16, "MDTS slots (unused: the slots are tile-local)");
    }
  }

  void enqueue(ClPipeline& p) override {
    cl::Kernel& kernel = kernel_.forFrame(p);
    cl_uint i = 0;
    kernel.setArg(i++, p.records().buffer);
    kernel.setArg(i++, p.bins().buffer);
    kernel.setArg(i++, p.tileOffsets().buffer);
    kernel.setArg(i++, cl_uint(p.tilesX()));
    kernel.setArg(i++, p.binCapacity());
    kernel.setArg(i++, cl_uint(k_));
    if (packed_) kernel.setArg(i++, cl_uint(depth_bits_));
    kernel.setArg(i++, cl_int(global_slots_ ? 1 : 0));
    ++i;  // the __local slots, set in prepare
    kernel.setArg(i++, slots_.buffer);
    kernel.setArg(i++, p.triangleColors().buffer);
    kernel.setArg(i++, p.texTriangles().buffer);
    kernel.setArg(i++, p.atlas().buffer);
    kernel.setArg(i++, p.view().buffer);
    kernel.setArg(i++, p.image().buffer);
    kernel.setArg(i++, p.counters().buffer);
    kernel.setArg(i++, p.depthComplexity().buffer);
    kernel.setArg(i++, cl_int(p.captureDepthComplexity() ? 1 : 0));
    // Insertion and resolve share one launch per tile (the slots never leave the tile).
    kernel_.launch(p, "raster+resolve");
  }

  void addStats(ClPipeline& p, const uint64_t* counters, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = uint64_t(k_) * p.pixels() * wordBytes();
    st.fragments_lost = counters[ST_COUNTER_FRAGMENTS_LOST];
    st.bytes_needed = counters[ST_COUNTER_MAX_DEPTH] * p.pixels() * wordBytes();
  }

  uint64_t deviceBytes() const override { return slots_.bytes; }

 private:
  size_t wordBytes() const { return packed_ ? 4 : 8; }
  cl_uint slotArgIndex() const { return packed_ ? 8 : 7; }

  bool packed_;
  TileKernel kernel_;
  cl::Device device_;
  DeviceBuffer slots_;
  uint32_t k_ = 16, depth_bits_ = 24;
  bool global_slots_ = false;
};

}  // namespace

std::unique_ptr<ClMethod> makeMdtsMethod(bool packed_32bit) {
  return std::make_unique<MdtsMethod>(packed_32bit);
}

}  // namespace strata
