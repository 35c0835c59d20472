#include "engine/reference/embree_reference.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstring>
#include <exception>
#include <limits>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

#include <embree3/rtcore.h>

#include "engine/reference/embree_support.h"
#include "engine/frontend/texture_shading.h"
#include "engine/frontend/view_constants.h"
#include "kernels/strata_shared.h"

namespace strata {

namespace {

using namespace embree_support;
using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Pixels per tile side: a worker takes one tile at a time from an atomic counter.
constexpr int kTileSize = 16;
constexpr uint32_t kNoTriangle = 0xFFFFFFFFu;
// Triangles shaded per work item of the per-frame shading pass.
constexpr uint32_t kShadeChunk = 1u << 15;

static_assert(sizeof(glm::vec3) == 3 * sizeof(float), "positions are copied as packed float3");

// ---- The renderer -------------------------------------------------------------------------------

// Per-thread state kept across frames so the hit arrays keep their capacity.
struct Worker {
  std::vector<std::vector<uint64_t>> hits;  // one growable list per ray slot
  std::vector<NearestHit> nearest;
  std::vector<glm::vec3> ray_org, ray_dir;  // the ray of each slot
  std::vector<uint64_t> scratch;
  std::vector<RTCRayHit> stream;  // Stream query: the rays of one tile
  uint64_t fragments = 0, max_depth = 0;

  size_t bytes() const {
    size_t b = scratch.capacity() * sizeof(uint64_t) + nearest.capacity() * sizeof(NearestHit) +
               stream.capacity() * sizeof(RTCRayHit) + 2 * ray_org.capacity() * sizeof(glm::vec3);
    for (const auto& h : hits) b += h.capacity() * sizeof(uint64_t);
    return b;
  }
  size_t hitBytes() const {
    size_t b = scratch.capacity() * sizeof(uint64_t);
    for (const auto& h : hits) b += h.capacity() * sizeof(uint64_t);
    return b;
  }
};

// What every worker reads during one frame.
struct FrameJob {
  RTCScene scene = nullptr;
  EmbreeMode mode = EmbreeMode::Transparency;
  bool translucency = false;  // Effect::Translucency (transparency mode only)
  float sigma = 0.0f;         // translucency: absorption per world unit
  const WorldGeometry* geometry = nullptr;
  const Camera* camera = nullptr;
  glm::vec3 forward{0.0f};
  int width = 0, height = 0, tiles_x = 0, tiles_y = 0;
  const StViewConstants* view = nullptr;
  const glm::vec4* shade = nullptr;  // per triangle: flat-shaded RGB, opacity
  // Textured geometry: the reference textures (nullptr when untextured, so untextured scenes
  // take exactly the flat-shaded path).
  const ReferenceTextures* textures = nullptr;
  Image* image = nullptr;
  uint32_t* depth_complexity = nullptr;  // per pixel, when asked for
  std::atomic<int> next_tile{0};
};

// The colour of triangle tri's fragment on the ray of pixel (x, y): its flat-shaded colour, times
// the reference texel at that pixel when the geometry is textured (RGB multiplies the colour, A
// the opacity). One ray per pixel centre, so every fragment along it uses that pixel's texel.
inline glm::vec4 fragmentColor(const FrameJob& job, uint32_t tri, int x, int y) {
  const glm::vec4& s = job.shade[tri];
  if (!job.textures) return s;
  return s * referenceTexel(*job.geometry, *job.textures, *job.view, tri, x, y);
}

int querySlots(EmbreeQuery q) {
  switch (q) {
    case EmbreeQuery::Packet4:
      return 4;
    case EmbreeQuery::Packet8:
      return 8;
    case EmbreeQuery::Packet16:
      return 16;
    case EmbreeQuery::Stream:
      return kTileSize * kTileSize;
    default:
      return 1;
  }
}

class EmbreeRenderer final : public MethodRenderer {
 public:
  explicit EmbreeRenderer(const EmbreeOptions& options);
  ~EmbreeRenderer() override;
  EmbreeRenderer(const EmbreeRenderer&) = delete;
  EmbreeRenderer& operator=(const EmbreeRenderer&) = delete;

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override;
  // Ray picks (EmbreeRayPicker): the all-hit traversal of the transparency mode, per pixel.
  void pickRays(const WorldGeometry& geometry, const FrameSettings& settings,
                const std::vector<glm::ivec2>& pixels, bool all_hits,
                std::vector<std::vector<EmbreeRayHit>>& out);

 private:
  void releaseScene();
  bool sceneMatches(const WorldGeometry& geometry) const;
  void buildScene(const WorldGeometry& geometry);
  void shadeTriangles(const WorldGeometry& geometry, const glm::vec3& light);
  void traceTiles(FrameJob& job);
  void traceTile(const FrameJob& job, Worker& w, int x0, int y0, int x1, int y1);
  template <int N, typename RayHitN, typename Intersect>
  void traceTilePackets(const FrameJob& job, Worker& w, int x0, int y0, int x1, int y1, int block_w,
                        Intersect intersect);
  void traceTileStream(const FrameJob& job, Worker& w, int x0, int y0, int x1, int y1);
  bool pixelRay(const FrameJob& job, int x, int y, glm::vec3& org, glm::vec3& dir,
                float& tnear) const;
  void resolvePixel(const FrameJob& job, Worker& w, int slot, int x, int y);
  static void translucentHits(const FrameJob& job, const std::vector<uint64_t>& hits, size_t depth,
                              const glm::vec3& dir, int x, int y, float rgb[3],
                              float& transmittance);
  void initContext(TraceContext& ctx, Worker& w, bool coherent) const;

  EmbreeOptions options_;
  int threads_ = 1;
  RTCDevice device_ = nullptr;
  std::string device_name_;

  // The cached BVH and Embree's own copies of the triangles it was built from.
  RTCScene scene_ = nullptr;
  const float* scene_vertices_ = nullptr;
  const uint32_t* scene_indices_ = nullptr;
  size_t scene_vertex_count_ = 0;
  size_t scene_triangle_count_ = 0;

  std::vector<glm::vec4> shade_;
  std::vector<Worker> workers_;
};

EmbreeRenderer::EmbreeRenderer(const EmbreeOptions& options) : options_(options) {
  // Auto: packets of 8 coherent rays (4x2 pixels). Measured on a 2-core AVX2 VM, 1024x1024,
  // 960k triangles, robust BVH: 8- and 16-ray packets about 1.7x rtcIntersect1, 4-ray packets
  // 1.3x, a tile-sized rtcIntersect1M stream 1.5x.
  if (options_.query == EmbreeQuery::Auto) options_.query = EmbreeQuery::Packet8;
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  threads_ = options_.threads > 0 ? options_.threads : int(hw);

  // With an explicit thread count, the BVH build uses the same number of threads.
  const std::string config =
      options_.threads > 0 ? "threads=" + std::to_string(options_.threads) : std::string();
  device_ = rtcNewDevice(config.empty() ? nullptr : config.c_str());
  if (!device_) {
    const RTCError code = rtcGetDeviceError(nullptr);
    throw Error(std::string("Embree: rtcNewDevice failed: ") + errorName(code));
  }
  rtcSetDeviceErrorFunction(device_, onEmbreeError, nullptr);
  const auto prop = [&](RTCDeviceProperty p) { return rtcGetDeviceProperty(device_, p); };
  device_name_ = "Embree " + std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_MAJOR)) + "." +
                 std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_MINOR)) + "." +
                 std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_PATCH)) + " on " +
                 std::to_string(threads_) + (threads_ == 1 ? " thread" : " threads");
  if (!prop(RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED)) {
    rtcReleaseDevice(device_);
    throw Error(
        "Embree: this Embree library was built without filter functions, which the "
        "all-hit reference needs");
  }

  workers_.resize(size_t(threads_));
  const int slots = querySlots(options_.query);
  for (Worker& w : workers_) {
    w.hits.resize(size_t(slots));
    w.nearest.resize(size_t(slots));
    w.ray_org.resize(size_t(slots));
    w.ray_dir.resize(size_t(slots));
  }
}

EmbreeRenderer::~EmbreeRenderer() {
  releaseScene();
  if (device_) rtcReleaseDevice(device_);
}

void EmbreeRenderer::releaseScene() {
  if (scene_) rtcReleaseScene(scene_);
  scene_ = nullptr;
  scene_vertices_ = nullptr;
  scene_indices_ = nullptr;
  scene_vertex_count_ = scene_triangle_count_ = 0;
}

// The BVH is reused when the triangles are the same: same counts and the same bytes as Embree's
// copies (a cheap memcmp next to a build, and safe when a geometry at the same address changed).
bool EmbreeRenderer::sceneMatches(const WorldGeometry& g) const {
  if (!scene_ || g.positions.size() != scene_vertex_count_ ||
      g.triangleCount() != scene_triangle_count_)
    return false;
  if (scene_triangle_count_ == 0) return true;
  return std::memcmp(scene_vertices_, g.positions.data(), g.positions.size() * 12) == 0 &&
         std::memcmp(scene_indices_, g.indices.data(), scene_triangle_count_ * 12) == 0;
}

void EmbreeRenderer::buildScene(const WorldGeometry& g) {
  releaseScene();
  const size_t triangles = g.triangleCount();
  const size_t vertices = g.positions.size();
  for (size_t i = 0; i < triangles * 3; ++i)
    if (g.indices[i] >= vertices)
      throw Error("world geometry: triangle " + std::to_string(i / 3) + " refers to vertex " +
                  std::to_string(g.indices[i]) + " of " + std::to_string(vertices));
  // Embree traces only within about +-1.8e18 (its rays are invalid beyond): a corner of a
  // finite triangle further out would be lost without a word, so such a scene is refused.
  constexpr float kEmbreeReach = 1e18f;
  for (size_t i = 0; i < triangles * 3; ++i) {
    const glm::vec3& p = g.positions[g.indices[i]];
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
        (std::abs(p.x) > kEmbreeReach || std::abs(p.y) > kEmbreeReach ||
         std::abs(p.z) > kEmbreeReach)) {
      char where[96];
      std::snprintf(where, sizeof(where), "(%g, %g, %g)", p.x, p.y, p.z);
      throw Error("embree: triangle " + std::to_string(i / 3) + " has a corner at " + where +
                  ", beyond the +-1e18 Embree can trace; scale the scene down (the OpenCL "
                  "methods render it)");
    }
  }

  RTCScene scene = rtcNewScene(device_);
  checkEmbree(device_, "rtcNewScene");
  try {
    // Robust: conservative traversal and watertight triangle tests (no pixel slips between two
    // triangles sharing an edge). High quality: an SAH build (with spatial splits when not
    // robust: Embree 3.13 then reports some triangles from several leaves).
    rtcSetSceneFlags(scene, options_.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE);
    checkEmbree(device_, "rtcSetSceneFlags");
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    checkEmbree(device_, "rtcSetSceneBuildQuality");
    if (triangles > 0) {
      RTCGeometry geom = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
      checkEmbree(device_, "rtcNewGeometry");
      // The scene keeps the geometry (and its buffers) alive after attachment.
      struct GeometryRef {
        RTCGeometry g;
        ~GeometryRef() { rtcReleaseGeometry(g); }
      } ref{geom};
      rtcSetGeometryBuildQuality(geom, RTC_BUILD_QUALITY_HIGH);
      checkEmbree(device_, "rtcSetGeometryBuildQuality");
      // Copies (not shared buffers): Embree pads them for its vector loads and they stay valid
      // whatever the caller does with the geometry; they also key the BVH cache.
      auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
          geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), vertices));
      checkEmbree(device_, "rtcSetNewGeometryBuffer(vertex)");
      auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(
          geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), triangles));
      checkEmbree(device_, "rtcSetNewGeometryBuffer(index)");
      std::memcpy(v, g.positions.data(), vertices * 3 * sizeof(float));
      std::memcpy(idx, g.indices.data(), triangles * 3 * sizeof(uint32_t));
      rtcSetGeometryIntersectFilterFunction(
          geom, options_.mode == EmbreeMode::Transparency ? gatherEveryHit : keepNearestHit);
      checkEmbree(device_, "rtcSetGeometryIntersectFilterFunction");
      rtcCommitGeometry(geom);
      checkEmbree(device_, "rtcCommitGeometry");
      rtcAttachGeometryByID(scene, geom, 0);
      checkEmbree(device_, "rtcAttachGeometryByID");
      scene_vertices_ = v;
      scene_indices_ = idx;
    }
    rtcCommitScene(scene);
    checkEmbree(device_, "rtcCommitScene");
  } catch (...) {
    rtcReleaseScene(scene);
    scene_vertices_ = nullptr;
    scene_indices_ = nullptr;
    throw;
  }
  scene_ = scene;
  scene_vertex_count_ = vertices;
  scene_triangle_count_ = triangles;
}

// Flat shading is per triangle, so it is computed once per frame (light follows the camera).
void EmbreeRenderer::shadeTriangles(const WorldGeometry& g, const glm::vec3& light) {
  const uint32_t n = g.triangleCount();
  shade_.resize(n);
  if (g.triangle_material.size() < n)
    throw Error("world geometry: " + std::to_string(g.triangle_material.size()) +
                " triangle materials for " + std::to_string(n) + " triangles");
  std::atomic<uint32_t> next{0};
  const size_t materials = g.material_colors.size();
  runWorkers(std::min(threads_, int((n + kShadeChunk - 1) / kShadeChunk)), [&](int) {
    for (;;) {
      const uint32_t begin = next.fetch_add(kShadeChunk);
      if (begin >= n) return;
      const uint32_t end = std::min(n, begin + kShadeChunk);
      for (uint32_t t = begin; t < end; ++t) {
        if (g.triangle_material[t] >= materials)
          throw Error("world geometry: triangle " + std::to_string(t) + " has material " +
                      std::to_string(g.triangle_material[t]) + " of " + std::to_string(materials));
        shade_[t] = shadeTriangle(g, t, light);
      }
    }
  });
}

void EmbreeRenderer::initContext(TraceContext& ctx, Worker& w, bool coherent) const {
  rtcInitIntersectContext(&ctx.embree);
  ctx.embree.flags =
      coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
  ctx.hits = w.hits.data();
  ctx.nearest = w.nearest.data();
}

// The primary ray of pixel (x, y), starting at the rasterizer's near plane: view distance
// d = t * dot(dir, forward) >= near_distance.
bool EmbreeRenderer::pixelRay(const FrameJob& job, int x, int y, glm::vec3& org, glm::vec3& dir,
                              float& tnear) const {
  job.camera->pixelRay(x, y, job.width, job.height, org, dir);
  const float cos_fwd = glm::dot(dir, job.forward);
  if (!(cos_fwd > 0.0f) || !std::isfinite(org.x + org.y + org.z + dir.x + dir.y + dir.z))
    return false;
  tnear = std::max(0.0f, job.camera->near_distance / cos_fwd);
  return std::isfinite(tnear);
}

// A single primary ray from the near plane to infinity, with no hit yet.
static RTCRayHit primaryRay(const glm::vec3& org, const glm::vec3& dir, float tnear, unsigned id) {
  RTCRayHit rh;
  rh.ray.org_x = org.x;
  rh.ray.org_y = org.y;
  rh.ray.org_z = org.z;
  rh.ray.tnear = tnear;
  rh.ray.dir_x = dir.x;
  rh.ray.dir_y = dir.y;
  rh.ray.dir_z = dir.z;
  rh.ray.time = 0.0f;
  rh.ray.tfar = std::numeric_limits<float>::infinity();
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.id = id;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  return rh;
}

// Translucency (the rule of strata_shared.h) over a ray's sorted, deduplicated hits: Schlick
// reflection of the flat-shaded colour at every hit, Beer-Lambert absorption along the ray
// between consecutive hits while inside (front faces entered minus back faces left, never below
// 0). The ray direction has unit length, so the path length between two hits is the difference
// of their ray parameters. Facing is that of the rasterizer: a triangle is front-facing when its
// winding normal cross(v1 - v0, v2 - v0) points towards the viewer, dot(normal, dir) < 0. The
// normal comes from the triangle's corners, not from Embree's Ng (which the filter does not
// keep, and whose sign convention is Embree's own). A triangle without a usable normal (zero
// area in double precision) is skipped: the rasterizer culls it too.
void EmbreeRenderer::translucentHits(const FrameJob& job, const std::vector<uint64_t>& hits,
                                     size_t depth, const glm::vec3& dir_f, int x, int y,
                                     float rgb[3], float& transmittance) {
  const WorldGeometry& g = *job.geometry;
  const glm::dvec3 dir(dir_f);
  int inside = 0;
  float prev_t = 0.0f;
  bool have_prev = false;
  for (size_t i = 0; i < depth; ++i) {
    const uint32_t tri = hitTriangle(hits[i]);
    const uint32_t* idx = &g.indices[3 * size_t(tri)];
    const glm::dvec3 p0(g.positions[idx[0]]), p1(g.positions[idx[1]]), p2(g.positions[idx[2]]);
    const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
    const double len = glm::length(n);
    if (!(len > 0.0) || !std::isfinite(len)) continue;
    float t;
    const uint32_t t_bits = uint32_t(hits[i] >> 32);
    std::memcpy(&t, &t_bits, sizeof(t));
    if (have_prev && inside > 0) transmittance *= std::exp(-job.sigma * (t - prev_t));
    prev_t = t;
    have_prev = true;
    const double n_dot_dir = glm::dot(n, dir);
    const float r = st_schlick_reflectance(float(std::abs(n_dot_dir) / len));
    const glm::vec4 s = fragmentColor(job, tri, x, y);
    const float tr = transmittance * r;
    rgb[0] += tr * s.r;
    rgb[1] += tr * s.g;
    rgb[2] += tr * s.b;
    transmittance *= 1.0f - r;
    if (n_dot_dir < 0.0)
      ++inside;
    else if (inside > 0)
      --inside;
  }
}

void EmbreeRenderer::resolvePixel(const FrameJob& job, Worker& w, int slot, int x, int y) {
  float rgb[3] = {0.0f, 0.0f, 0.0f};
  float transmittance = 1.0f;
  if (job.mode == EmbreeMode::Transparency) {
    std::vector<uint64_t>& hits = w.hits[size_t(slot)];
    size_t depth = sortUniqueHits(hits, w.scratch);
    if (depth > 1)
      depth = mergeSharedBoundaryHits(hits, *job.geometry, w.ray_org[size_t(slot)],
                                      w.ray_dir[size_t(slot)]);
    if (job.translucency) {
      translucentHits(job, hits, depth, w.ray_dir[size_t(slot)], x, y, rgb, transmittance);
    } else {
      for (size_t i = 0; i < depth; ++i) {
        // Front-to-back "under": C += T * a * rgb; T *= 1 - a.
        const glm::vec4 s = fragmentColor(job, hitTriangle(hits[i]), x, y);
        const float ta = transmittance * s.a;
        rgb[0] += ta * s.r;
        rgb[1] += ta * s.g;
        rgb[2] += ta * s.b;
        transmittance *= 1.0f - s.a;
      }
    }
    w.fragments += depth;
    w.max_depth = std::max<uint64_t>(w.max_depth, depth);
    if (job.depth_complexity) job.depth_complexity[size_t(y) * job.width + x] = uint32_t(depth);
  } else {
    const NearestHit& best = w.nearest[size_t(slot)];
    if (best.triangle != kNoTriangle) {
      const glm::vec4 s = fragmentColor(job, best.triangle, x, y);
      rgb[0] = s.r;
      rgb[1] = s.g;
      rgb[2] = s.b;
      transmittance = 0.0f;
      w.fragments += 1;
      w.max_depth = std::max<uint64_t>(w.max_depth, 1);
    }
  }
  uint8_t* out = job.image->pixel(x, y);
  for (int c = 0; c < 3; ++c) {
    const float bg = transmittance > 0.0f ? st_background_channel(job.view, x, y, c) : 0.0f;
    out[c] = uint8_t(st_to_unorm8(rgb[c] + transmittance * bg));
  }
  out[3] = 255;
}

void EmbreeRenderer::traceTile(const FrameJob& job, Worker& w, int x0, int y0, int x1, int y1) {
  TraceContext ctx;
  initContext(ctx, w, false);
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      w.hits[0].clear();
      w.nearest[0] = {std::numeric_limits<float>::infinity(), kNoTriangle};
      glm::vec3 org, dir;
      float tnear;
      if (pixelRay(job, x, y, org, dir, tnear)) {
        w.ray_org[0] = org;
        w.ray_dir[0] = dir;
        RTCRayHit rh = primaryRay(org, dir, tnear, 0);
        rtcIntersect1(job.scene, &ctx.embree, &rh);
      }
      resolvePixel(job, w, 0, x, y);
    }
  }
}

// Packets of N rays over coherent blocks of block_w x (N / block_w) pixels.
template <int N, typename RayHitN, typename Intersect>
void EmbreeRenderer::traceTilePackets(const FrameJob& job, Worker& w, int x0, int y0, int x1,
                                      int y1, int block_w, Intersect intersect) {
  const int block_h = N / block_w;
  TraceContext ctx;
  initContext(ctx, w, true);
  alignas(64) int valid[N];
  alignas(64) RayHitN rh;
  for (int by = y0; by < y1; by += block_h) {
    for (int bx = x0; bx < x1; bx += block_w) {
      bool any = false;
      for (int lane = 0; lane < N; ++lane) {
        const int x = bx + lane % block_w, y = by + lane / block_w;
        w.hits[size_t(lane)].clear();
        w.nearest[size_t(lane)] = {std::numeric_limits<float>::infinity(), kNoTriangle};
        glm::vec3 org(0.0f), dir(0.0f, 0.0f, 1.0f);
        float tnear = 0.0f;
        const bool live = x < x1 && y < y1 && pixelRay(job, x, y, org, dir, tnear);
        valid[lane] = live ? -1 : 0;
        w.ray_org[size_t(lane)] = org;
        w.ray_dir[size_t(lane)] = dir;
        any |= live;
        rh.ray.org_x[lane] = org.x;
        rh.ray.org_y[lane] = org.y;
        rh.ray.org_z[lane] = org.z;
        rh.ray.tnear[lane] = tnear;
        rh.ray.dir_x[lane] = dir.x;
        rh.ray.dir_y[lane] = dir.y;
        rh.ray.dir_z[lane] = dir.z;
        rh.ray.time[lane] = 0.0f;
        rh.ray.tfar[lane] = live ? std::numeric_limits<float>::infinity() : -1.0f;
        rh.ray.mask[lane] = 0xFFFFFFFFu;
        rh.ray.id[lane] = unsigned(lane);
        rh.ray.flags[lane] = 0;
        rh.hit.geomID[lane] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID[lane] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][lane] = RTC_INVALID_GEOMETRY_ID;
      }
      if (any) intersect(valid, job.scene, &ctx.embree, &rh);
      for (int lane = 0; lane < N; ++lane) {
        const int x = bx + lane % block_w, y = by + lane / block_w;
        if (x < x1 && y < y1) resolvePixel(job, w, lane, x, y);
      }
    }
  }
}

// A whole tile as one ray stream (rtcIntersect1M): Embree regroups it into packets itself.
void EmbreeRenderer::traceTileStream(const FrameJob& job, Worker& w, int x0, int y0, int x1,
                                     int y1) {
  TraceContext ctx;
  initContext(ctx, w, true);
  w.stream.clear();
  const int tile_w = x1 - x0;
  for (int y = y0; y < y1; ++y) {
    for (int x = x0; x < x1; ++x) {
      const unsigned slot = unsigned((y - y0) * tile_w + (x - x0));
      w.hits[slot].clear();
      w.nearest[slot] = {std::numeric_limits<float>::infinity(), kNoTriangle};
      glm::vec3 org, dir;
      float tnear;
      if (!pixelRay(job, x, y, org, dir, tnear)) continue;
      w.ray_org[slot] = org;
      w.ray_dir[slot] = dir;
      RTCRayHit rh = primaryRay(org, dir, tnear, unsigned(slot));
      w.stream.push_back(rh);
    }
  }
  if (!w.stream.empty())
    rtcIntersect1M(job.scene, &ctx.embree, w.stream.data(), unsigned(w.stream.size()),
                   sizeof(RTCRayHit));
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) resolvePixel(job, w, (y - y0) * tile_w + (x - x0), x, y);
}

void EmbreeRenderer::traceTiles(FrameJob& job) {
  const int tiles = job.tiles_x * job.tiles_y;
  for (Worker& w : workers_) w.fragments = w.max_depth = 0;
  runWorkers(std::min(threads_, tiles), [&](int worker) {
    Worker& w = workers_[size_t(worker)];
    for (;;) {
      const int tile = job.next_tile.fetch_add(1);
      if (tile >= tiles) return;
      const int x0 = (tile % job.tiles_x) * kTileSize, y0 = (tile / job.tiles_x) * kTileSize;
      const int x1 = std::min(job.width, x0 + kTileSize);
      const int y1 = std::min(job.height, y0 + kTileSize);
      switch (options_.query) {
        case EmbreeQuery::Packet4:
          traceTilePackets<4, RTCRayHit4>(job, w, x0, y0, x1, y1, 2, rtcIntersect4);
          break;
        case EmbreeQuery::Packet8:
          traceTilePackets<8, RTCRayHit8>(job, w, x0, y0, x1, y1, 4, rtcIntersect8);
          break;
        case EmbreeQuery::Packet16:
          traceTilePackets<16, RTCRayHit16>(job, w, x0, y0, x1, y1, 4, rtcIntersect16);
          break;
        case EmbreeQuery::Stream:
          traceTileStream(job, w, x0, y0, x1, y1);
          break;
        default:
          traceTile(job, w, x0, y0, x1, y1);
          break;
      }
    }
  });
}

RenderResult EmbreeRenderer::render(const WorldGeometry& geometry, const FrameSettings& settings) {
  validateFrameSize(settings.width, settings.height);
  const bool translucency =
      options_.mode == EmbreeMode::Transparency && settings.effect == Effect::Translucency;
  if (translucency && !(std::isfinite(settings.sigma) && settings.sigma >= 0.0f))
    throw Error("translucency: sigma must be a finite number >= 0 (got " +
                std::to_string(settings.sigma) + ")");
  RenderResult result;
  FrameStats& stats = result.stats;

  // Build the BVH unless the cached one was built from the same triangles.
  const Clock::time_point bvh_start = Clock::now();
  if (!sceneMatches(geometry)) buildScene(geometry);
  stats.stage_ms["bvh_build"] = msSince(bvh_start);

  StViewConstants view = makeViewConstants(settings);
  Camera camera = settings.camera;  // this frame's: a moving camera turns it every frame
  // Textured geometry: the reference mip chains, once per call (like the BVH, not part of a
  // frame's time).
  ReferenceTextures textures;
  if (geometry.textured()) {
    const Clock::time_point texture_start = Clock::now();
    textures = ReferenceTextures::build(geometry);
    stats.stage_ms["texture_build"] = msSince(texture_start);
  }
  result.image = Image(settings.width, settings.height);
  FrameJob job;
  job.scene = scene_;
  job.mode = options_.mode;
  job.translucency = translucency;
  job.sigma = settings.sigma;
  job.geometry = &geometry;
  job.camera = &camera;
  job.forward = camera.forward();
  job.width = settings.width;
  job.height = settings.height;
  job.tiles_x = (settings.width + kTileSize - 1) / kTileSize;
  job.tiles_y = (settings.height + kTileSize - 1) / kTileSize;
  job.view = &view;
  job.textures = geometry.textured() ? &textures : nullptr;
  job.image = &result.image;
  if (settings.capture_depth_complexity && options_.mode == EmbreeMode::Transparency) {
    result.depth_complexity.assign(size_t(settings.width) * settings.height, 0u);
    job.depth_complexity = result.depth_complexity.data();
  }

  const int frames = std::max(1, settings.frames);
  std::vector<double> frame_ms, shade_ms, trace_ms;
  FrameSettings moved;
  if (settings.orbit_deg != 0.0f) moved = settings;
  for (int f = 0; f < frames; ++f) {
    const Clock::time_point start = Clock::now();
    if (settings.orbit_deg != 0.0f) {
      moved.camera = camera = frameCamera(settings, f);
      job.forward = camera.forward();
      view = makeViewConstants(moved);
    }
    shadeTriangles(geometry, camera.lightDirection());
    job.shade = shade_.data();
    shade_ms.push_back(msSince(start));
    const Clock::time_point trace_start = Clock::now();
    job.next_tile = 0;
    traceTiles(job);
    trace_ms.push_back(msSince(trace_start));
    frame_ms.push_back(msSince(start));
    if (settings.on_frame) settings.on_frame(f + 1, frames);
  }

  stats.method = options_.mode == EmbreeMode::Transparency ? "embree" : "embree-opaque";
  stats.device = device_name_;
  stats.width = settings.width;
  stats.height = settings.height;
  stats.triangles = geometry.triangleCount();
  stats.triangles_read = 0;  // no raster stage
  stats.kernel_launches = 0;
  for (const Worker& w : workers_) {
    stats.fragments += w.fragments;
    stats.max_depth_complexity = std::max(stats.max_depth_complexity, w.max_depth);
    stats.fragment_bytes += w.hitBytes();
    stats.device_bytes += w.bytes();
  }
  // Approximate working memory: the per-thread hit arrays (and ray buffers), the per-triangle
  // shading table and the image. Embree's BVH is not counted (it plays the part of the scene's
  // acceleration data, which the OpenCL methods do not count either).
  stats.device_bytes += shade_.capacity() * sizeof(glm::vec4) + result.image.rgba.size();
  stats.orbit_deg = settings.orbit_deg;
  stats.frame_ms = summarizeTimes(frame_ms);
  stats.stage_ms["shade"] = median(shade_ms);
  stats.stage_ms["trace"] = median(trace_ms);
  return result;
}

// Ray picks reuse the transparency path's traversal (gatherEveryHit) and its deduplication
// (sortUniqueHits, mergeSharedBoundaryHits), one incoherent rtcIntersect1 per pixel; workers take
// chunks of pixels from an atomic counter.
void EmbreeRenderer::pickRays(const WorldGeometry& geometry, const FrameSettings& settings,
                              const std::vector<glm::ivec2>& pixels, bool all_hits,
                              std::vector<std::vector<EmbreeRayHit>>& out) {
  validateFrameSize(settings.width, settings.height);
  if (options_.mode != EmbreeMode::Transparency)
    throw Error("Embree ray picks need the all-hit (transparency) traversal");
  if (!sceneMatches(geometry)) buildScene(geometry);
  out.assign(pixels.size(), {});
  if (!scene_ || geometry.triangleCount() == 0) return;
  FrameJob job;
  job.scene = scene_;
  job.geometry = &geometry;
  job.camera = &settings.camera;
  job.forward = settings.camera.forward();
  job.width = settings.width;
  job.height = settings.height;
  const glm::vec3 eye = settings.camera.eye;
  constexpr size_t kChunk = 64;
  const size_t n = pixels.size();
  std::atomic<size_t> next{0};
  const int threads = int(std::min<size_t>(size_t(threads_), (n + kChunk - 1) / kChunk));
  runWorkers(std::max(1, threads), [&](int worker) {
    Worker& w = workers_[size_t(worker)];
    TraceContext ctx;
    initContext(ctx, w, false);
    std::vector<uint64_t>& hits = w.hits[0];
    for (;;) {
      const size_t begin = next.fetch_add(kChunk);
      if (begin >= n) return;
      for (size_t i = begin; i < std::min(n, begin + kChunk); ++i) {
        const glm::ivec2 p = pixels[i];
        if (p.x < 0 || p.y < 0 || p.x >= job.width || p.y >= job.height) continue;
        glm::vec3 org, dir;
        float tnear;
        if (!pixelRay(job, p.x, p.y, org, dir, tnear)) continue;
        hits.clear();
        RTCRayHit rh = primaryRay(org, dir, tnear, 0);
        rtcIntersect1(job.scene, &ctx.embree, &rh);
        size_t depth = sortUniqueHits(hits, w.scratch);
        if (depth > 1) depth = mergeSharedBoundaryHits(hits, geometry, org, dir);
        if (!all_hits) depth = std::min<size_t>(depth, 1);
        const float along = glm::dot(dir, job.forward), base = glm::dot(org - eye, job.forward);
        out[i].reserve(depth);
        for (size_t k = 0; k < depth; ++k) {
          float t;
          const uint32_t t_bits = uint32_t(hits[k] >> 32);
          std::memcpy(&t, &t_bits, sizeof(t));
          out[i].push_back({hitTriangle(hits[k]), t, base + t * along});
        }
      }
    }
  });
}

}  // namespace

struct EmbreeRayPicker::Impl {
  EmbreeRenderer renderer;
  explicit Impl(const EmbreeOptions& o) : renderer(o) {}
};

EmbreeRayPicker::EmbreeRayPicker(int threads) {
  EmbreeOptions options;
  options.mode = EmbreeMode::Transparency;
  options.query = EmbreeQuery::Single;
  options.threads = threads;
  impl_ = std::make_unique<Impl>(options);
}

EmbreeRayPicker::~EmbreeRayPicker() = default;

std::vector<std::vector<EmbreeRayHit>> EmbreeRayPicker::pick(const WorldGeometry& geometry,
                                                             const FrameSettings& settings,
                                                             const std::vector<glm::ivec2>& pixels,
                                                             bool all_hits) {
  std::vector<std::vector<EmbreeRayHit>> out;
  impl_->renderer.pickRays(geometry, settings, pixels, all_hits, out);
  return out;
}

std::vector<EmbreeRayHit> embreePickRay(const WorldGeometry& geometry,
                                        const FrameSettings& settings, int x, int y,
                                        bool all_hits) {
  EmbreeRayPicker picker(1);
  return picker.pick(geometry, settings, {glm::ivec2(x, y)}, all_hits).front();
}

std::unique_ptr<MethodRenderer> makeEmbreeRenderer(const EmbreeOptions& options) {
  return std::make_unique<EmbreeRenderer>(options);
}

std::unique_ptr<MethodRenderer> makeEmbreeRenderer(EmbreeMode mode) {
  EmbreeOptions options;
  options.mode = mode;
  return makeEmbreeRenderer(options);
}

}  // namespace strata
