// The OpenCL rasterization methods (opaque visibility buffer, per-pixel linked lists).
#pragma once

#include <memory>

#include "engine/renderer.h"

namespace strata {

std::unique_ptr<Renderer> makeClRenderer(Method method, const DeviceOptions& device);

}  // namespace strata
