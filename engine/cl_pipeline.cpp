// The shared OpenCL front end and frame loop. One frame, as data flows (DESIGN.md):
//   transform -> setup (clip, snap, edges) -> bin (count, scan, fill) -> method raster/resolve
#include "engine/cl_pipeline.h"

#include <chrono>

#include "engine/view_constants.h"

namespace strata {

namespace {

size_t roundUp(size_t n, size_t m) { return (n + m - 1) / m * m; }

}  // namespace

ClPipeline::ClPipeline(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device)
    : method_(method), impl_(std::move(impl)), rt_(ClRuntime::forDevice(device.device)),
      timer_(rt_.queue()) {
  transform_ = rt_.kernel("transform_vertices");
  setup_ = rt_.kernel("setup_triangles");
  bin_count_ = rt_.kernel("bin_count");
  bin_scan_ = rt_.kernel("bin_scan");
  bin_fill_ = rt_.kernel("bin_fill");
  impl_->init(*this);
}

cl::NDRange ClPipeline::tilesGlobal() const {
  return cl::NDRange(size_t(tiles_x_) * ST_TILE_SIZE, size_t(tiles_y_) * ST_TILE_SIZE);
}

cl::NDRange ClPipeline::tileLocal() const { return cl::NDRange(ST_TILE_SIZE, ST_TILE_SIZE); }

void ClPipeline::ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
  bytes = std::max<size_t>(bytes, 16);
  if (b.bytes != bytes) {
    b.buffer = cl::Buffer();  // free first, so the peak is not old + new
    b.bytes = 0;
    b.buffer = rt_.allocate(bytes, purpose);
    b.bytes = bytes;
  }
}

void ClPipeline::upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
  ensure(b, bytes, purpose);
  // Blocking: the source may be a local of the caller, and an error thrown before the frame's
  // finish must not leave the device reading a dead stack frame (found by ASan).
  if (bytes) rt_.queue().enqueueWriteBuffer(b.buffer, CL_TRUE, 0, bytes, data);
}

RenderResult ClPipeline::render(const WorldGeometry& geometry, const FrameSettings& settings) {
  validateFrameSize(settings.width, settings.height);
  try {
    return renderChecked(geometry, settings);
  } catch (const cl::Error& e) {
    rethrowClError(e, "rendering with method " + methodName(method_));
  }
}

RenderResult ClPipeline::renderChecked(const WorldGeometry& geo, const FrameSettings& settings) {
  width_ = settings.width;
  height_ = settings.height;
  tiles_x_ = uint32_t((width_ + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
  tiles_y_ = uint32_t((height_ + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
  triangle_count_ = geo.triangleCount();
  const uint32_t vertex_count = uint32_t(geo.positions.size());
  const uint32_t tile_count = tiles_x_ * tiles_y_;

  // The scene's own data (not counted in device_bytes).
  upload(positions_, geo.positions.data(), geo.positions.size() * sizeof(glm::vec3), "vertex positions");
  upload(indices_, geo.indices.data(), geo.indices.size() * sizeof(uint32_t), "triangle indices");
  upload(materials_, geo.triangle_material.data(), geo.triangle_material.size() * sizeof(uint32_t), "triangle materials");
  upload(material_colors_, geo.material_colors.data(), geo.material_colors.size() * sizeof(glm::vec4), "material colours");
  const StViewConstants view = makeViewConstants(settings);
  upload(view_, &view, sizeof(view), "view constants");

  // Working buffers sized by the frame.
  ensure(clip_, size_t(vertex_count) * 16, "clip-space vertices");
  ensure(triangle_colors_, size_t(triangle_count_) * 16, "triangle colours");
  ensure(tile_counts_, size_t(tile_count) * 4, "tile counts");
  ensure(tile_offsets_, size_t(tile_count + 1) * 4, "tile offsets");
  ensure(tile_cursors_, size_t(tile_count) * 4, "tile cursors");
  ensure(counters_, ST_COUNTER_COUNT * sizeof(uint64_t), "frame counters");
  ensure(image_, pixels() * 4, "image");
  capture_depth_ = settings.capture_depth_complexity;
  ensure(depth_map_, capture_depth_ ? pixels() * 4 : 16, "depth-complexity map");
  if (overflow_capacity_ == 0) overflow_capacity_ = triangle_count_ / 64 + 1024;
  if (bin_capacity_ == 0) bin_capacity_ = 2 * size_t(triangle_count_) + tile_count + 1024;
  impl_->prepare(*this, settings);

  RenderResult result;
  FrameStats& st = result.stats;
  std::vector<double> frame_ms;
  std::map<std::string, std::vector<double>> stage_runs;
  uint64_t counters[ST_COUNTER_COUNT] = {};
  const int frames = std::max(1, settings.frames);
  for (int f = 0; f < frames;) {
    ensure(records_, (triangle_count_ + overflow_capacity_) * sizeof(StTriSetup), "setup records");
    ensure(bins_, bin_capacity_ * 4, "tile bin entries");
    rt_.queue().finish();  // uploads and allocations are not part of the frame time

    timer_.clear();
    const auto t0 = std::chrono::steady_clock::now();
    enqueueFrontEnd(vertex_count);
    impl_->enqueue(*this);
    rt_.queue().enqueueReadBuffer(counters_.buffer, CL_TRUE, 0, sizeof(counters), counters);
    const auto t1 = std::chrono::steady_clock::now();

    // Grow what overflowed to the count the kernels reported, and run the frame again.
    bool rerun = false;
    if (counters[ST_COUNTER_SETUP_OVERFLOW] > overflow_capacity_) {
      overflow_capacity_ = counters[ST_COUNTER_SETUP_OVERFLOW] + counters[ST_COUNTER_SETUP_OVERFLOW] / 16;
      rerun = true;
    } else if (counters[ST_COUNTER_BIN_ENTRIES] > bin_capacity_) {
      bin_capacity_ = counters[ST_COUNTER_BIN_ENTRIES] + counters[ST_COUNTER_BIN_ENTRIES] / 16;
      rerun = true;
    } else {
      rerun = impl_->growIfOverflowed(*this, counters);
    }
    if (rerun) {
      ++st.reruns;
      continue;
    }
    if (!warmed_up_) {
      // The first frame a pipeline runs pays for PoCL's lazy kernel compilation: not timed.
      warmed_up_ = true;
      continue;
    }
    frame_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    for (const auto& [name, ms] : timer_.stageTimes()) stage_runs[name].push_back(ms);
    ++f;
    if (settings.on_frame) settings.on_frame(f, frames);
  }

  result.image = Image(width_, height_);
  rt_.queue().enqueueReadBuffer(image_.buffer, CL_TRUE, 0, pixels() * 4, result.image.rgba.data());
  if (capture_depth_) {
    result.depth_complexity.resize(pixels());
    rt_.queue().enqueueReadBuffer(depth_map_.buffer, CL_TRUE, 0, pixels() * 4,
                                  result.depth_complexity.data());
  }

  st.method = methodName(method_);
  st.device = rt_.info().label();
  st.width = width_;
  st.height = height_;
  st.triangles = triangle_count_;
  st.triangles_read = triangle_count_;  // single pass; multi-pass methods scale it in addStats
  st.fragments = counters[ST_COUNTER_FRAGMENTS];
  st.max_depth_complexity = counters[ST_COUNTER_MAX_DEPTH];
  st.culled_degenerate = counters[ST_COUNTER_CULLED_DEGENERATE];
  st.culled_nonfinite = counters[ST_COUNTER_CULLED_NONFINITE];
  st.clipped = counters[ST_COUNTER_CLIPPED];
  st.kernel_launches = timer_.launches();
  impl_->addStats(*this, counters, st);
  st.device_bytes = clip_.bytes + triangle_colors_.bytes + tile_counts_.bytes + tile_offsets_.bytes +
                    tile_cursors_.bytes + counters_.bytes + image_.bytes + records_.bytes +
                    bins_.bytes + (capture_depth_ ? depth_map_.bytes : 0) +
                    // Layers a method keeps in local memory still count as fragment memory.
                    std::max<uint64_t>(impl_->deviceBytes(), st.fragment_bytes);
  st.frame_ms = summarizeTimes(frame_ms);
  for (auto& [name, runs] : stage_runs) st.stage_ms[name] = summarizeTimes(runs).median;
  return result;
}

void ClPipeline::enqueueFrontEnd(uint32_t vertex_count) {
  const uint32_t tile_count = tiles_x_ * tiles_y_;
  const cl_uint overflow_cap = cl_uint(overflow_capacity_);
  const size_t record_slots = size_t(triangle_count_) + overflow_capacity_;
  timer_.fill("clear", counters_.buffer, 0u, counters_.bytes);
  timer_.fill("clear", tile_counts_.buffer, 0u, size_t(tile_count) * 4);

  setArgs(transform_, positions_.buffer, cl_uint(vertex_count), view_.buffer, clip_.buffer);
  timer_.launch("transform", transform_, cl::NDRange(roundUp(vertex_count, ST_LINEAR_WG)),
                cl::NDRange(ST_LINEAR_WG));
  setArgs(setup_, positions_.buffer, indices_.buffer, materials_.buffer, material_colors_.buffer,
          cl_uint(vertex_count), cl_uint(triangle_count_), clip_.buffer, view_.buffer,
          triangle_colors_.buffer, records_.buffer, overflow_cap, counters_.buffer);
  timer_.launch("setup", setup_, cl::NDRange(roundUp(triangle_count_, ST_LINEAR_WG)),
                cl::NDRange(ST_LINEAR_WG));
  setArgs(bin_count_, records_.buffer, cl_uint(triangle_count_), overflow_cap, counters_.buffer,
          cl_uint(tiles_x_), tile_counts_.buffer);
  timer_.launch("bin", bin_count_, cl::NDRange(roundUp(record_slots, ST_LINEAR_WG)),
                cl::NDRange(ST_LINEAR_WG));
  setArgs(bin_scan_, tile_counts_.buffer, cl_uint(tile_count), tile_offsets_.buffer,
          tile_cursors_.buffer, counters_.buffer);
  timer_.launch("bin", bin_scan_, cl::NDRange(ST_SCAN_WG), cl::NDRange(ST_SCAN_WG));
  setArgs(bin_fill_, records_.buffer, cl_uint(triangle_count_), overflow_cap, counters_.buffer,
          cl_uint(tiles_x_), tile_cursors_.buffer, bins_.buffer, binCapacity());
  timer_.launch("bin", bin_fill_, cl::NDRange(roundUp(record_slots, ST_LINEAR_WG)),
                cl::NDRange(ST_LINEAR_WG));
}

}  // namespace strata
