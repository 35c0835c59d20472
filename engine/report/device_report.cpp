#include "engine/report/device_report.h"

#include <cstdio>

#include "host/cl_runtime.h"

namespace strata {

int printDeviceReport(const std::string& spec) {
  const std::vector<DeviceInfo> devices = listDevices();
  if (devices.empty()) throw Error(noDeviceMessage());
  const DeviceInfo chosen = chooseDevice(spec);
  std::printf("OpenCL devices:\n");
  for (const DeviceInfo& d : devices) {
    std::printf(
        "  %c [%d] %s\n      platform %s, %s, driver %s, %s\n      %.1f GiB global memory, "
        "largest allocation %.1f GiB, work-group up to %zu\n",
        d.index == chosen.index ? '*' : ' ', d.index, d.name.c_str(), d.platform.c_str(),
        d.version.c_str(), d.driver_version.c_str(), d.is_gpu ? "GPU" : "not a GPU",
        double(d.global_mem_bytes) / (1 << 30), double(d.max_alloc_bytes) / (1 << 30),
        d.max_work_group_size);
  }
  for (const EmptyPlatform& p : platformsWithoutDevices())
    std::printf("    platform %s shows no device%s%s\n", p.name.c_str(), p.hint.empty() ? "" : ": ",
                p.hint.c_str());
  std::printf("chosen device: [%d] %s (pick another with --device or STRATA_DEVICE)\n",
              chosen.index, chosen.label().c_str());
  std::printf("extensions the kernels use:\n");
  int missing = 0;
  for (const std::string& e : requiredExtensions()) {
    const bool ok = chosen.hasExtension(e);
    missing += !ok;
    std::printf("  %-36s %s\n", e.c_str(), ok ? "present" : "MISSING");
  }
  return missing ? 1 : 0;
}

}  // namespace strata
