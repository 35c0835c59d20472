// The shared OpenCL front end (transform, setup, binning) and the interface every OpenCL method
// implements on top of it (raster passes and resolve). Private to the library: includes OpenCL.
//
// A frame: the pipeline clears its counters, runs the front end once, then hands over to the
// method, which rasterizes the binned triangles (once, or once per geometry pass) and resolves
// into the image. After the frame the counters are read back once; any buffer whose needed size
// exceeded its capacity is grown to the reported count and the frame re-run, so nothing is ever
// silently truncated.
#pragma once

#include <memory>
#include <string>

#include "engine/batching.h"
#include "engine/device_atlas.h"
#include "engine/draw_sort.h"
#include "engine/renderer.h"
#include "host/cl_runtime.h"
#include "kernels/strata_shared.h"

namespace strata {

// A device buffer and its size in bytes.
struct DeviceBuffer {
  cl::Buffer buffer;
  size_t bytes = 0;
};

class ClPipeline;

// Sets a kernel's arguments in order.
template <typename... Args>
void setArgs(cl::Kernel& k, Args&&... args) {
  cl_uint i = 0;
  (k.setArg(i++, std::forward<Args>(args)), ...);
}

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
};

class ClPipeline {
 public:
  ClPipeline(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device);

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings);

  // --- for methods ---
  ClRuntime& runtime() { return rt_; }
  LaunchTimer& timer() { return timer_; }
  cl::Kernel kernel(const std::string& name) { return rt_.kernel(name); }
  // Allocates (or reallocates) `b` to exactly `bytes` (at least 16).
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose);

  int width() const { return width_; }
  int height() const { return height_; }
  size_t pixels() const { return size_t(width_) * size_t(height_); }
  uint32_t tilesX() const { return tiles_x_; }
  uint32_t tilesY() const { return tiles_y_; }
  uint32_t triangleCount() const { return triangle_count_; }  // = record slots of the front end
  cl_uint binCapacity() const { return cl_uint(bin_capacity_); }
  bool captureDepthComplexity() const { return capture_depth_; }
  // NDRanges of a per-tile launch: one ST_TILE_SIZE^2 work-group per screen tile.
  cl::NDRange tilesGlobal() const;
  cl::NDRange tileLocal() const;

  DeviceBuffer& view() { return view_; }
  DeviceBuffer& triangleColors() { return triangle_colors_; }
  // Texturing (kernels/texture.cl): a record per world triangle and the atlas words; 16-byte
  // placeholders when the scene is not textured (view constants say so).
  DeviceBuffer& texTriangles() { return tex_tris_; }
  DeviceBuffer& atlas() { return atlas_; }
  DeviceBuffer& records() { return records_; }
  DeviceBuffer& bins() { return bins_; }
  DeviceBuffer& tileOffsets() { return tile_offsets_; }
  DeviceBuffer& counters() { return counters_; }
  DeviceBuffer& image() { return image_; }
  DeviceBuffer& depthComplexity() { return depth_map_; }  // per-pixel counts, if captured

 private:
  RenderResult renderChecked(const WorldGeometry& geometry, const FrameSettings& settings);
  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose);
  // Per frame: sorts the draw units, uploads the frame's constants, draw table and instances
  // (non-blocking, from members that outlive the frame) and enqueues the front end.
  void enqueueFrontEnd(const FrameSettings& settings);

  Method method_;
  std::unique_ptr<ClMethod> impl_;
  ClRuntime& rt_;
  LaunchTimer timer_;
  cl::Kernel transform_, setup_, bin_count_, bin_scan_, bin_fill_;
  DeviceBuffer positions_, indices_, materials_, material_colors_, view_;
  // Draw units (engine/batching.h): the plan of the current render() call, the source triangle
  // ids (static), instances, the frame's draw table, world positions written by the transform.
  BatchPlan plan_;
  DrawSorter sorter_;
  DrawSort sort_ = DrawSort::None;
  std::vector<uint32_t> order_;
  std::vector<StDraw> table_;
  std::vector<DrawLaunch> launches_;
  StViewConstants view_host_{};
  DrawSortStats sort_stats_;
  uint64_t frame_upload_bytes_ = 0;
  DeviceBuffer triangle_ids_, instances_, draws_, world_, tex_tris_, atlas_;
  DeviceAtlasCache atlas_cache_;
  DeviceBuffer clip_, triangle_colors_, tile_counts_, tile_offsets_, tile_cursors_, counters_,
      image_, records_, bins_, depth_map_;
  int width_ = 0, height_ = 0;
  uint32_t tiles_x_ = 0, tiles_y_ = 0, triangle_count_ = 0;
  size_t overflow_capacity_ = 0, bin_capacity_ = 0;
  bool capture_depth_ = false;
  bool warmed_up_ = false;
};

// Method factories, one file each (engine/method_*.cpp).
std::unique_ptr<ClMethod> makeOpaqueMethod();
std::unique_ptr<ClMethod> makePpllMethod();
std::unique_ptr<ClMethod> makeAbufferMethod();                  // method_abuffer.cpp
std::unique_ptr<ClMethod> makeMdtsMethod(bool packed_32bit);      // method_mdts.cpp
std::unique_ptr<ClMethod> makeDepthPeelingMethod(bool dual);      // method_peeling.cpp
std::unique_ptr<ClMethod> makeBucketPeelingMethod(bool adaptive); // method_bucket.cpp
// The convex-cells method streams batches through its own front end (method_cells.cpp).
std::unique_ptr<Renderer> makeCellsRenderer(const DeviceOptions& device);

}  // namespace strata
