// ID picking (engine/features/picking.h): an ID-buffer frame through the shared OpenCL pipeline,
// then gather kernels (kernels/pick.cl) that read back only the asked pixels.
#include "engine/features/picking.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "engine/frontend/cl_pipeline.h"
#include "preprocess/core/enum_table.h"

namespace strata {

namespace {

// The frame of a pick: the opaque method's visibility raster (the nearest fragment per pixel)
// and, with all layers, the ppll method's linked-list build, both over one front end. Nothing is
// shaded or resolved: the buffers stay on the device for the gather kernels.
class PickMethod final : public ClMethod {
 public:
  bool all_layers = false;
  DeviceBuffer visibility, heads, nodes;

  void init(ClPipeline& p) override {
    raster_.create(p, "raster_visibility");
    build_.create(p, "ppll_build");
  }

  void prepare(ClPipeline& p, const FrameSettings&) override {
    p.ensure(visibility, p.pixels() * 8, "picking visibility buffer");
    if (all_layers) {
      p.ensure(heads, p.pixels() * 4, "picking linked-list heads");
      if (node_capacity_ == 0) node_capacity_ = 2 * p.pixels() + 1024;
      p.ensure(nodes, node_capacity_ * sizeof(StPpllNode), "picking linked-list nodes");
    }
  }

  void enqueue(ClPipeline& p) override {
    p.timer().fill("clear", visibility.buffer, 0xFFFFFFFFu, visibility.bytes);
    setArgs(raster_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
            visibility.buffer, p.counters().buffer, p.depthComplexity().buffer, cl_int(0));
    raster_.launch(p, "raster");
    if (!all_layers) return;
    setArgs(build_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
            cl_uint(p.tilesX()), p.binCapacity(), cl_int(p.width()), cl_int(p.height()),
            heads.buffer, nodes.buffer, cl_ulong(node_capacity_), p.counters().buffer);
    build_.launch(p, "layers");
  }

  bool growIfOverflowed(ClPipeline& p, const uint64_t* counters) override {
    if (!all_layers) return false;
    if (!growCapacity(node_capacity_, counters[ST_COUNTER_NODES], 1)) return false;
    p.ensure(nodes, node_capacity_ * sizeof(StPpllNode), "picking linked-list nodes");
    return true;
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.fragment_bytes = deviceBytes();
  }

  uint64_t deviceBytes() const override { return visibility.bytes + heads.bytes + nodes.bytes; }

 private:
  TileKernel raster_, build_;
  size_t node_capacity_ = 0;
};

constexpr uint64_t kEmpty = ST_VISIBILITY_EMPTY;

float wordDepth(uint64_t word) {
  const uint32_t bits = uint32_t(word >> 32);
  float d;
  std::memcpy(&d, &bits, sizeof(d));
  return d;
}

}  // namespace

const char* pickStatusName(PickStatus s) {
  static constexpr const char* kNames[] = {"hit", "background", "outside image"};
  return enumLookup(s, kNames, "unknown");
}

ObjectNames objectNames(const Scene& scene) {
  ObjectNames names;
  for (const Instance& inst : scene.instances) {
    std::string name = inst.name;
    if (name.empty() && inst.mesh < scene.meshes.size()) name = scene.meshes[inst.mesh].name;
    if (name.empty()) name = "object " + std::to_string(inst.object_id);
    names.emplace(inst.object_id, std::move(name));  // the first instance of an id names it
  }
  return names;
}

void validatePickRect(const PickRect& r, int width, int height) {
  const std::string text = std::to_string(r.x0) + "," + std::to_string(r.y0) + "," +
                           std::to_string(r.x1) + "," + std::to_string(r.y1);
  if (r.x1 < r.x0 || r.y1 < r.y0)
    throw Error("rectangle " + text + ": X1 must be >= X0 and Y1 >= Y0 (corners are inclusive)");
  if (r.x0 < 0 || r.y0 < 0 || r.x1 >= width || r.y1 >= height)
    throw Error("rectangle " + text + " is not inside the " + std::to_string(width) + "x" +
                std::to_string(height) + " image (pixels 0.." + std::to_string(width - 1) +
                ", 0.." + std::to_string(height - 1) + ")");
}

struct IdPicker::Impl {
  PickMethod* method = nullptr;  // owned by the pipeline
  std::unique_ptr<ClPipeline> pipeline;
  cl::Kernel front, layers, mark, compact;
  DeviceBuffer pixels, words, first, counts, fragments, used;
  DeviceBuffer triangle_run, run_seen, runs, found;
  size_t fragment_capacity = 0;

  // The last update().
  const WorldGeometry* geometry = nullptr;
  FrameSettings settings;
  bool have_frame = false, all_layers = false;
  bool runs_ready = false;
  std::vector<uint32_t> run_object;  // object of each run of equal triangle_object

  explicit Impl(const DeviceOptions& device) {
    auto m = std::make_unique<PickMethod>();
    method = m.get();
    pipeline = std::make_unique<ClPipeline>(Method::Opaque, std::move(m), device);
    front = pipeline->kernel("pick_front");
    layers = pipeline->kernel("pick_layers");
    mark = pipeline->kernel("pick_rect_mark");
    compact = pipeline->kernel("pick_rect_compact");
  }

  cl::CommandQueue& queue() { return pipeline->runtime().queue(); }

  void requireFrame() const {
    if (!have_frame) throw Error("picking: no frame yet (call IdPicker::update first)");
  }

  uint32_t objectOf(uint32_t triangle) const {
    return triangle < geometry->triangle_object.size() ? geometry->triangle_object[triangle] : 0u;
  }

  PickFragment fragment(uint32_t triangle, float depth, const glm::ivec2& pixel,
                        const ObjectNames* names) const {
    const WorldGeometry& g = *geometry;
    PickFragment f;
    f.triangle = triangle;
    f.object = objectOf(triangle);
    if (names) {
      const auto it = names->find(f.object);
      if (it != names->end()) f.name = it->second;
    }
    f.depth = depth;
    glm::vec3 org, dir;
    settings.camera.pixelRay(pixel.x, pixel.y, settings.width, settings.height, org, dir);
    const glm::vec3 fwd = settings.camera.forward();
    const float along = glm::dot(dir, fwd);
    const float t =
        along > 0.0f ? (depth - glm::dot(org - settings.camera.eye, fwd)) / along : 0.0f;
    f.position = org + t * dir;
    if (size_t(triangle) * 3 + 2 < g.indices.size()) {
      const glm::dvec3 a(g.positions[g.indices[3 * size_t(triangle)]]);
      const glm::dvec3 b(g.positions[g.indices[3 * size_t(triangle) + 1]]);
      const glm::dvec3 c(g.positions[g.indices[3 * size_t(triangle) + 2]]);
      const glm::dvec3 n = glm::cross(b - a, c - a);
      const double len = glm::length(n);
      if (len > 0.0 && std::isfinite(len)) f.normal = glm::vec3(n / len);
      f.front_facing = glm::dot(n, glm::dvec3(dir)) < 0.0;
    }
    if (triangle < g.triangle_material.size() &&
        g.triangle_material[triangle] < g.material_colors.size())
      f.opacity = g.material_colors[g.triangle_material[triangle]].a;
    return f;
  }

  void update(const WorldGeometry& g, const FrameSettings& s, bool layers_too) {
    FrameSettings frame = s;
    frame.frames = 1;
    frame.capture_depth_complexity = false;
    frame.on_frame = nullptr;
    method->all_layers = layers_too;
    have_frame = false;
    pipeline->render(g, frame);
    geometry = &g;
    settings = frame;
    all_layers = layers_too;
    have_frame = true;
    runs_ready = false;
  }

  PickResult pick(const std::vector<glm::ivec2>& asked, const ObjectNames* names) {
    requireFrame();
    PickResult result;
    result.all_layers = all_layers;
    const size_t n = asked.size();
    result.pixels.resize(n);
    if (n == 0) return result;
    const int width = settings.width, height = settings.height;
    static_assert(sizeof(glm::ivec2) == sizeof(cl_int2), "pixels are uploaded as int2");
    pipeline->ensure(pixels, n * sizeof(cl_int2), "picked pixels");
    pipeline->ensure(words, n * 8, "picked visibility words");
    // Blocking: an error before the final finish must not leave the device reading `asked`.
    queue().enqueueWriteBuffer(pixels.buffer, CL_TRUE, 0, n * sizeof(cl_int2), asked.data());
    const cl::NDRange global(roundUp(n, ST_LINEAR_WG)), local(ST_LINEAR_WG);
    setArgs(front, method->visibility.buffer, cl_int(width), cl_int(height), pixels.buffer,
            cl_uint(n), words.buffer);
    queue().enqueueNDRangeKernel(front, cl::NullRange, global, local);
    std::vector<uint64_t> word(n);
    std::vector<uint64_t> starts, layer_words;
    std::vector<uint32_t> layer_counts;
    if (all_layers) {
      pipeline->ensure(first, n * 8, "picked layer offsets");
      pipeline->ensure(counts, n * 4, "picked layer counts");
      pipeline->ensure(used, 8, "picked layer total");
      if (fragment_capacity == 0) fragment_capacity = std::max<size_t>(4 * n, 1024);
      uint64_t total = 0;
      for (;;) {
        pipeline->ensure(fragments, fragment_capacity * 8, "picked layers");
        pipeline->runtime().fill(used.buffer, 0, 8, "clearing the picked-layer count");
        setArgs(layers, method->heads.buffer, method->nodes.buffer, cl_int(width), cl_int(height),
                pixels.buffer, cl_uint(n), first.buffer, counts.buffer, fragments.buffer,
                cl_ulong(fragment_capacity), used.buffer);
        queue().enqueueNDRangeKernel(layers, cl::NullRange, global, local);
        queue().enqueueReadBuffer(used.buffer, CL_TRUE, 0, 8, &total);
        if (total <= fragment_capacity) break;
        fragment_capacity = total + total / 16;  // grow to what the kernel asked for and re-run
      }
      starts.resize(n);
      layer_counts.resize(n);
      layer_words.resize(total);
      queue().enqueueReadBuffer(first.buffer, CL_FALSE, 0, n * 8, starts.data());
      queue().enqueueReadBuffer(counts.buffer, CL_FALSE, 0, n * 4, layer_counts.data());
      if (total)
        queue().enqueueReadBuffer(fragments.buffer, CL_FALSE, 0, total * 8, layer_words.data());
    }
    queue().enqueueReadBuffer(words.buffer, CL_TRUE, 0, n * 8, word.data());
    queue().finish();

    for (size_t i = 0; i < n; ++i) {
      PickedPixel& out = result.pixels[i];
      const glm::ivec2 p = asked[i];
      out.pixel = p;
      if (p.x < 0 || p.y < 0 || p.x >= width || p.y >= height) {
        out.status = PickStatus::OutsideImage;
        continue;
      }
      if (word[i] == kEmpty) {
        out.status = PickStatus::Background;
        continue;
      }
      out.status = PickStatus::Hit;
      out.front = fragment(uint32_t(word[i]), wordDepth(word[i]), p, names);
      if (!all_layers) continue;
      float transmittance = 1.0f;
      out.layers.reserve(layer_counts[i]);
      for (uint32_t k = 0; k < layer_counts[i]; ++k) {
        const uint64_t w = layer_words[size_t(starts[i]) + k];
        PickFragment f = fragment(uint32_t(w), wordDepth(w), p, names);
        f.transmittance = transmittance;
        transmittance *= 1.0f - f.opacity;
        out.layers.push_back(std::move(f));
      }
    }
    return result;
  }

  // Runs of consecutive triangles of one object (instances are contiguous): the rectangle query
  // marks runs, so its flags do not depend on how large the object ids are.
  void prepareRuns() {
    if (runs_ready) return;
    const uint32_t triangles = geometry->triangleCount();
    std::vector<uint32_t> run_of(std::max<uint32_t>(triangles, 1), 0u);
    run_object.clear();
    for (uint32_t t = 0; t < triangles; ++t) {
      const uint32_t object = objectOf(t);
      if (run_object.empty() || run_object.back() != object) run_object.push_back(object);
      run_of[t] = uint32_t(run_object.size() - 1);
    }
    pipeline->ensure(triangle_run, run_of.size() * 4, "triangle runs");
    queue().enqueueWriteBuffer(triangle_run.buffer, CL_TRUE, 0, run_of.size() * 4, run_of.data());
    runs_ready = true;
  }

  std::vector<uint32_t> objectsInRect(const PickRect& r) {
    requireFrame();
    validatePickRect(r, settings.width, settings.height);
    prepareRuns();
    const size_t run_count = std::max<size_t>(run_object.size(), 1);
    pipeline->ensure(run_seen, run_count * 4, "rectangle run flags");
    pipeline->ensure(runs, run_count * 4, "rectangle runs");
    pipeline->ensure(found, 4, "rectangle run count");
    pipeline->runtime().fill(run_seen.buffer, 0, run_count * 4, "clearing rectangle run flags");
    pipeline->runtime().fill(found.buffer, 0, 4, "clearing the rectangle run count");
    const int w = r.x1 - r.x0 + 1, h = r.y1 - r.y0 + 1;
    setArgs(mark, method->visibility.buffer, cl_int(settings.width), cl_int(r.x0), cl_int(r.y0),
            cl_int(w), cl_int(h), triangle_run.buffer, run_seen.buffer);
    queue().enqueueNDRangeKernel(
        mark, cl::NullRange,
        cl::NDRange(roundUp(size_t(w), ST_TILE_SIZE), roundUp(size_t(h), ST_TILE_SIZE)),
        cl::NDRange(ST_TILE_SIZE, ST_TILE_SIZE));
    setArgs(compact, run_seen.buffer, cl_uint(run_object.size()), runs.buffer, found.buffer);
    queue().enqueueNDRangeKernel(compact, cl::NullRange,
                                 cl::NDRange(roundUp(run_count, ST_LINEAR_WG)),
                                 cl::NDRange(ST_LINEAR_WG));
    uint32_t count = 0;
    queue().enqueueReadBuffer(found.buffer, CL_TRUE, 0, 4, &count);
    std::vector<uint32_t> marked(count);
    if (count) queue().enqueueReadBuffer(runs.buffer, CL_TRUE, 0, size_t(count) * 4, marked.data());
    std::vector<uint32_t> objects;
    objects.reserve(count);
    for (uint32_t run : marked) objects.push_back(run_object[run]);
    std::sort(objects.begin(), objects.end());
    objects.erase(std::unique(objects.begin(), objects.end()), objects.end());
    return objects;
  }
};

IdPicker::IdPicker(const DeviceOptions& device) : impl_(std::make_unique<Impl>(device)) {}
IdPicker::~IdPicker() = default;

void IdPicker::update(const WorldGeometry& geometry, const FrameSettings& settings,
                      bool all_layers) {
  impl_->update(geometry, settings, all_layers);
}

PickResult IdPicker::pick(const std::vector<glm::ivec2>& pixels, const ObjectNames* names) {
  try {
    return impl_->pick(pixels, names);
  } catch (const cl::Error& e) {
    rethrowClError(e, "picking pixels");
  }
}

std::vector<uint32_t> IdPicker::objectsInRect(const PickRect& rect) {
  try {
    return impl_->objectsInRect(rect);
  } catch (const cl::Error& e) {
    rethrowClError(e, "picking the objects of a rectangle");
  }
}

PickResult IdPicker::pick(const WorldGeometry& geometry, const FrameSettings& settings,
                          const std::vector<glm::ivec2>& pixels, bool all_layers,
                          const ObjectNames* names) {
  update(geometry, settings, all_layers);
  return pick(pixels, names);
}

std::string IdPicker::device() const { return impl_->pipeline->runtime().info().label(); }

}  // namespace strata
