// Per-frame view constants in the layout the kernels read (StViewConstants), built from the
// camera and frame settings. Used by the OpenCL renderer and by the Embree reference so both
// apply the same background and light.
#pragma once

#include <glm/glm.hpp>

#include "engine/renderer.h"
#include "kernels/strata_shared.h"

namespace strata {

StViewConstants makeViewConstants(const FrameSettings& settings);

// A moving camera: replaces `current` by the view constants of the frame's settings (keeping
// its `textured` flag) and says whether they changed, so per-view uploads happen only then.
bool updateViewConstants(StViewConstants& current, const FrameSettings& frame);

// Checks a frame size; throws Error naming the problem (zero, negative or beyond the limits).
void validateFrameSize(int width, int height);

// The pixels the world-space box [lo, hi] may cover in view v, two pixels wider than its
// projection for the raster's snapping and rounding: the whole image when a corner is not in
// front of the near plane or the box is not finite, an empty rectangle (x > z) when it lies
// off the image.
glm::ivec4 boxPixelRect(const glm::vec3& lo, const glm::vec3& hi, const StViewConstants& v);

}  // namespace strata
