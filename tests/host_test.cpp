// host/: device choice, extension check, program cache key, error naming.
#include <algorithm>
#include <cstdlib>

#include <gtest/gtest.h>

#include "host/cl_runtime.h"

namespace strata {
namespace {

TEST(Host, ListsAtLeastOneDeviceWithTheRequiredExtensions) {
  const std::vector<DeviceInfo> devices = listDevices();
  ASSERT_FALSE(devices.empty());
  const DeviceInfo chosen = chooseDevice("");
  EXPECT_NO_THROW(checkRequiredExtensions(chosen));
}

TEST(Host, MissingExtensionIsNamed) {
  DeviceInfo d = chooseDevice("");
  d.extensions.erase(std::remove(d.extensions.begin(), d.extensions.end(),
                                 "cl_khr_int64_extended_atomics"),
                     d.extensions.end());
  try {
    checkRequiredExtensions(d);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cl_khr_int64_extended_atomics"), std::string::npos);
  }
}

TEST(Host, DeviceChoiceByIndexNameAndEnvironment) {
  const std::vector<DeviceInfo> devices = listDevices();
  EXPECT_EQ(chooseDevice("0").index, 0);
  EXPECT_EQ(chooseDevice(devices[0].name.substr(0, 4)).index, devices[0].index);
  EXPECT_THROW(chooseDevice("99"), Error);
  EXPECT_THROW(chooseDevice("surely-no-such-device"), Error);
  setenv("STRATA_DEVICE", "surely-no-such-device", 1);
  EXPECT_THROW(chooseDevice(""), Error);
  unsetenv("STRATA_DEVICE");
  EXPECT_NO_THROW(chooseDevice(""));
}

TEST(Host, ClErrorsNameTheCallAndTheCode) {
  try {
    rethrowClError(cl::Error(CL_OUT_OF_RESOURCES, "clEnqueueNDRangeKernel"), "launching raster");
    FAIL();
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("clEnqueueNDRangeKernel"), std::string::npos) << m;
    EXPECT_NE(m.find("CL_OUT_OF_RESOURCES"), std::string::npos) << m;
    EXPECT_NE(m.find("launching raster"), std::string::npos) << m;
  }
}

TEST(Host, OversizedAllocationIsRefusedWithTheSize) {
  ClRuntime& rt = ClRuntime::forDevice("");
  const size_t too_big = size_t(rt.info().max_alloc_bytes) + 1;
  try {
    rt.allocate(too_big, "a test buffer");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(std::to_string(too_big)), std::string::npos) << e.what();
  }
}

TEST(Host, CacheKeyHashIsStable) {
  EXPECT_EQ(fnv1a64(""), 14695981039346656037ull);
  EXPECT_EQ(fnv1a64("a"), 0xaf63dc4c8601ec8cull);
  EXPECT_NE(fnv1a64("kernel A"), fnv1a64("kernel B"));
}

}  // namespace
}  // namespace strata
