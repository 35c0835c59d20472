// `strata info`: OpenCL platforms and devices, the chosen device, the extensions strata uses.
#pragma once

#include <string>

namespace strata {

// Prints the report to stdout; returns the process exit code (non-zero if the chosen device
// lacks a required extension).
int printDeviceReport(const std::string& device_spec);

}  // namespace strata
