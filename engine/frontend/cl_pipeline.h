// The shared OpenCL front end (transform, setup, binning) and the interface every method on it
// implements (raster passes and resolve). Private to the library: includes OpenCL.
//
// A frame (run by engine/frontend/frame_runner.h): the front end runs once, then the method
// rasterizes the binned triangles (once, or once per geometry pass) and resolves into the image.
// The front end grows its record and bin buffers, the method its own, when the counters say they
// overflowed.
#pragma once

#include <memory>
#include <string>

#include "engine/features/batching.h"
#include "engine/features/device_atlas.h"
#include "engine/features/draw_sort.h"
#include "engine/frontend/frame_runner.h"
#include "engine/renderer.h"

namespace strata {

class ClPipeline;

// One OpenCL method (opaque, ppll, abuffer, ...). Methods own their per-pixel and fragment
// buffers; everything else comes from the pipeline.
class ClMethod {
 public:
  virtual ~ClMethod() = default;
  // Creates kernels; called once.
  virtual void init(ClPipeline& pipeline) = 0;
  // Sizes the method's buffers for a render() call (frame size, settings).
  virtual void prepare(ClPipeline& pipeline, const FrameSettings& settings) = 0;
  // Enqueues everything after binning: raster pass(es) and the resolve into pipeline.image().
  // Multi-pass methods may read counters back between passes.
  virtual void enqueue(ClPipeline& pipeline) = 0;
  // After a frame: grows what overflowed (from the counters) and returns true to re-run it.
  virtual bool growIfOverflowed(ClPipeline& pipeline, const uint64_t* counters) { return false; }
  // Fills method-specific statistics (fragment_bytes, lost fragments, passes, ...).
  virtual void addStats(ClPipeline& pipeline, const uint64_t* counters, FrameStats& stats) = 0;
  // Bytes of all buffers the method owns.
  virtual uint64_t deviceBytes() const = 0;
  // True for a method whose image depends on the order of a pixel's fragments (mlab): every
  // tile's list then keeps the drawing order in either form of the tile kernels (the serial
  // binner), as a GPU's raster order does.
  virtual bool needsDrawingOrder() const { return false; }
};

class ClPipeline final : private FrameStages {
 public:
  ClPipeline(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device);

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) {
    return runner_.render(geometry, settings, *this);
  }

  // --- for methods ---
  ClRuntime& runtime() { return runner_.runtime(); }
  LaunchTimer& timer() { return runner_.timer(); }
  cl::Kernel kernel(const std::string& name) { return runner_.kernel(name); }
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
    runner_.ensure(b, bytes, purpose);
  }
  // ensure(), then a blocking write.
  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
    runner_.upload(b, data, bytes, purpose);
  }

  int width() const { return runner_.width(); }
  int height() const { return runner_.height(); }
  size_t pixels() const { return runner_.pixels(); }
  uint32_t tilesX() const { return runner_.tilesX(); }
  uint32_t tilesY() const { return runner_.tilesY(); }
  uint32_t triangleCount() const { return triangle_count_; }  // = record slots of the front end
  cl_uint binCapacity() const { return cl_uint(bin_capacity_); }
  bool captureDepthComplexity() const { return capture_depth_; }
  cl::NDRange tilesGlobal() const { return runner_.tilesGlobal(); }
  cl::NDRange tileLocal() const { return runner_.tileLocal(); }
  bool serialTiles() const { return runner_.serialTiles(); }
  // Whether the frame bins with the serial binner, whose tile lists keep the drawing order.
  bool serialBins() const { return serialTiles() || impl_->needsDrawingOrder(); }
  void launchTiles(const std::string& stage, cl::Kernel& kernel, bool serial) {
    runner_.launchTiles(stage, kernel, serial);
  }

  DeviceBuffer& view() { return view_; }
  DeviceBuffer& triangleColors() { return triangle_colors_; }
  // Texturing (kernels/texture.cl): a record per world triangle and the atlas words; 16-byte
  // placeholders when the scene is not textured (view constants say so).
  DeviceBuffer& texTriangles() { return tex_tris_; }
  DeviceBuffer& atlas() { return atlas_; }
  DeviceBuffer& records() { return records_; }
  DeviceBuffer& bins() { return bins_; }
  DeviceBuffer& tileOffsets() { return tile_offsets_; }
  DeviceBuffer& counters() { return runner_.counters(); }
  DeviceBuffer& image() { return runner_.image(); }
  DeviceBuffer& depthComplexity() override { return depth_map_; }  // per-pixel counts, if captured

 private:
  // FrameStages
  void prepare(const WorldGeometry& geometry, const FrameSettings& settings) override;
  void beforeFrame() override;
  void enqueueFrame(const FrameSettings& settings) override;
  bool growIfOverflowed(const uint64_t* counters) override;
  void frameTimed() override { sort_runs_.push_back(sort_stats_.sort_ms); }
  void addStats(const uint64_t* counters, FrameStats& stats) override;

  // The scene's own data, once per geometry (not counted in device_bytes).
  void uploadScene(const WorldGeometry& geometry, const DeviceAtlas& atlas, bool atlas_changed);
  // Per view: the texture-coordinate planes of every triangle.
  void uploadTexturing(const WorldGeometry& geometry, const DeviceAtlas& atlas);
  // Per frame: the view constants (and texturing records) of the frame's camera when it moved.
  void updateView(const FrameSettings& settings);
  // Per frame: sorts the draw units, uploads the frame's constants, draw table and instances
  // (non-blocking, from members that outlive the frame) and enqueues the front end.
  void enqueueFrontEnd(const FrameSettings& settings);

  FrameRunner runner_;  // first member: released last
  Method method_;
  std::unique_ptr<ClMethod> impl_;
  cl::Kernel transform_, setup_, bin_scan_, bin_fill_;
  // The serial binner (tile_kernels serial): records cut into bin_chunks_ runs
  // (FrameRunner::binRuns), counted in a tile x run table.
  cl::Kernel bin_count_serial_, bin_fill_serial_, bin_tile_offsets_;
  uint32_t bin_chunks_ = 16;
  size_t binTableSize() const {
    return size_t(runner_.tileCount()) * (serialBins() ? bin_chunks_ : 1);
  }
  // The words of the counts and cursors: the serial binner's table is padded per run.
  size_t countTableWords() const {
    return size_t(runner_.binRunTableWords(serialBins() ? bin_chunks_ : 1));
  }
  DeviceBuffer positions_, indices_, materials_, material_colors_, view_;
  // Draw units (engine/features/batching.h): the plan of the current render() call, the source
  // triangle ids (static), instances, the frame's draw table, world positions written by the
  // transform.
  BatchPlan plan_;
  DrawSorter sorter_;
  DrawSort sort_ = DrawSort::None;
  std::vector<uint32_t> order_;
  std::vector<StDraw> table_;
  std::vector<DrawLaunch> launches_;
  StViewConstants view_host_{};
  std::vector<StTexTriangle> tex_host_;      // the current view's texturing records
  const WorldGeometry* geometry_ = nullptr;  // of the current render() call
  DrawSortStats sort_stats_;
  std::vector<double> sort_runs_;
  uint64_t frame_upload_bytes_ = 0, scene_upload_bytes_ = 0;
  DeviceBuffer triangle_ids_, instances_, draws_, world_, tex_tris_, atlas_;
  DeviceAtlasCache atlas_cache_;
  const DeviceAtlas* atlas_now_ = nullptr;  // the atlas of the current render() call
  AtlasChoice atlas_choice_ = AtlasChoice::Packed;
  DeviceBuffer clip_, screen_, record_bounds_, triangle_colors_, tile_counts_, tile_offsets_,
      tile_cursors_, chunk_offsets_, records_, bins_, depth_map_;
  uint32_t triangle_count_ = 0;
  // What the uploaded scene was made from (FrameSettings::geometry_generation and the settings
  // the plan depends on); generation 0: nothing reusable.
  struct SceneKey {
    uint64_t generation = 0;
    Batch batch = Batch::Static;
    Effect effect = Effect::Transparency;
    AtlasChoice atlas = AtlasChoice::Packed;
    bool operator==(const SceneKey& o) const {
      return generation == o.generation && batch == o.batch && effect == o.effect &&
             atlas == o.atlas;
    }
  } scene_key_;
  size_t overflow_capacity_ = 0, bin_capacity_ = 0;
  bool capture_depth_ = false;
};

// A per-tile kernel in its two forms (docs/raster.md): NAME, a work-group per tile, and
// NAME_serial, one work-item alone per tile, taking the same arguments.
class TileKernel {
 public:
  void create(ClPipeline& p, const std::string& name) {
    group_ = p.kernel(name);
    serial_ = p.kernel(name + "_serial");
  }
  // The form the current frame runs (ClPipeline::serialTiles), to set its arguments on.
  cl::Kernel& forFrame(const ClPipeline& p) { return p.serialTiles() ? serial_ : group_; }
  // That form launched over the frame's tiles, timed as `stage`.
  void launch(ClPipeline& p, const std::string& stage) {
    p.launchTiles(stage, forFrame(p), p.serialTiles());
  }

 private:
  cl::Kernel group_, serial_;
};

// The device's local memory per work-group, in bytes.
inline uint64_t localMemorySize(ClPipeline& p) {
  return p.runtime().queue().getInfo<CL_QUEUE_DEVICE>().getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
}

// For a method that sizes a tile kernel's __local tables from its settings: throws Error "<what>
// need N KB of local memory per tile; DEVICE has M KB<hint>" unless `needed` bytes fit.
inline void requireLocalMemory(ClPipeline& p, uint64_t needed, const std::string& what,
                               const std::string& hint = "") {
  const uint64_t available = localMemorySize(p);
  if (needed <= available) return;
  throw Error(what + " need " + std::to_string((needed + 1023) / 1024) +
              " KB of local memory per tile; " +
              p.runtime().queue().getInfo<CL_QUEUE_DEVICE>().getInfo<CL_DEVICE_NAME>() + " has " +
              std::to_string(available / 1024) + " KB" + hint);
}

}  // namespace strata
