// The public API (include/strata/strata.h) over the engine: devices, validated geometry,
// renderers by method name, picking.
#include <array>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <new>

#include "engine/features/picking.h"
#include "engine/renderer.h"
#include "engine/report/stats_json.h"
#include "host/cl_runtime.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/convex_cells.h"
#include "preprocess/image_io.h"
#include "preprocess/validate.h"
#include "strata/strata.h"

namespace strata {

// ---- methods, devices ------------------------------------------------------------------------

namespace {

// Runs `work`; a host allocation that fails inside it becomes an OutOfMemory naming `subject`
// (the std::bad_alloc itself names nothing, and would reach a Python user as a bare MemoryError).
template <typename Work>
auto namingMemory(const std::string& subject, Work&& work) -> decltype(work()) {
  try {
    return work();
  } catch (const std::bad_alloc&) {
    throw OutOfMemory(subject +
                      ": out of memory (the scene or the image needs more memory than "
                      "there is)");
  }
}

MethodInfo publicInfo(const MethodTraits& t) {
  return MethodInfo{t.name,   t.summary, t.exact,
                    t.opencl, t.takes_k, t.renders(Effect::Translucency)};
}

}  // namespace

std::vector<MethodInfo> methods() {
  std::vector<MethodInfo> out;
  for (const MethodTraits& t : methodRegistry()) out.push_back(publicInfo(t));
  return out;
}

struct Device::State {
  std::shared_ptr<ClRuntime> runtime;  // keeps the context and built program while in use
  std::string spec;                    // the index, for the renderers made on it
  std::string atomics;                 // "64" or "32": the path the runtime was built for
  DeviceOptions options() const { return DeviceOptions{spec, atomics}; }
};

std::vector<DeviceDescription> Device::list() {
  std::vector<DeviceDescription> out;
  for (const DeviceInfo& d : listDevices())
    out.push_back({d.index, d.name, d.platform, d.driver_version, d.is_gpu});
  return out;
}

Device Device::open(const std::string& spec, const std::string& atomics) {
  Device d;
  auto state = std::make_shared<State>();
  state->runtime = ClRuntime::acquire(spec, atomics);
  state->spec = std::to_string(state->runtime->info().index);
  state->atomics = state->runtime->int64Atomics() ? "64" : "32";
  d.state = std::move(state);
  return d;
}

std::string Device::label() const {
  if (!state) throw Error("strata::Device: not opened (use Device::open)");
  return state->runtime->info().label();
}

bool Device::int64Atomics() const {
  if (!state) throw Error("strata::Device: not opened (use Device::open)");
  return state->runtime->int64Atomics();
}

// ---- geometry -------------------------------------------------------------------------------

struct Geometry::State {
  Scene scene;
  WorldGeometry world;
  BoundingSphere sphere;    // the scene's, once (every view is framed by it)
  uint64_t generation = 0;  // unique per geometry made: renderers keep what they prepared for it
};

namespace {

Geometry makeGeometry(Scene scene, float alpha) {
  if (alpha >= 0.0f && !(alpha <= 1.0f)) throw Error("geometry: alpha must be in 0..1");
  auto state = std::make_shared<Geometry::State>();
  state->world = WorldGeometry::fromScene(scene, alpha);
  validateWorldGeometry(state->world);
  state->sphere = scene.boundingSphere();
  state->scene = std::move(scene);
  static std::atomic<uint64_t> next_generation{1};
  state->generation = next_generation++;
  Geometry g;
  g.state = std::move(state);
  return g;
}

const Geometry::State& stateOf(const Geometry& g, const char* who) {
  if (!g.state)
    throw Error(std::string(who) + ": the geometry is empty (use Geometry::load or fromArrays)");
  return *g.state;
}

}  // namespace

Geometry Geometry::load(const std::string& path, float alpha) {
  return namingMemory(path, [&] { return makeGeometry(loadScene(path), alpha); });
}

namespace {

Geometry geometryFromArrays(const float* positions, size_t vertex_count, const uint32_t* indices,
                            size_t triangle_count, const float* rgba, float alpha) {
  if (!positions || !indices) throw Error("geometry arrays: positions and indices are required");
  if (vertex_count == 0 || triangle_count == 0)
    throw Error("geometry arrays: no vertices or no triangles");
  if (vertex_count > UINT32_MAX / 4 || triangle_count > UINT32_MAX / 4)
    throw Error("geometry arrays: more than " + std::to_string(UINT32_MAX / 4) +
                " vertices or triangles");
  for (size_t i = 0; i < vertex_count * 3; ++i)
    if (!std::isfinite(positions[i]))
      throw Error("geometry arrays: position " + std::to_string(i / 3) + " is not finite");
  for (size_t i = 0; i < triangle_count * 3; ++i)
    if (indices[i] >= vertex_count)
      throw Error("geometry arrays: index " + std::to_string(indices[i]) + " of triangle " +
                  std::to_string(i / 3) + " is past the " + std::to_string(vertex_count) +
                  " vertices");
  if (rgba)
    for (size_t i = 0; i < triangle_count * 4; ++i)
      if (!(rgba[i] >= 0.0f && rgba[i] <= 1.0f))
        throw Error("geometry arrays: colour of triangle " + std::to_string(i / 4) +
                    " is not in 0..1");

  Scene scene;
  scene.source = "arrays";
  std::vector<glm::vec3> all(vertex_count);
  for (size_t v = 0; v < vertex_count; ++v)
    all[v] = {positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]};
  if (!rgba) {
    Mesh mesh;
    mesh.name = "arrays";
    mesh.positions = std::move(all);
    mesh.indices.assign(indices, indices + triangle_count * 3);
    scene.meshes.push_back(std::move(mesh));
    scene.materials.push_back(Material{});
  } else {
    // One material and one mesh (holding only its own vertices) per distinct colour.
    std::map<std::array<float, 4>, uint32_t> material_of;
    std::vector<std::vector<uint32_t>> remap;
    for (size_t t = 0; t < triangle_count; ++t) {
      const std::array<float, 4> c{rgba[4 * t], rgba[4 * t + 1], rgba[4 * t + 2], rgba[4 * t + 3]};
      auto [it, added] = material_of.emplace(c, uint32_t(scene.materials.size()));
      if (added) {
        Material m;
        m.name = "colour" + std::to_string(it->second);
        m.color = glm::vec4(c[0], c[1], c[2], 1.0f);
        m.opacity = c[3];
        scene.materials.push_back(m);
        Mesh mesh;
        mesh.name = m.name;
        mesh.material = it->second;
        scene.meshes.push_back(std::move(mesh));
        remap.emplace_back(vertex_count, UINT32_MAX);
      }
      Mesh& mesh = scene.meshes[it->second];
      std::vector<uint32_t>& map = remap[it->second];
      for (int k = 0; k < 3; ++k) {
        const uint32_t v = indices[3 * t + k];
        if (map[v] == UINT32_MAX) {
          map[v] = uint32_t(mesh.positions.size());
          mesh.positions.push_back(all[v]);
        }
        mesh.indices.push_back(map[v]);
      }
    }
  }
  for (uint32_t m = 0; m < scene.meshes.size(); ++m)
    scene.instances.push_back({m, glm::mat4(1.0f), m, scene.meshes[m].name});
  validateScene(scene);  // drops zero-area triangles as the file loaders do, and counts them
  return makeGeometry(std::move(scene), alpha);
}

}  // namespace

Geometry Geometry::fromArrays(const float* positions, size_t vertex_count, const uint32_t* indices,
                              size_t triangle_count, const float* rgba, float alpha) {
  return namingMemory("geometry arrays", [&] {
    return geometryFromArrays(positions, vertex_count, indices, triangle_count, rgba, alpha);
  });
}

Geometry Geometry::fromFlatArrays(const float* positions, size_t position_floats,
                                  const uint32_t* indices, size_t index_count, const float* rgba,
                                  size_t rgba_floats, float alpha) {
  if (position_floats % 3 != 0)
    throw Error("geometry arrays: " + std::to_string(position_floats) +
                " position values are not whole x, y, z vertices");
  if (index_count % 3 != 0)
    throw Error("geometry arrays: " + std::to_string(index_count) +
                " indices are not whole triangles of three");
  if (rgba_floats != 0 && rgba_floats != index_count / 3 * 4)
    throw Error("geometry arrays: " + std::to_string(rgba_floats) + " colour values for " +
                std::to_string(index_count / 3) + " triangles (none, or four per triangle)");
  return fromArrays(positions, position_floats / 3, indices, index_count / 3,
                    rgba_floats ? rgba : nullptr, alpha);
}

uint64_t Geometry::triangleCount() const {
  const WorldGeometry& w = stateOf(*this, "Geometry").world;
  return w.out_of_core ? w.out_of_core->triangles : w.triangleCount();
}
uint64_t Geometry::vertexCount() const { return stateOf(*this, "Geometry").world.positions.size(); }
std::string Geometry::source() const { return stateOf(*this, "Geometry").scene.source; }

View Geometry::naturalView(int width, int height) const {
  const Scene& scene = stateOf(*this, "Geometry").scene;
  const OrbitView orbit = scene.default_view.value_or(OrbitView{});
  View v;
  v.width = width;
  v.height = height;
  v.azimuth_deg = orbit.azimuth_deg;
  v.elevation_deg = orbit.elevation_deg;
  v.distance = orbit.distance_radii.value_or(0.0f);
  v.ortho_height = orbit.ortho_height.value_or(0.0f);
  v.orthographic =
      scene.default_projection.value_or(Projection::Perspective) == Projection::Orthographic;
  return v;
}

View View::lookAt(const float eye[3], const float target[3], const float up[3], int width,
                  int height) {
  View v;
  v.look_at = true;
  v.width = width;
  v.height = height;
  for (int i = 0; i < 3; ++i) {
    v.eye[i] = eye[i];
    v.target[i] = target[i];
    v.up[i] = up[i];
  }
  return v;
}

void Geometry::boundingSphere(float centre[3], float* radius) const {
  const BoundingSphere s = stateOf(*this, "Geometry").sphere;
  centre[0] = s.center.x;
  centre[1] = s.center.y;
  centre[2] = s.center.z;
  *radius = s.radius;
}

// ---- rendering ------------------------------------------------------------------------------

namespace {

FrameSettings frameSettings(const Geometry::State& g, const View& v, const RenderOptions& o) {
  FrameSettings s;
  s.width = v.width;
  s.height = v.height;
  if (!(v.fov_deg > 1.0f && v.fov_deg < 179.0f))
    throw Error("view: fov must be between 1 and 179 degrees");
  const Projection projection = v.orthographic ? Projection::Orthographic : Projection::Perspective;
  const BoundingSphere sphere = g.sphere;
  if (!(v.ortho_height >= 0.0f && std::isfinite(v.ortho_height)))
    throw Error("view: ortho_height must be >= 0 world units (0: the bounding sphere's)");
  if (v.look_at) {
    for (int i = 0; i < 3; ++i)
      if (!std::isfinite(v.eye[i]) || !std::isfinite(v.target[i]) || !std::isfinite(v.up[i]))
        throw Error("view: eye, target and up must be finite");
    const glm::vec3 eye{v.eye[0], v.eye[1], v.eye[2]},
        target{v.target[0], v.target[1], v.target[2]};
    const glm::vec3 up{v.up[0], v.up[1], v.up[2]};
    if (!(glm::length(target - eye) > 0.0f)) throw Error("view: eye and target coincide");
    if (!(glm::length(glm::cross(target - eye, up)) > 0.0f))
      throw Error("view: up is zero or along the line of sight");
    s.camera = Camera::lookAt(eye, target, up);
    s.camera.projection = projection;
    s.camera.fov_y_deg = v.fov_deg;
    s.camera.ortho_height = v.ortho_height > 0.0f ? v.ortho_height : 2.0f * sphere.radius;
  } else {
    if (!std::isfinite(v.azimuth_deg) || !std::isfinite(v.elevation_deg))
      throw Error("view: azimuth and elevation must be finite numbers of degrees");
    OrbitView orbit;
    orbit.azimuth_deg = v.azimuth_deg;
    orbit.elevation_deg = v.elevation_deg;
    if (v.distance < 0.0f || !std::isfinite(v.distance))
      throw Error("view: distance must be >= 0 (0: auto-frame)");
    if (v.distance > 0.0f) orbit.distance_radii = v.distance;
    if (v.ortho_height > 0.0f) orbit.ortho_height = v.ortho_height;
    s.camera = Camera::orbit(sphere, orbit, projection, v.fov_deg);
  }
  s.frames = o.frames;
  s.orbit_deg = o.orbit_deg;
  s.k = o.k;
  s.effect = o.effect;
  s.sigma = o.sigma >= 0.0f ? o.sigma : 1.0f / std::max(sphere.radius, 1e-6f);
  s.background.checker = o.checker_background;
  s.background.color = {o.background_rgb[0], o.background_rgb[1], o.background_rgb[2]};
  s.capture_depth_complexity = o.capture_depth_complexity;
  s.batch = o.batch;
  s.sort = o.sort;
  s.atlas = o.atlas;
  s.decompose = optionName(o.decompose);
  s.cell_cache_dir = o.cell_cache_dir;
  static_cast<MethodOptions&>(s) = o;
  s.tile_kernels = optionName(o.tile_kernels);
  s.memory_budget = o.memory_budget;
  return s;
}

}  // namespace

struct Renderer::State {
  // Serialises the frames: the method's buffers and kernels are one frame's at a time.
  std::mutex render_mutex;
  // Guards options and geometry, held only to change or copy them, so setGeometry never waits
  // for a frame (which keeps the geometry it began with).
  std::mutex settings_mutex;
  Device device;
  const MethodTraits* traits = nullptr;
  MethodInfo info;
  RenderOptions options;
  Geometry geometry;
  std::unique_ptr<MethodRenderer> renderer;
};

Renderer::Renderer(const Device& device, const std::string& method, const RenderOptions& options)
    : state_(std::make_unique<State>()) {
  if (!device.state) throw Error("strata::Renderer: the device is not opened (use Device::open)");
  state_->device = device;
  state_->traits = &methodInfo(parseMethod(method));
  state_->info = publicInfo(*state_->traits);
  state_->options = options;
  state_->renderer = makeRenderer(state_->traits->method, device.state->options());
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

void Renderer::setGeometry(const Geometry& geometry) {
  stateOf(geometry, "Renderer::setGeometry");
  std::lock_guard<std::mutex> lock(state_->settings_mutex);
  state_->geometry = geometry;
}

void Renderer::setOptions(const RenderOptions& options) {
  std::lock_guard<std::mutex> lock(state_->settings_mutex);
  state_->options = options;
}

const MethodInfo& Renderer::method() const { return state_->info; }

Frame Renderer::render(const View& view) {
  std::lock_guard<std::mutex> frame_lock(state_->render_mutex);
  Geometry geometry;
  RenderOptions options;
  {
    std::lock_guard<std::mutex> lock(state_->settings_mutex);
    geometry = state_->geometry;  // alive until the frame ends, whatever setGeometry does
    options = state_->options;
  }
  const Geometry::State& g = stateOf(geometry, "Renderer::render (call setGeometry first)");
  FrameSettings settings = frameSettings(g, view, options);
  settings.geometry_generation = g.generation;
  RenderResult r =
      namingMemory(g.scene.source + " (" + state_->info.name + ", " + std::to_string(view.width) +
                       "x" + std::to_string(view.height) + ")",
                   [&] { return state_->renderer->render(g.world, settings); });
  Frame f;
  f.image = std::move(r.image);
  f.depth_complexity = std::move(r.depth_complexity);
  f.frame_ms = r.stats.frame_ms.median;
  f.frame_ms_min = r.stats.frame_ms.min;
  f.frame_ms_max = r.stats.frame_ms.max;
  f.triangles = r.stats.triangles;
  f.triangles_read = r.stats.triangles_read;
  f.fragments = r.stats.fragments;
  f.fragments_lost = r.stats.fragments_lost;
  f.max_depth_complexity = r.stats.max_depth_complexity;
  f.device_bytes = r.stats.device_bytes;
  f.kernel_launches = r.stats.kernel_launches;
  f.stage_ms.assign(r.stats.stage_ms.begin(), r.stats.stage_ms.end());
  f.stats_json = statsToJson(r.stats, g.scene.source).dump();
  return f;
}

// ---- picking --------------------------------------------------------------------------------

struct Picker::State {
  std::mutex pick_mutex, settings_mutex;  // as Renderer's render and settings mutexes
  Device device;
  Geometry geometry;
  std::shared_ptr<const ObjectNames> names;  // the geometry's
  std::unique_ptr<IdPicker> picker;

  // The geometry and names a query runs with: copied under the settings mutex, so setGeometry
  // never waits for a query, which keeps what it began with.
  struct Snapshot {
    Geometry geometry;
    std::shared_ptr<const ObjectNames> names;
  };
  Snapshot snapshot() {
    std::lock_guard<std::mutex> lock(settings_mutex);
    return {geometry, names};
  }
};

Picker::Picker(const Device& device) : state_(std::make_unique<State>()) {
  if (!device.state) throw Error("strata::Picker: the device is not opened (use Device::open)");
  state_->device = device;
  state_->picker = std::make_unique<IdPicker>(device.state->options());
}

Picker::~Picker() = default;
Picker::Picker(Picker&&) noexcept = default;
Picker& Picker::operator=(Picker&&) noexcept = default;

void Picker::setGeometry(const Geometry& geometry) {
  auto names = std::make_shared<const ObjectNames>(
      objectNames(stateOf(geometry, "Picker::setGeometry").scene));
  std::lock_guard<std::mutex> lock(state_->settings_mutex);
  state_->names = std::move(names);
  state_->geometry = geometry;
}

namespace {

PickLayer publicLayer(const PickFragment& f) {
  PickLayer l;
  l.object = f.object;
  l.triangle = f.triangle;
  l.name = f.name;
  l.depth = f.depth;
  for (int i = 0; i < 3; ++i) {
    l.position[i] = f.position[i];
    l.normal[i] = f.normal[i];
  }
  l.front_facing = f.front_facing;
  l.opacity = f.opacity;
  l.transmittance = f.transmittance;
  return l;
}

}  // namespace

std::vector<PickHit> Picker::pick(const View& view, const std::vector<std::pair<int, int>>& pixels,
                                  bool all_layers) {
  std::lock_guard<std::mutex> pick_lock(state_->pick_mutex);
  const Picker::State::Snapshot snap = state_->snapshot();
  const std::shared_ptr<const ObjectNames>& names = snap.names;
  const Geometry::State& g = stateOf(snap.geometry, "Picker::pick (call setGeometry first)");
  const FrameSettings settings = frameSettings(g, view, RenderOptions{});
  std::vector<glm::ivec2> at;
  for (const auto& [x, y] : pixels) at.emplace_back(x, y);
  const PickResult r = namingMemory(g.scene.source + " (picking)", [&] {
    return state_->picker->pick(g.world, settings, at, all_layers, names.get());
  });
  std::vector<PickHit> out;
  for (const PickedPixel& p : r.pixels) {
    PickHit h;
    h.hit = p.status == PickStatus::Hit;
    if (h.hit) static_cast<PickLayer&>(h) = publicLayer(p.front);
    for (const PickFragment& f : p.layers) h.layers.push_back(publicLayer(f));
    out.push_back(std::move(h));
  }
  return out;
}

std::vector<PickedObject> Picker::objectsInRect(const View& view, int x0, int y0, int x1, int y1) {
  std::lock_guard<std::mutex> pick_lock(state_->pick_mutex);
  const Picker::State::Snapshot snap = state_->snapshot();
  const std::shared_ptr<const ObjectNames>& names = snap.names;
  const Geometry::State& g =
      stateOf(snap.geometry, "Picker::objectsInRect (call setGeometry first)");
  const FrameSettings settings = frameSettings(g, view, RenderOptions{});
  const PickRect rect{x0, y0, x1, y1};
  validatePickRect(rect, settings.width, settings.height);
  const std::vector<uint32_t> ids = namingMemory(g.scene.source + " (picking)", [&] {
    state_->picker->update(g.world, settings, false);
    return state_->picker->objectsInRect(rect);
  });
  std::vector<PickedObject> out;
  for (uint32_t id : ids) {
    PickedObject o;
    o.object = id;
    if (names) {
      auto it = names->find(id);
      if (it != names->end()) o.name = it->second;
    }
    out.push_back(std::move(o));
  }
  return out;
}

void saveImage(const std::string& path, const Image& image) { writeImage(image, path); }

}  // namespace strata
