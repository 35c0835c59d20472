// OpenCL runtime: device choice, extension check, program build + cache, timed launches.
// Private to the library: public headers never include this (it pulls in CL/opencl.hpp).
#pragma once

#define CL_HPP_ENABLE_EXCEPTIONS
#define CL_HPP_TARGET_OPENCL_VERSION 120
#define CL_HPP_MINIMUM_OPENCL_VERSION 120
#include <CL/opencl.hpp>

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "strata/error.h"

namespace strata {

struct DeviceInfo {
  int index = 0;  // position in the global enumeration (platforms in order, then devices)
  std::string platform, name, vendor, version, driver_version;
  bool is_gpu = false;
  bool little_endian = true;
  uint64_t global_mem_bytes = 0, max_alloc_bytes = 0;
  size_t max_work_group_size = 0;
  std::vector<std::string> extensions;
  bool hasExtension(const std::string& e) const;
  // Whether the device has the 64-bit atomics (requiredExtensions()) that the work-group forms
  // of the tile kernels use.
  bool hasInt64Atomics() const;
  // PoCL, whose CPU devices run a work-group's items one after another.
  bool isPocl() const;
  // The Oclgrind simulator, whose runtime is not thread-safe: OpenCL calls from two host threads
  // at once can crash it.
  bool isOclgrind() const;
  // Mesa's llvmpipe, which ends a kernel's loops after 65,535 iterations per work-item.
  bool isLlvmpipe() const;
  std::string label() const;  // "NAME (PLATFORM, DRIVER)"
};

// The 64-bit atomic extensions that the work-group forms of the tile kernels and the 64-bit
// frame counters use. A device without them runs the path without 64-bit atomics (common.cl).
const std::vector<std::string>& requiredExtensions();

// Which path a runtime compiles: "auto" (64-bit atomics where the device has them), "64"
// or "32" (the path without 64-bit atomics, on any device). Throws Error for another name.
void checkAtomicsChoice(const std::string& choice);
// Whether `choice` on `device` runs with 64-bit atomics; throws Error naming the device and the
// reason where it cannot run at all ("64" without the extensions, "32" or "auto" on a big-endian
// device, whose counters are not two little-endian words).
bool useInt64Atomics(const DeviceInfo& device, const std::string& choice);

// Throws Error naming the first required extension the device lacks.
void checkRequiredExtensions(const DeviceInfo& device);

// Every OpenCL device of every platform. Throws Error if no platform is installed.
std::vector<DeviceInfo> listDevices();
// The platforms that show no device (rusticl without RUSTICL_ENABLE, Clover without a GPU),
// each with a hint of how to give it one where one is known.
struct EmptyPlatform {
  std::string name, hint;
};
std::vector<EmptyPlatform> platformsWithoutDevices();

// Picks a device: `spec` is an index or a case-insensitive substring of the device or platform
// name; empty: the first GPU, else the first device. (The library reads no environment: the CLI
// passes STRATA_DEVICE in.)
DeviceInfo chooseDevice(const std::string& spec);
// Why no device was found, with the advice that fits: an OpenCL driver to install, or a cache
// folder the driver cannot use.
std::string noDeviceMessage();

// Name of an OpenCL error code (CL_OUT_OF_RESOURCES, ...).
const char* clErrorName(cl_int code);
// Converts a cl::Error into an Error naming the call and the code.
[[noreturn]] void rethrowClError(const cl::Error& e, const std::string& context = "");

// One device, its context, an in-order profiling queue and the program built from the embedded
// kernels. Renderers that use the same device share one runtime (the program is built once)
// and own it together: the last owner to go releases every OpenCL object, so nothing is left
// for static destructors after main returns.
class ClRuntime {
 public:
  // `atomics`: checkAtomicsChoice; runtimes of one device and path are shared.
  static std::shared_ptr<ClRuntime> acquire(const std::string& spec,
                                            const std::string& atomics = "auto");
  ~ClRuntime();
  ClRuntime(const ClRuntime&) = delete;
  ClRuntime& operator=(const ClRuntime&) = delete;

  const DeviceInfo& info() const { return info_; }
  // Whether the program was built with 64-bit atomics; without, only the serial forms of the
  // tile kernels may run (FrameRunner::serialTilesFor).
  bool int64Atomics() const { return int64_atomics_; }
  cl::Context& context() { return context_; }
  cl::Device& device() { return device_; }
  cl::CommandQueue& queue() { return queue_; }
  cl::Kernel kernel(const std::string& name);
  // Enqueues setting the first `bytes` (a multiple of 4) of `b` to the 32-bit `pattern`, with a
  // kernel (fill.cl); errors name `purpose`.
  void fill(cl::Buffer& b, uint32_t pattern, size_t bytes, const std::string& purpose,
            cl::Event* event = nullptr);

  // Allocates a device buffer; throws Error naming the size and purpose on failure, also when
  // the buffers alive on the device (every renderer's) would exceed its global memory.
  // On a CPU device (PoCL) every buffer lives in host memory allocated here (one of
  // kHugePageBufferBytes or more on huge pages), so that memory the host cannot give is an
  // OutOfMemory from this call, never an abort inside the driver later.
  cl::Buffer allocate(size_t bytes, const std::string& purpose,
                      cl_mem_flags flags = CL_MEM_READ_WRITE);
  static constexpr size_t kHugePageBytes = size_t(2) << 20;
  static constexpr size_t kHugePageBufferBytes = size_t(4) << 20;
  // The smaller buffers of a CPU device, in memory of our own: PoCL's largest alignment.
  static constexpr size_t kHostBufferAlignment = 128;
  // Bytes of the buffers allocate() made that are still alive.
  uint64_t liveBytes() const { return *live_bytes_; }
  // The same over every runtime of the process (every device).
  static uint64_t liveBytesOfAllDevices();

 private:
  ClRuntime(const DeviceInfo& info, bool int64_atomics);
  void buildProgram();

  DeviceInfo info_;
  bool int64_atomics_ = true;
  cl::Platform platform_;
  cl::Device device_;
  cl::Context context_;
  cl::CommandQueue queue_;
  cl::Program program_;
  std::mutex fill_mutex_;  // fill_kernel_'s arguments
  cl::Kernel fill_kernel_;
  // Counted down by each buffer's destructor callback (which may outlive this object).
  std::shared_ptr<std::atomic<uint64_t>> live_bytes_ = std::make_shared<std::atomic<uint64_t>>(0);
};

// Records named launches of one frame and sums their device times per name.
class LaunchTimer {
 public:
  explicit LaunchTimer(ClRuntime& runtime) : runtime_(runtime) {}
  // Enqueues a 1-D or 2-D range kernel and records its event under `name`.
  void launch(const std::string& name, cl::Kernel& k, const cl::NDRange& global,
              const cl::NDRange& local, const cl::NDRange& offset = cl::NullRange);
  // Records a fill (ClRuntime::fill) as a launch named `name`.
  void fill(const std::string& name, cl::Buffer& b, uint32_t pattern, size_t bytes);
  uint64_t launches() const { return events_.size(); }
  // Device time per name in milliseconds; call after the queue is finished.
  std::map<std::string, double> stageTimes() const;
  // Device time and launch count per "stage/kernel function" ("stage/fill" for fills), to see
  // which kernel of a stage costs what; call after the queue is finished.
  struct KernelTime {
    double ms = 0.0;
    uint64_t launches = 0;
  };
  std::map<std::string, KernelTime> kernelTimes() const;
  void clear() { events_.clear(); }

 private:
  struct Launch {
    std::string stage;
    cl_kernel kernel;  // null for a fill; the caller's kernel outlives the frame's launches
    cl::Event event;
  };
  static double eventMs(const cl::Event& ev);
  ClRuntime& runtime_;
  std::vector<Launch> events_;
};

}  // namespace strata
