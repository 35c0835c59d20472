#include "engine/report/device_report.h"

#include <cstdio>
#include <memory>

#include "host/cl_runtime.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

int printDeviceReport(const DeviceOptions& options) {
  const std::vector<DeviceInfo> devices = listDevices();
  if (devices.empty()) throw Error(noDeviceMessage());
  const DeviceInfo chosen = chooseDevice(options.device);
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
  for (const std::string& e : requiredExtensions())
    std::printf("  %-36s %s\n", e.c_str(),
                chosen.hasExtension(e) ? "present"
                                       : "missing (the path without 64-bit atomics runs instead)");
  std::fflush(stdout);

  // Whether each method runs: one 16x16 frame of the demo scene each, on the path --atomics
  // chooses. A method that cannot run says why (the device, its local memory, a driver fault).
  bool int64 = false;
  std::string why_not;
  try {
    int64 = useInt64Atomics(chosen, options.atomics);
  } catch (const Error& e) {
    why_not = e.what();
  }
  if (chosen.isLlvmpipe())
    std::printf(
        "note: llvmpipe ends a kernel's loops after 65,535 iterations per work-item, so "
        "large frames and scenes lose fragments there (docs/results/devices.md)\n");
  std::printf("methods on this device (%s):\n",
              !why_not.empty() ? "none can run"
              : int64          ? "with 64-bit atomics"
                               : "the path without 64-bit atomics: serial tile kernels");
  const Scene scene = loadScene("builtin:demo");
  const WorldGeometry geometry = WorldGeometry::fromScene(scene, -1.0f);
  FrameSettings settings;
  settings.width = settings.height = 16;
  settings.camera = Camera::orbit(scene.boundingSphere(), scene.default_view.value_or(OrbitView{}),
                                  scene.default_projection.value_or(Projection::Perspective));
  int running = 0;
  for (const MethodTraits& t : methodRegistry()) {
    std::string verdict;
    if (!t.opencl) {
      verdict = "runs on the host (the CPU reference)";
    } else if (!why_not.empty()) {
      verdict = "cannot run: " + why_not;
    } else {
      try {
        makeRenderer(t.method, DeviceOptions{std::to_string(chosen.index), options.atomics})
            ->render(geometry, settings);
        verdict = int64 ? "runs" : "runs without 64-bit atomics";
        ++running;
      } catch (const Error& e) {
        verdict = std::string("cannot run: ") + e.what();
      }
    }
    std::printf("  %-10s %s\n", t.name, verdict.c_str());
    std::fflush(stdout);
  }
  return running > 0 ? 0 : 1;
}

}  // namespace strata
