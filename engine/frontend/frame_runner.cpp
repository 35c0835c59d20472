#include "engine/frontend/frame_runner.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include "engine/frontend/view_constants.h"

namespace strata {

FrameRunner::FrameRunner(std::string method_name, const DeviceOptions& device)
    : runtime_(ClRuntime::acquire(device.device, device.atomics)),
      method_(std::move(method_name)),
      timer_(*runtime_) {
  const cl_uint units = runtime_->device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
  bin_run_limit_ = std::clamp<uint32_t>(8 * units, 16, 256);
  compute_units_ = std::max<uint32_t>(units, 1);
}

void FrameRunner::transformVertices(const cl::Buffer& positions, uint32_t vertex_count,
                                    const cl::Buffer& view, const cl::Buffer& screen) {
  if (vertex_count == 0) return;
  // PoCL compiles explicit vectors to SIMD but leaves the work-item loop scalar.
  const uint32_t lanes = runtime_->info().isPocl() ? 8 : 1;
  if (!transform_())
    transform_ = kernel(lanes > 1 ? "transform_vertices_lanes" : "transform_vertices");
  setArgs(transform_, positions, cl_uint(vertex_count), view, screen);
  timer_.launch("transform", transform_,
                cl::NDRange(roundUp((vertex_count + lanes - 1) / lanes, ST_LINEAR_WG)),
                cl::NDRange(ST_LINEAR_WG));
}

cl_uint4 FrameRunner::blockRange(const glm::ivec4& rect) const {
  cl_uint4 range{};
  if (rect.x > rect.z || rect.y > rect.w) return range;  // no blocks
  const uint32_t block_px = ST_TILE_SIZE * ST_CELLS_BLOCK_TILES;
  const uint32_t blocks_x = (tiles_x_ + ST_CELLS_BLOCK_TILES - 1) / ST_CELLS_BLOCK_TILES;
  const uint32_t blocks_y = (tiles_y_ + ST_CELLS_BLOCK_TILES - 1) / ST_CELLS_BLOCK_TILES;
  const uint32_t bx0 = uint32_t(rect.x) / block_px, by0 = uint32_t(rect.y) / block_px;
  const uint32_t bx1 = std::min(blocks_x - 1, uint32_t(rect.z) / block_px);
  const uint32_t by1 = std::min(blocks_y - 1, uint32_t(rect.w) / block_px);
  range.s[0] = bx0;
  range.s[1] = by0;
  range.s[2] = bx1 - bx0 + 1;
  range.s[3] = by1 - by0 + 1;
  return range;
}

void FrameRunner::launchBlocks(const std::string& stage, cl::Kernel& kernel, const cl_uint4& range,
                               bool serial) {
  if (range.s[2] == 0 || range.s[3] == 0) return;
  if (serial) {
    timer_.launch(stage, kernel, cl::NDRange(compute_units_), cl::NDRange(1));
    return;
  }
  timer_.launch(stage, kernel,
                cl::NDRange(size_t(range.s[2]) * ST_TILE_SIZE, size_t(range.s[3]) * ST_TILE_SIZE),
                cl::NDRange(ST_TILE_SIZE, ST_TILE_SIZE),
                cl::NDRange(size_t(range.s[0]) * ST_TILE_SIZE, size_t(range.s[1]) * ST_TILE_SIZE));
}

uint32_t FrameRunner::localLayers(uint32_t max_layers, uint32_t min_layers, const char* method) {
  const uint64_t local = runtime_->device().getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
  const uint64_t usable = local > 8192 ? local - 8192 : 0;
  const uint32_t layers = uint32_t(std::min<uint64_t>(max_layers, usable / (ST_TILE_PIXELS * 8)));
  if (layers < min_layers)
    throw Error("device " + runtime_->info().label() + ": too little local memory for the " +
                method + " method");
  return layers;
}

uint32_t FrameRunner::binRuns(uint64_t records) const {
  const uint64_t tiles = std::max<uint64_t>(tileCount(), 1);
  return uint32_t(std::clamp<uint64_t>(std::min<uint64_t>(2 * records / tiles, (1u << 24) / tiles),
                                       1, bin_run_limit_));
}

cl::NDRange FrameRunner::tilesGlobal() const {
  return cl::NDRange(size_t(tiles_x_) * ST_TILE_SIZE, size_t(tiles_y_) * ST_TILE_SIZE);
}

cl::NDRange FrameRunner::tileLocal() const { return cl::NDRange(ST_TILE_SIZE, ST_TILE_SIZE); }

bool FrameRunner::serialTilesFor(const std::string& choice) const {
  checkTileKernels(choice);
  const DeviceInfo& d = runtime_->info();
  // The work-group forms merge 64-bit words with 64-bit local atomics.
  if (!runtime_->int64Atomics()) {
    if (choice == "group")
      throw Error(
          method_ + ": the work-group tile kernels need 64-bit atomics, which this run " +
          (d.hasInt64Atomics() ? "was told not to use (--atomics 32)" : "lacks on " + d.name) +
          ": use --tile-kernels serial or auto");
    return true;
  }
  if (choice != "auto") return choice == "serial";
  return !d.is_gpu && d.isPocl();
}

void FrameRunner::fillBackground(const cl::Buffer& view, DeviceBuffer& pixel_fragments,
                                 const std::string& stage) {
  if (!background_()) background_ = kernel("fill_background");
  setArgs(background_, view, image_.buffer, pixel_fragments.buffer);
  timer_.launch(stage, background_, tilesGlobal(), tileLocal());
}

void FrameRunner::ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
  bytes = std::max<size_t>(bytes, 16);
  if (b.bytes != bytes) {
    b.buffer = cl::Buffer();
    b.bytes = 0;
    b.buffer = runtime_->allocate(bytes, purpose);
    b.bytes = bytes;
  }
}

void FrameRunner::upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
  ensure(b, bytes, purpose);
  // Blocking: the source may be a local of the caller, and an error thrown before the frame's
  // finish must not leave the device reading a dead stack frame.
  if (bytes) runtime_->queue().enqueueWriteBuffer(b.buffer, CL_TRUE, 0, bytes, data);
}

RenderResult FrameRunner::render(const WorldGeometry& geometry, const FrameSettings& settings,
                                 FrameStages& stages) {
  validateFrameSize(settings.width, settings.height);
  try {
    try {
      return renderChecked(geometry, settings, stages);
    } catch (...) {
      // Per-frame uploads may be non-blocking from the stages' members: let them finish before
      // anything that failed unwinds further (and perhaps destroys the stages).
      try {
        runtime_->queue().finish();
      } catch (const cl::Error&) {
      }
      throw;
    }
  } catch (const cl::Error& e) {
    rethrowClError(e, "rendering with method " + method_);
  }
}

RenderResult FrameRunner::renderChecked(const WorldGeometry& geometry,
                                        const FrameSettings& settings, FrameStages& stages) {
  width_ = settings.width;
  height_ = settings.height;
  tiles_x_ = uint32_t((width_ + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
  tiles_y_ = uint32_t((height_ + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
  serial_tiles_ = serialTilesFor(settings.tile_kernels);
  ensure(counters_, ST_COUNTER_COUNT * sizeof(uint64_t), "frame counters");
  ensure(image_, pixels() * 4, "image");
  stages.prepare(geometry, settings);

  RenderResult result;
  FrameStats& st = result.stats;
  std::vector<double> frame_ms;
  std::map<std::string, std::vector<double>> stage_runs;
  std::map<std::string, std::vector<double>> kernel_runs;
  std::map<std::string, uint64_t> kernel_launches;
  uint64_t counters[ST_COUNTER_COUNT] = {};
  cl::CommandQueue& queue = runtime_->queue();
  const int frames = std::max(1, settings.frames);
  FrameSettings frame = settings;  // this frame's camera when the camera moves
  for (int f = 0; f < frames;) {
    stages.beforeFrame();
    queue.finish();  // uploads and allocations are not part of the frame time
    timer_.clear();
    // The warm-up frame looks one step before the first, so every timed frame of a moving
    // camera is a view not seen before (and pays for everything a new view needs).
    if (settings.orbit_deg != 0.0f) frame.camera = frameCamera(settings, warmed_up_ ? f : -1);
    const auto t0 = std::chrono::steady_clock::now();
    timer_.fill("clear", counters_.buffer, 0u, counters_.bytes);
    stages.enqueueFrame(frame);
    const int next = warmed_up_ ? f + 1 : 0;
    if (settings.orbit_deg != 0.0f && next < frames) {
      queue.flush();  // the device starts on this frame while the host prepares the next
      FrameSettings ahead = settings;
      ahead.camera = frameCamera(settings, next);
      stages.willRender(ahead);
    }
    queue.enqueueReadBuffer(counters_.buffer, CL_TRUE, 0, sizeof(counters), counters);
    const auto t1 = std::chrono::steady_clock::now();
    if (stages.growIfOverflowed(counters)) {
      ++st.reruns;
      continue;
    }
    if (!warmed_up_) {
      warmed_up_ = true;
      continue;
    }
    frame_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    for (const auto& [name, ms] : timer_.stageTimes()) stage_runs[name].push_back(ms);
    for (const auto& [name, k] : timer_.kernelTimes()) {
      kernel_runs[name].push_back(k.ms);
      kernel_launches[name] = k.launches;
    }
    stages.frameTimed();
    ++f;
    if (settings.on_frame) settings.on_frame(f, frames);
  }

  result.image = Image(width_, height_);
  queue.enqueueReadBuffer(image_.buffer, CL_TRUE, 0, pixels() * 4, result.image.rgba.data());
  if (settings.capture_depth_complexity) {
    result.depth_complexity.resize(pixels());
    queue.enqueueReadBuffer(stages.depthComplexity().buffer, CL_TRUE, 0, pixels() * 4,
                            result.depth_complexity.data());
  }

  st.method = method_;
  st.device = runtime_->info().label();
  st.width = width_;
  st.height = height_;
  st.fragments = counters[ST_COUNTER_FRAGMENTS];
  st.max_depth_complexity = counters[ST_COUNTER_MAX_DEPTH];
  st.culled_degenerate = counters[ST_COUNTER_CULLED_DEGENERATE];
  st.culled_nonfinite = counters[ST_COUNTER_CULLED_NONFINITE];
  st.clipped = counters[ST_COUNTER_CLIPPED];
  st.kernel_launches = timer_.launches();
  st.orbit_deg = settings.orbit_deg;
  st.frame_ms = summarizeTimes(frame_ms);
  for (auto& [name, runs] : stage_runs) st.stage_ms[name] = summarizeTimes(runs).median;
  for (auto& [name, runs] : kernel_runs)
    st.kernel_ms[name] = {summarizeTimes(runs).median, kernel_launches[name]};
  st.tile_kernels = "group";  // a method with serial tile kernels says when they ran
  stages.addStats(counters, st);
  st.device_bytes += counters_.bytes + image_.bytes;
  stages.addOutputs(result);
  return result;
}

}  // namespace strata
