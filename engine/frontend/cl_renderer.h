// The OpenCL rasterization methods (opaque visibility buffer, per-pixel linked lists).
#pragma once

#include <memory>

#include "engine/renderer.h"

namespace strata {

class ClMethod;
// A renderer of one method on the shared OpenCL front end (engine/frontend/cl_pipeline.h).
std::unique_ptr<MethodRenderer> makeClRenderer(Method method, std::unique_ptr<ClMethod> impl,
                                               const DeviceOptions& device);

}  // namespace strata
