#include "engine/renderer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>

#include "engine/frontend/cl_pipeline.h"
#include "engine/frontend/cl_renderer.h"
#include "engine/frontend/view_constants.h"
#include "engine/reference/embree_reference.h"
#include "host/cl_runtime.h"
#include "preprocess/core/enum_table.h"
#include "preprocess/octree_scene.h"

namespace strata {

// The methods' factories, one file each (engine/methods/NAME.cpp); only the registry below
// knows them.
std::unique_ptr<ClMethod> makeOpaqueMethod();
std::unique_ptr<ClMethod> makePpllMethod();
std::unique_ptr<ClMethod> makeAbufferMethod();
std::unique_ptr<ClMethod> makeMdtsMethod(bool packed_32bit);
std::unique_ptr<ClMethod> makeDepthPeelingMethod(bool dual);
std::unique_ptr<ClMethod> makeBucketPeelingMethod(bool adaptive);
std::unique_ptr<ClMethod> makeWboitMethod();
std::unique_ptr<ClMethod> makeMlabMethod();
std::unique_ptr<ClMethod> makeHybridMethod();
std::unique_ptr<ClMethod> makeAdaptiveMethod();
std::unique_ptr<ClMethod> makeStochasticMethod();
std::unique_ptr<ClMethod> makeMboitMethod();
// The convex-cells and octree methods stream batches through their own front ends.
std::unique_ptr<MethodRenderer> makeCellsRenderer(const DeviceOptions& device);
std::unique_ptr<MethodRenderer> makeOctreeRenderer(const DeviceOptions& device);

namespace {

std::unique_ptr<MethodRenderer> makeEmbree(const DeviceOptions&) {
  return makeEmbreeRenderer(EmbreeMode::Transparency);
}

// name, summary, exact, OpenCL, takes k, effects, factory.
const MethodTraits kMethods[] = {
    {Method::Opaque,
     "opaque",
     "nearest fragment only (64-bit visibility buffer)",
     true,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Opaque, makeOpaqueMethod(), d); }},
    {Method::Ppll,
     "ppll",
     "exact transparency with per-pixel linked lists",
     true,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Ppll, makePpllMethod(), d); }},
    {Method::Abuffer,
     "abuffer",
     "FreePipe ABS: K fragments per pixel appended, then sorted (exact while K >= depth)",
     true,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Abuffer, makeAbufferMethod(), d);
     }},
    {Method::Mdts,
     "mdts",
     "FreePipe MDTS: K sorted slots filled by atomic-min insertion (exact while K >= depth)",
     true,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Mdts, makeMdtsMethod(false), d); }},
    {Method::Mdts32,
     "mdts32",
     "MDTS with the published 32-bit depth+colour packing (approximate)",
     false,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Mdts32, makeMdtsMethod(true), d);
     }},
    {Method::Dp,
     "dp",
     "depth peeling: one geometry pass per layer",
     true,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Dp, makeDepthPeelingMethod(false), d);
     }},
    {Method::Ddp,
     "ddp",
     "dual depth peeling: front and back layer per pass",
     true,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Ddp, makeDepthPeelingMethod(true), d);
     }},
    {Method::Bdp,
     "bdp",
     "bucket depth peeling, 32 uniform depth buckets (approximate)",
     false,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Bdp, makeBucketPeelingMethod(false), d);
     }},
    {Method::Bdp2,
     "bdp2",
     "adaptive bucket depth peeling, histogram-divided buckets (approximate)",
     false,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Bdp2, makeBucketPeelingMethod(true), d);
     }},
    {Method::Wboit,
     "wboit",
     "weighted blended OIT (McGuire and Bavoil 2013): weighted average colour, exact coverage "
     "(approximate)",
     false,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Wboit, makeWboitMethod(), d); }},
    {Method::Mlab,
     "mlab",
     "multi-layer alpha blending (Salvi and Vaidyanathan 2014): k layers per pixel, the last two "
     "merged (approximate)",
     false,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Mlab, makeMlabMethod(), d); }},
    {Method::Hybrid,
     "hybrid",
     "hybrid transparency (Maule et al. 2013): k nearest fragments exact, the rest blended by "
     "weighted average (approximate)",
     false,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Hybrid, makeHybridMethod(), d); }},
    {Method::Adaptive,
     "adaptive",
     "adaptive transparency (Salvi et al. 2011): a k-node visibility function per pixel, "
     "compressed by least area (approximate)",
     false,
     true,
     true,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Adaptive, makeAdaptiveMethod(), d);
     }},
    {Method::Stochastic,
     "stochastic",
     "stochastic transparency (Enderton et al. 2010): random coverage of --samples per pixel, "
     "alpha-corrected (approximate, unbiased)",
     false,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) {
       return makeClRenderer(Method::Stochastic, makeStochasticMethod(), d);
     }},
    {Method::Mboit,
     "mboit",
     "moment-based OIT (Munstermann et al. 2018): four power moments of optical depth per pixel, "
     "then every fragment through the transmittance they bound (approximate)",
     false,
     true,
     false,
     {Effect::Transparency},
     [](const DeviceOptions& d) { return makeClRenderer(Method::Mboit, makeMboitMethod(), d); }},
    {Method::Cells,
     "cells",
     "convex cells drawn in visibility order, front and back layer per cell (headline method)",
     true,
     true,
     false,
     {Effect::Transparency, Effect::Translucency},
     [](const DeviceOptions& d) { return makeCellsRenderer(d); }},
    {Method::Octree,
     "octree",
     "octree leaves in visibility order, each resolved on its own (any triangle soup, any depth)",
     true,
     true,
     false,
     {Effect::Transparency, Effect::Translucency},
     [](const DeviceOptions& d) { return makeOctreeRenderer(d); }},
    {Method::Embree,
     "embree",
     "the CPU reference: Embree all-hit ray casting, sorted per pixel",
     true,
     false,
     false,
     {Effect::Transparency, Effect::Translucency},
     makeEmbree},
};

std::string knownMethods() {
  std::string known;
  for (const MethodTraits& m : kMethods) known += std::string(known.empty() ? "" : ", ") + m.name;
  return known;
}

// Every renderer the registry makes checks its input first, so no method sees geometry or
// settings it cannot render (an invalid WorldGeometry would otherwise be read out of bounds by
// the kernels).
class CheckedRenderer final : public MethodRenderer {
 public:
  CheckedRenderer(const MethodTraits& info, std::unique_ptr<MethodRenderer> inner)
      : info_(info), inner_(std::move(inner)) {}
  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override {
    checkSettings(info_, settings);
    // A geometry is checked once per generation (0: unknown, checked every call).
    if (settings.geometry_generation == 0 || settings.geometry_generation != validated_) {
      validated_ = 0;
      validateWorldGeometry(geometry);
      validated_ = settings.geometry_generation;
    }
    // An out-of-core octree scene: the octree method streams it from its file; every other
    // method renders it read whole into host memory (once per file).
    const WorldGeometry* scene = &geometry;
    if (geometry.out_of_core && info_.method != Method::Octree) {
      if (in_core_source_ != geometry.out_of_core->file) {
        in_core_source_.reset();
        in_core_ = materializeOctreeScene(*geometry.out_of_core->file, geometry.material_colors,
                                          geometry.material_state);
        in_core_source_ = geometry.out_of_core->file;
      }
      in_core_.material_colors = geometry.material_colors;  // --alpha may differ per call
      in_core_.material_state = geometry.material_state;
      scene = &in_core_;
    }
    RenderResult result = inner_->render(*scene, settings);
    const uint64_t budget = settings.memory_budget;
    if (budget && info_.opencl && info_.method != Method::Octree) {
      // The method's working set plus the scene's own buffers, which it keeps resident.
      const uint64_t scene_bytes = scene->positions.size() * 12 + scene->indices.size() * 4 +
                                   scene->triangle_material.size() * 4 +
                                   scene->material_colors.size() * 16;
      const uint64_t need = result.stats.device_bytes + scene_bytes;
      if (need > budget)
        throw Error(std::string(info_.name) + " needed " + megabytes(need) +
                    " of device memory, over the memory budget of " + megabytes(budget) +
                    (info_.method == Method::Cells
                         ? " (cells streams its triangles in batches sized to a budget, but the "
                           "scene, the image and its largest group of cells need this much)"
                         : " (octree and cells keep within a budget by streaming their "
                           "triangles)"));
    }
    return result;
  }

 private:
  const MethodTraits& info_;
  std::unique_ptr<MethodRenderer> inner_;
  uint64_t validated_ = 0;  // the generation last validated
  // The out-of-core scene last read whole, for methods that cannot stream it.
  std::shared_ptr<const OctreeSceneFile> in_core_source_;
  WorldGeometry in_core_;
};

}  // namespace

bool MethodTraits::renders(Effect e) const {
  return std::find(effects.begin(), effects.end(), e) != effects.end();
}

const std::vector<MethodTraits>& methodRegistry() {
  static const std::vector<MethodTraits> all(std::begin(kMethods), std::end(kMethods));
  return all;
}

const MethodTraits& methodInfo(Method method) {
  for (const MethodTraits& m : kMethods)
    if (m.method == method) return m;
  throw Error("method " + std::to_string(int(method)) + " is not registered");
}

Method parseMethod(const std::string& name) {
  for (const MethodTraits& m : kMethods)
    if (name == m.name) return m.method;
  throw Error("unknown method '" + name + "' (known: " + knownMethods() + ")");
}

std::string methodName(Method method) { return methodInfo(method).name; }

void checkTileKernels(const std::string& name) { parseTileKernels(name); }

constexpr const char* kTileKernelsNames[] = {"auto", "group", "serial"};

TileKernels parseTileKernels(const std::string& name) {
  if (auto value = enumFromName<TileKernels>(name, kTileKernelsNames)) return *value;
  throw Error("unknown tile kernels '" + name + "' (auto, group or serial)");
}

const char* optionName(TileKernels value) { return enumLookup(value, kTileKernelsNames, "auto"); }

std::vector<std::string> methodNames() {
  std::vector<std::string> out;
  for (const MethodTraits& m : kMethods) out.push_back(m.name);
  return out;
}

uint64_t deviceBytesInUse() { return ClRuntime::liveBytesOfAllDevices(); }

void checkFrameCount(int frames, const std::string& what) {
  if (frames < 1 || frames > kMaxFrames)
    throw Error(what + " must be between 1 and " + std::to_string(kMaxFrames));
}

Camera frameCamera(const FrameSettings& settings, int frame) {
  return settings.camera.turned(float(frame) * settings.orbit_deg);
}

namespace {

// Rays are traced (embree) and vertices projected (OpenCL) only within +-1e18 (Embree's rays are
// invalid beyond about 1.8e18, and float products of such coordinates overflow): a camera
// further out, or not finite, gets a one-line error instead of an abort or an empty image.
void checkCamera(const MethodTraits& m, const Camera& c) {
  constexpr float kReach = 1e18f;
  auto within = [&](const glm::vec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
           std::fabs(p.x) <= kReach && std::fabs(p.y) <= kReach && std::fabs(p.z) <= kReach;
  };
  auto text = [](const glm::vec3& p) {
    char out[96];
    std::snprintf(out, sizeof(out), "(%g, %g, %g)", p.x, p.y, p.z);
    return std::string(out);
  };
  const char* problem = nullptr;
  std::string where;
  if (!within(c.eye))
    problem = "eye", where = text(c.eye);
  else if (!within(c.target))
    problem = "target", where = text(c.target);
  if (problem)
    throw Error(std::string(m.name) + ": the view's " + problem + " is at " + where +
                ", not within +-1e18 (a scene or view too large to frame; scale it down)");
  // An eye on the target (an orbit distance so small that they round together) looks nowhere.
  const glm::vec3 forward = glm::normalize(c.target - c.eye);
  if (!std::isfinite(forward.x) || !std::isfinite(forward.y) || !std::isfinite(forward.z))
    throw Error(std::string(m.name) + ": the view's eye " + text(c.eye) +
                " is on its target (a view distance too small to tell them apart)");
  if (!within(c.up) || glm::length(c.up) <= 0.0f)
    throw Error(std::string(m.name) + ": the view's up direction " + text(c.up) +
                " is not a finite non-zero vector");
  if (!(c.near_distance > 0.0f && std::isfinite(c.near_distance)) ||
      (c.projection == Projection::Perspective && !(c.fov_y_deg > 0.0f && c.fov_y_deg < 180.0f)) ||
      (c.projection == Projection::Orthographic &&
       !(c.ortho_height > 0.0f && c.ortho_height <= 2.0f * kReach)))
    throw Error(std::string(m.name) + ": the view's field of view or near plane is not finite");
}

}  // namespace

void checkSettings(const MethodTraits& m, const FrameSettings& s) {
  validateFrameSize(s.width, s.height);
  checkCamera(m, s.camera);
  checkFrameCount(s.frames, std::string(m.name) + ": frames");
  if (!std::isfinite(s.orbit_deg) || std::fabs(s.orbit_deg) > 360.0f)
    throw Error(std::string(m.name) + ": the orbit step must be between -360 and 360 degrees");
  if (s.orbit_deg != 0.0f && s.partial)
    throw Error(std::string(m.name) + ": a distributed frame has a still view (no orbit)");
  if (!m.renders(s.effect)) {
    std::string which;
    for (const MethodTraits& o : kMethods)
      if (o.renders(s.effect)) which += std::string(which.empty() ? "" : ", ") + o.name;
    throw Error(std::string(m.name) + " does not render " + effectName(s.effect) +
                " (methods that do: " + which + ")");
  }
  if (m.takes_k && (s.k < 1 || s.k > 256))
    throw Error(std::string(m.name) + ": the per-pixel budget k = " + std::to_string(s.k) +
                " must be between 1 and 256");
  if (!(s.sigma >= 0.0f && std::isfinite(s.sigma)))
    throw Error(std::string(m.name) + ": sigma must be a finite number >= 0");
  if ((s.partial || s.octree_leaves) && m.method != Method::Octree)
    throw Error(std::string(m.name) +
                " does not render a share of a distributed frame (octree does)");
}

std::unique_ptr<MethodRenderer> makeRenderer(Method method, const DeviceOptions& device) {
  const MethodTraits& info = methodInfo(method);
  return std::make_unique<CheckedRenderer>(info, info.make(device));
}

FrameTimes summarizeTimes(std::vector<double> ms) {
  FrameTimes t;
  t.runs = int(ms.size());
  if (ms.empty()) return t;
  std::sort(ms.begin(), ms.end());
  t.min = ms.front();
  t.max = ms.back();
  const size_t n = ms.size();
  t.median = n % 2 ? ms[n / 2] : 0.5 * (ms[n / 2 - 1] + ms[n / 2]);
  double sum = 0.0;
  for (double v : ms) sum += v;
  t.mean = sum / double(n);
  return t;
}

}  // namespace strata

namespace strata {

Effect parseEffect(const std::string& name) {
  if (name == "transparency") return Effect::Transparency;
  if (name == "translucency") return Effect::Translucency;
  throw Error("unknown effect '" + name + "' (known: transparency, translucency)");
}

std::string effectName(Effect e) {
  return e == Effect::Translucency ? "translucency" : "transparency";
}

}  // namespace strata
