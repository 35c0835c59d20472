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
// Where a ray passes exactly through an edge or vertex shared by neighbouring triangles, Embree's
// watertight test reports every one of them; the reference counts such a crossing once (keeping
// the smallest triangle id), as a rasterizer's fill rule would.
//
// Stats: fragments = hits after deduplication (opaque: pixels covered), max_depth_complexity =
// most hits at one pixel, stage_ms: "bvh_build" (time this call spent building or checking the
// BVH, not part of frame_ms), "shade" (per-triangle flat shading), "trace" (rays, sort,
// composite). A renderer renders one frame at a time (it is not reentrant).
#pragma once

#include <memory>

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

std::unique_ptr<Renderer> makeEmbreeRenderer(EmbreeMode mode = EmbreeMode::Transparency);
std::unique_ptr<Renderer> makeEmbreeRenderer(const EmbreeOptions& options);

}  // namespace strata
