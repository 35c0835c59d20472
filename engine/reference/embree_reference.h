// The Embree reference renderer: exact all-hit ray casting on the CPU with Intel Embree. It is the
// independent oracle of the image tests (it shares no code with the OpenCL pipeline beyond the
// shading rules of strata_shared.h) and the CPU peer of the benchmarks.
//
// Transparency: every hit along the primary ray of a pixel centre is gathered in one traversal
// (an intersection filter records and rejects each hit), deduplicated by triangle, sorted by
// (distance, triangle id) and composited front to back over the background. FrameSettings::effect
// picks the compositing: Transparency, "under" of flat-shaded colour and opacity; Translucency,
// the rule of strata_shared.h (Schlick reflection of the flat-shaded colour at every hit,
// Beer-Lambert absorption with settings.sigma per world unit along the ray between a front-facing
// hit and the back-facing hit that leaves; opacity unused). Opaque: the nearest hit, ties broken
// by the smaller triangle id; it ignores the effect. The BVH is kept across render() calls while
// the geometry's triangles stay the same (compared by content, so a changed mesh is never traced
// with a stale BVH). No Embree types appear here.
//
// Textured geometry (WorldGeometry::textured()): a fragment's flat-shaded colour is multiplied by
// the reference texel of its triangle at the pixel (referenceTexel, engine/frontend/texture_shading.h:
// RGB multiplies the colour, A the opacity), in every mode and effect; there is one ray per pixel
// centre, so every fragment along a pixel's ray uses that pixel's texture coordinates. Opaque
// and translucency use only the RGB (they ignore opacity). Untextured geometry takes the
// flat-shaded path unchanged.
//
// Where a ray passes exactly through an edge or vertex shared by neighbouring triangles, Embree's
// watertight test reports every one of them; the reference counts such a crossing once (keeping
// the smallest triangle id), as a rasterizer's fill rule would.
//
// Stats: fragments = hits after deduplication (opaque: pixels covered), max_depth_complexity =
// most hits at one pixel, stage_ms: "bvh_build" (time this call spent building or checking the
// BVH, not part of frame_ms), "shade" (per-triangle flat shading), "trace" (rays, sort,
// composite, texture sampling) and, for textured geometry, "texture_build" (the reference mip
// chains, once per call, not part of frame_ms). A renderer renders one frame at a time (it is not
// reentrant).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <glm/glm.hpp>

#include "engine/renderer.h"

namespace strata {

enum class EmbreeMode { Transparency, Opaque };

// How primary rays are handed to Embree. Packets trace coherent pixel blocks (2x2, 4x2, 4x4);
// Stream passes a whole 16x16 tile to rtcIntersect1M.
enum class EmbreeQuery { Auto, Single, Packet4, Packet8, Packet16, Stream };

struct EmbreeOptions {
  EmbreeMode mode = EmbreeMode::Transparency;
  EmbreeQuery query = EmbreeQuery::Auto;  // Auto: the fastest measured on the project machines
  int threads = 0;                        // render threads; 0: every hardware thread
  // RTC_SCENE_FLAG_ROBUST: watertight edge tests (no ray slips between two triangles sharing an
  // edge). Off: Embree's faster, non-watertight test and a spatial-split BVH, which reports some
  // triangles more than once (removed here).
  bool robust = true;
};

std::unique_ptr<MethodRenderer> makeEmbreeRenderer(EmbreeMode mode = EmbreeMode::Transparency);
std::unique_ptr<MethodRenderer> makeEmbreeRenderer(const EmbreeOptions& options);

// ---- Ray picks: the reference of ID picking (engine/features/picking.h)
// -----------------------------------

// One hit along a pixel's primary ray.
struct EmbreeRayHit {
  uint32_t triangle = 0;
  float t = 0.0f;      // ray parameter (the ray direction has unit length)
  float depth = 0.0f;  // view distance along the camera's forward axis (what the rasterizer keeps)
};

// Casts the primary ray of each pixel centre (the renderer's own rays, from the near plane) with
// the transparency reference's all-hit traversal and returns the hits nearest first, sorted by
// (t, triangle id) and deduplicated by the same rules as that reference: a triangle reported
// twice counts once, and a crossing of an edge or vertex shared by neighbouring triangles counts
// once (keeping the smaller triangle id). all_hits false: only the nearest hit (the first of that
// list). A pixel outside the image has no hits. The BVH is kept across calls while the triangles
// stay the same; rays are spread over `threads` threads (0: every hardware thread).
class EmbreeRayPicker {
 public:
  explicit EmbreeRayPicker(int threads = 0);
  ~EmbreeRayPicker();
  EmbreeRayPicker(const EmbreeRayPicker&) = delete;
  EmbreeRayPicker& operator=(const EmbreeRayPicker&) = delete;

  std::vector<std::vector<EmbreeRayHit>> pick(const WorldGeometry& geometry,
                                              const FrameSettings& settings,
                                              const std::vector<glm::ivec2>& pixels, bool all_hits);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// One ray pick at pixel (x, y) (builds the BVH each call: for repeated picks keep an
// EmbreeRayPicker).
std::vector<EmbreeRayHit> embreePickRay(const WorldGeometry& geometry,
                                        const FrameSettings& settings, int x, int y, bool all_hits);

}  // namespace strata
