// The frame loop every OpenCL method runs through, written once: warm-up, grow-and-rerun on
// overflow, per-stage timing, read-back and the common statistics. A method supplies only its
// stages (FrameStages). Private to the library: includes OpenCL.
//
// One render() call: the stages prepare the call (uploads, sizes), then frames run until
// settings.frames of them have been timed. Each frame attempt: the stages size their buffers
// (not timed), the runner clears the frame counters, the stages enqueue the frame, and the
// counters are read back once. Any buffer whose needed size exceeded its capacity is grown by
// the stages to the count the kernels reported and the frame run again, so nothing is ever
// silently truncated. The first frame a runner runs is not timed: PoCL compiles kernels lazily
// at their first launch.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include <glm/glm.hpp>

#include "engine/renderer.h"
#include "host/cl_runtime.h"
#include "kernels/strata_shared.h"

namespace strata {

// A device buffer and its size in bytes.
struct DeviceBuffer {
  cl::Buffer buffer;
  size_t bytes = 0;
};

// Sets a kernel's arguments in order.
template <typename... Args>
void setArgs(cl::Kernel& k, Args&&... args) {
  cl_uint i = 0;
  (k.setArg(i++, std::forward<Args>(args)), ...);
}

inline size_t roundUp(size_t n, size_t m) { return (n + m - 1) / m * m; }
// When `needed` exceeds `capacity`: `capacity` grown to `needed` and 1/16 more, rounded up to a
// multiple of `quantum`, and true (the frame runs again with it).
template <class Capacity>
bool growCapacity(Capacity& capacity, uint64_t needed, uint64_t quantum) {
  if (needed <= capacity) return false;
  capacity = Capacity(roundUp(needed + needed / 16, quantum));
  return true;
}

// Bytes as "12.3 MB" for messages about device memory.
inline std::string megabytes(uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f MB", double(bytes) / (1024.0 * 1024.0));
  return text;
}

// What one method gives the frame runner.
class FrameStages {
 public:
  virtual ~FrameStages() = default;
  // Once per render() call, before its first frame: uploads and sizes what the call needs.
  virtual void prepare(const WorldGeometry& geometry, const FrameSettings& settings) = 0;
  // Before every frame attempt, outside the timed part: sizes buffers to current capacities.
  virtual void beforeFrame() {}
  // Enqueues one frame (timed): everything after the counter clear, ending with the frame's
  // counters in FrameRunner::counters().
  virtual void enqueueFrame(const FrameSettings& settings) = 0;
  // A moving camera, after enqueueFrame and a flush, before the frame's counters are read: the
  // settings of the frame that comes next, so that host work for it can overlap the device's
  // work on this one.
  virtual void willRender(const FrameSettings&) {}
  // After a frame: grows what overflowed (from the counters read back); true runs it again.
  virtual bool growIfOverflowed(const uint64_t* counters) = 0;
  // After each timed frame: the stages' own per-frame figures.
  virtual void frameTimed() {}
  // Per-pixel fragment counts, read back when the settings ask for depth complexity.
  virtual DeviceBuffer& depthComplexity() = 0;
  // After the last frame: the method's statistics, device_bytes being its own buffers (the
  // runner adds the image and the counters). frame_ms and stage_ms are already filled.
  virtual void addStats(const uint64_t* counters, FrameStats& stats) = 0;
  // After the statistics: outputs beyond the image (RenderResult::partial).
  virtual void addOutputs(RenderResult&) {}
};

class FrameRunner {
 public:
  FrameRunner(std::string method_name, const DeviceOptions& device);

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings,
                      FrameStages& stages);

  ClRuntime& runtime() { return *runtime_; }
  LaunchTimer& timer() { return timer_; }
  cl::Kernel kernel(const std::string& name) { return runtime_->kernel(name); }
  // The one sizing rule of every working buffer: exactly `bytes` (at least 16), reallocated
  // whenever the size asked for changes (freed first, so the peak is not old + new).
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose);
  // ensure(), then a blocking write (the source may be a caller's local).
  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose);

  // The frame of the current render() call.
  int width() const { return width_; }
  int height() const { return height_; }
  size_t pixels() const { return size_t(width_) * size_t(height_); }
  uint32_t tilesX() const { return tiles_x_; }
  uint32_t tilesY() const { return tiles_y_; }
  uint32_t tileCount() const { return tiles_x_ * tiles_y_; }
  // NDRanges of a per-tile launch: one ST_TILE_SIZE^2 work-group per screen tile.
  cl::NDRange tilesGlobal() const;
  cl::NDRange tileLocal() const;
  // Whether the current render() call runs per-tile kernels serially (FrameSettings::
  // tile_kernels; auto: on PoCL's CPU devices), and the NDRanges of such a launch: one work-item,
  // a work-group of its own, per screen tile.
  bool serialTiles() const { return serial_tiles_; }
  cl::NDRange tilesSerialGlobal() const { return cl::NDRange(tiles_x_, tiles_y_); }
  cl::NDRange tileSerialLocal() const { return cl::NDRange(1, 1); }
  // How many (depth, id) layers of ST_TILE_PIXELS 64-bit words a tile kernel can keep in the
  // device's local memory beside 8 KiB of its own scratch, at most `max_layers`; throws Error
  // naming the device and `method` when that is fewer than `min_layers`.
  uint32_t localLayers(uint32_t max_layers, uint32_t min_layers, const char* method);
  // Whether FrameSettings::tile_kernels asks for serial tile kernels on this device; throws
  // Error for a name other than auto, group or serial.
  bool serialTilesFor(const std::string& choice) const;
  // Runs of records for the ordered binners (bin_count_serial, cells_bin_count), which count
  // in a tile x run table without atomics: at most binRunLimit() (8 per compute unit, 16..256),
  // no more than two per tile's worth of `records` (the table is cleared and scanned whole for
  // every batch, which for a few large triangles cost more than the counts), and a table of at
  // most 2^24 entries however large the frame.
  uint32_t binRunLimit() const { return bin_run_limit_; }
  uint32_t binRuns(uint64_t records) const;
  // Words of such a table's counts (and cursors), stored run by run with each run's column
  // padded (st_run_slot in bin.cl), the last column unpadded: for one run, a word per tile. Its
  // offsets are one word per entry, tile by tile, and one.
  uint64_t binRunTableWords(uint32_t runs) const {
    return uint64_t(std::max<uint32_t>(runs, 1) - 1) * (tileCount() + ST_BIN_RUN_PAD) + tileCount();
  }
  // Projects and snaps `vertex_count` world-space vertices into `screen` (transform.cl), timed
  // as the "transform" stage: eight vertices a work-item in vector lanes on PoCL, else one.
  void transformVertices(const cl::Buffer& positions, uint32_t vertex_count, const cl::Buffer& view,
                         const cl::Buffer& screen);
  // Launches a per-tile kernel timed as `stage`: a work-group per tile, or with `serial` (a
  // kernel of the serial form) a work-item per tile.
  void launchTiles(const std::string& stage, cl::Kernel& kernel, bool serial) {
    timer_.launch(stage, kernel, serial ? tilesSerialGlobal() : tilesGlobal(),
                  serial ? tileSerialLocal() : tileLocal());
  }
  // The whole image as a pixel rectangle (min x, min y, max x, max y).
  glm::ivec4 imageRect() const { return glm::ivec4(0, 0, width_ - 1, height_ - 1); }
  // The blocks of ST_CELLS_BLOCK_TILES^2 tiles the pixel rectangle `rect` touches, as the block
  // kernels' `block_range` argument: the first block's x and y, then blocks across and down
  // (none for an empty rectangle).
  cl_uint4 blockRange(const glm::ivec4& rect) const;
  // Launches a per-block kernel (cells_composite, octree_resolve) over `range`, timed as
  // `stage`: a work-group of ST_TILE_SIZE^2 work-items per block, or with `serial` (the serial
  // form) a work-item per compute unit, which claim the blocks themselves (st_block_deal_next).
  // Nothing for an empty range.
  void launchBlocks(const std::string& stage, cl::Kernel& kernel, const cl_uint4& range,
                    bool serial);

  DeviceBuffer& counters() { return counters_; }  // ST_COUNTER_COUNT 64-bit frame counters
  DeviceBuffer& image() { return image_; }        // RGBA8, row-major
  // Enqueues fill_background: the view's background into every pixel of the image and 0 into
  // every pixel's fragment count, timed as `stage` (a frame whose kernels skip empty tiles).
  void fillBackground(const cl::Buffer& view, DeviceBuffer& pixel_fragments,
                      const std::string& stage);

 private:
  RenderResult renderChecked(const WorldGeometry& geometry, const FrameSettings& settings,
                             FrameStages& stages);

  std::shared_ptr<ClRuntime> runtime_;  // first member: released last
  std::string method_;
  LaunchTimer timer_;
  cl::Kernel background_;  // fill_background, made on first use
  cl::Kernel transform_;   // transform_vertices(_lanes), made on first use
  DeviceBuffer counters_, image_;
  int width_ = 0, height_ = 0;
  uint32_t tiles_x_ = 0, tiles_y_ = 0;
  bool warmed_up_ = false;
  bool serial_tiles_ = false;
  uint32_t bin_run_limit_ = 16;
  uint32_t compute_units_ = 1;
};

}  // namespace strata
