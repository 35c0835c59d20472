// `strata info`: OpenCL platforms and devices, the chosen device, the extensions strata uses and
// whether each method runs there.
#pragma once

#include "engine/renderer.h"

namespace strata {

// Prints the report to stdout, rendering a small frame of builtin:demo with every method on the
// chosen device (which compiles the kernels if they are not cached); returns the process exit
// code: non-zero if no method of the OpenCL ones runs there.
int printDeviceReport(const DeviceOptions& device);

}  // namespace strata
