// OpenCL rasterization methods. One frame, as data flows (DESIGN.md):
//   transform -> setup (clip, snap, edges) -> bin (count, scan, fill) -> raster -> shade/resolve
// Buffers whose size depends on the frame's content (setup records, bin entries, list nodes) are
// sized from the counts the kernels report: if one overflowed, it is grown and the frame re-run.
#include "engine/cl_renderer.h"

#include <chrono>
#include <cstring>

#include "engine/view_constants.h"
#include "host/cl_runtime.h"
#include "kernels/strata_shared.h"

namespace strata {

namespace {

size_t roundUp(size_t n, size_t m) { return (n + m - 1) / m * m; }

// A device buffer and its size; reallocated when a frame needs a different size.
struct DeviceBuffer {
  cl::Buffer buffer;
  size_t bytes = 0;
};

template <typename... Args>
void setArgs(cl::Kernel& k, Args&&... args) {
  cl_uint i = 0;
  (k.setArg(i++, std::forward<Args>(args)), ...);
}

class ClRenderer final : public Renderer {
 public:
  ClRenderer(Method method, const DeviceOptions& device)
      : method_(method), rt_(ClRuntime::forDevice(device.device)) {
    transform_ = rt_.kernel("transform_vertices");
    setup_ = rt_.kernel("setup_triangles");
    bin_count_ = rt_.kernel("bin_count");
    bin_scan_ = rt_.kernel("bin_scan");
    bin_fill_ = rt_.kernel("bin_fill");
    if (method_ == Method::Opaque) {
      raster_ = rt_.kernel("raster_visibility");
      resolve_ = rt_.kernel("shade_visibility");
    } else {
      raster_ = rt_.kernel("ppll_build");
      resolve_ = rt_.kernel("ppll_resolve");
    }
  }

  RenderResult render(const WorldGeometry& geo, const FrameSettings& settings) override {
    validateFrameSize(settings.width, settings.height);
    try {
      return renderChecked(geo, settings);
    } catch (const cl::Error& e) {
      rethrowClError(e, "rendering with method " + methodName(method_));
    }
  }

 private:
  // Allocates (or reallocates) a buffer to exactly `bytes` and counts it in the frame's memory.
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
    bytes = std::max<size_t>(bytes, 16);
    if (b.bytes != bytes) {
      b.buffer = cl::Buffer();  // free first, so the peak is not old + new
      b.buffer = rt_.allocate(bytes, purpose);
      b.bytes = bytes;
    }
  }

  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
    ensure(b, bytes, purpose);
    if (bytes) rt_.queue().enqueueWriteBuffer(b.buffer, CL_FALSE, 0, bytes, data);
  }

  RenderResult renderChecked(const WorldGeometry& geo, const FrameSettings& settings) {
    const int width = settings.width, height = settings.height;
    const size_t pixels = size_t(width) * size_t(height);
    const uint32_t vertex_count = uint32_t(geo.positions.size());
    const uint32_t triangle_count = geo.triangleCount();
    const uint32_t tiles_x = uint32_t((width + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
    const uint32_t tiles_y = uint32_t((height + ST_TILE_SIZE - 1) / ST_TILE_SIZE);
    const uint32_t tile_count = tiles_x * tiles_y;

    // The scene's own data (not counted in device_bytes).
    upload(positions_, geo.positions.data(), geo.positions.size() * sizeof(glm::vec3), "vertex positions");
    upload(indices_, geo.indices.data(), geo.indices.size() * sizeof(uint32_t), "triangle indices");
    upload(materials_, geo.triangle_material.data(), geo.triangle_material.size() * sizeof(uint32_t), "triangle materials");
    upload(material_colors_, geo.material_colors.data(), geo.material_colors.size() * sizeof(glm::vec4), "material colours");
    const StViewConstants view = makeViewConstants(settings);
    upload(view_, &view, sizeof(view), "view constants");

    // Working buffers sized by the frame.
    ensure(clip_, size_t(vertex_count) * 16, "clip-space vertices");
    ensure(triangle_colors_, size_t(triangle_count) * 16, "triangle colours");
    ensure(tile_counts_, size_t(tile_count) * 4, "tile counts");
    ensure(tile_offsets_, size_t(tile_count + 1) * 4, "tile offsets");
    ensure(tile_cursors_, size_t(tile_count) * 4, "tile cursors");
    ensure(counters_, ST_COUNTER_COUNT * sizeof(uint64_t), "frame counters");
    ensure(image_, pixels * 4, "image");
    if (method_ == Method::Opaque) {
      ensure(visibility_, pixels * 8, "visibility buffer");
    } else {
      ensure(heads_, pixels * 4, "linked-list heads");
    }
    capture_depth_ = settings.capture_depth_complexity && method_ == Method::Ppll;
    ensure(depth_map_, capture_depth_ ? pixels * 4 : 16, "depth-complexity map");
    if (overflow_capacity_ == 0) overflow_capacity_ = triangle_count / 64 + 1024;
    if (bin_capacity_ == 0) bin_capacity_ = 2 * size_t(triangle_count) + tile_count + 1024;
    if (node_capacity_ == 0) node_capacity_ = 2 * pixels + 1024;

    RenderResult result;
    FrameStats& st = result.stats;
    std::vector<double> frame_ms;
    std::map<std::string, std::vector<double>> stage_runs;
    uint64_t counters[ST_COUNTER_COUNT] = {};
    const int frames = std::max(1, settings.frames);
    LaunchTimer timer(rt_.queue());
    for (int f = 0; f < frames;) {
      ensure(records_, (triangle_count + overflow_capacity_) * sizeof(StTriSetup), "setup records");
      ensure(bins_, bin_capacity_ * 4, "tile bin entries");
      if (method_ == Method::Ppll) ensure(nodes_, node_capacity_ * sizeof(StPpllNode), "linked-list nodes");
      rt_.queue().finish();  // uploads and allocations are not part of the frame time

      timer.clear();
      const auto t0 = std::chrono::steady_clock::now();
      enqueueFrame(timer, geo, width, height, tiles_x, tiles_y, vertex_count, triangle_count);
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
      } else if (method_ == Method::Ppll && counters[ST_COUNTER_NODES] > node_capacity_) {
        node_capacity_ = counters[ST_COUNTER_NODES] + counters[ST_COUNTER_NODES] / 16;
        rerun = true;
      }
      if (rerun) {
        ++st.reruns;
        continue;
      }
      frame_ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
      for (const auto& [name, ms] : timer.stageTimes()) stage_runs[name].push_back(ms);
      ++f;
      if (settings.on_frame) settings.on_frame(f, frames);
    }

    result.image = Image(width, height);
    rt_.queue().enqueueReadBuffer(image_.buffer, CL_TRUE, 0, pixels * 4, result.image.rgba.data());
    if (capture_depth_) {
      result.depth_complexity.resize(pixels);
      rt_.queue().enqueueReadBuffer(depth_map_.buffer, CL_TRUE, 0, pixels * 4,
                                    result.depth_complexity.data());
    }

    st.method = methodName(method_);
    st.device = rt_.info().label();
    st.width = width;
    st.height = height;
    st.triangles = triangle_count;
    st.triangles_read = triangle_count;  // single pass: setup reads each triangle once
    st.fragments = counters[ST_COUNTER_FRAGMENTS];
    st.max_depth_complexity = counters[ST_COUNTER_MAX_DEPTH];
    st.culled_degenerate = counters[ST_COUNTER_CULLED_DEGENERATE];
    st.culled_nonfinite = counters[ST_COUNTER_CULLED_NONFINITE];
    st.clipped = counters[ST_COUNTER_CLIPPED];
    st.kernel_launches = timer.launches();
    st.fragment_bytes = method_ == Method::Opaque ? visibility_.bytes : heads_.bytes + nodes_.bytes;
    st.device_bytes = clip_.bytes + triangle_colors_.bytes + tile_counts_.bytes + tile_offsets_.bytes +
                      tile_cursors_.bytes + counters_.bytes + image_.bytes + records_.bytes +
                      bins_.bytes + st.fragment_bytes;
    st.frame_ms = summarizeTimes(frame_ms);
    for (auto& [name, runs] : stage_runs) st.stage_ms[name] = summarizeTimes(runs).median;
    return result;
  }

  void enqueueFrame(LaunchTimer& timer, const WorldGeometry& geo, int width, int height,
                    uint32_t tiles_x, uint32_t tiles_y, uint32_t vertex_count,
                    uint32_t triangle_count) {
    const size_t pixels = size_t(width) * size_t(height);
    const uint32_t tile_count = tiles_x * tiles_y;
    const cl_uint overflow_cap = cl_uint(overflow_capacity_);
    const size_t record_slots = size_t(triangle_count) + overflow_capacity_;
    const cl_uint bin_cap = cl_uint(bin_capacity_);
    timer.fill("clear", counters_.buffer, 0u, counters_.bytes);
    timer.fill("clear", tile_counts_.buffer, 0u, size_t(tile_count) * 4);
    // Linked-list heads need no clear: each tile's owner stores all of its heads.
    if (method_ == Method::Opaque) timer.fill("clear", visibility_.buffer, 0xFFFFFFFFu, pixels * 8);

    setArgs(transform_, positions_.buffer, cl_uint(vertex_count), view_.buffer, clip_.buffer);
    timer.launch("transform", transform_, cl::NDRange(roundUp(vertex_count, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));
    setArgs(setup_, positions_.buffer, indices_.buffer, materials_.buffer, material_colors_.buffer,
            cl_uint(vertex_count), cl_uint(triangle_count), clip_.buffer, view_.buffer,
            triangle_colors_.buffer, records_.buffer, overflow_cap, counters_.buffer);
    timer.launch("setup", setup_, cl::NDRange(roundUp(triangle_count, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));
    setArgs(bin_count_, records_.buffer, cl_uint(triangle_count), overflow_cap, counters_.buffer,
            cl_uint(tiles_x), tile_counts_.buffer);
    timer.launch("bin", bin_count_, cl::NDRange(roundUp(record_slots, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));
    setArgs(bin_scan_, tile_counts_.buffer, cl_uint(tile_count), tile_offsets_.buffer,
            tile_cursors_.buffer, counters_.buffer);
    timer.launch("bin", bin_scan_, cl::NDRange(ST_SCAN_WG), cl::NDRange(ST_SCAN_WG));
    setArgs(bin_fill_, records_.buffer, cl_uint(triangle_count), overflow_cap, counters_.buffer,
            cl_uint(tiles_x), tile_cursors_.buffer, bins_.buffer, bin_cap);
    timer.launch("bin", bin_fill_, cl::NDRange(roundUp(record_slots, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));

    const cl::NDRange tiles_global(size_t(tiles_x) * ST_TILE_SIZE, size_t(tiles_y) * ST_TILE_SIZE);
    const cl::NDRange tile_local(ST_TILE_SIZE, ST_TILE_SIZE);
    if (method_ == Method::Opaque) {
      setArgs(raster_, records_.buffer, bins_.buffer, tile_offsets_.buffer, cl_uint(tiles_x), bin_cap,
              cl_int(width), cl_int(height), visibility_.buffer, counters_.buffer);
      timer.launch("raster", raster_, tiles_global, tile_local);
      setArgs(resolve_, visibility_.buffer, triangle_colors_.buffer, view_.buffer, image_.buffer);
      timer.launch("shade", resolve_, tiles_global, tile_local);
    } else {
      setArgs(raster_, records_.buffer, bins_.buffer, tile_offsets_.buffer, cl_uint(tiles_x), bin_cap,
              cl_int(width), cl_int(height), heads_.buffer, nodes_.buffer, cl_ulong(node_capacity_),
              counters_.buffer);
      timer.launch("raster", raster_, tiles_global, tile_local);
      setArgs(resolve_, heads_.buffer, nodes_.buffer, triangle_colors_.buffer, view_.buffer,
              image_.buffer, counters_.buffer, depth_map_.buffer, cl_int(capture_depth_ ? 1 : 0));
      timer.launch("resolve", resolve_, tiles_global, tile_local);
    }
  }

  Method method_;
  ClRuntime& rt_;
  cl::Kernel transform_, setup_, bin_count_, bin_scan_, bin_fill_, raster_, resolve_;
  DeviceBuffer positions_, indices_, materials_, material_colors_, view_;
  DeviceBuffer clip_, triangle_colors_, tile_counts_, tile_offsets_, tile_cursors_, counters_,
      image_, records_, bins_, visibility_, heads_, nodes_, depth_map_;
  bool capture_depth_ = false;
  size_t overflow_capacity_ = 0, bin_capacity_ = 0, node_capacity_ = 0;
};

}  // namespace

std::unique_ptr<Renderer> makeClRenderer(Method method, const DeviceOptions& device) {
  return std::make_unique<ClRenderer>(method, device);
}

}  // namespace strata
