// host/: device choice, extension check, program cache key, error naming.
#include <algorithm>
#include <cstdlib>

#include <gtest/gtest.h>

#include "engine/renderer.h"
#include "host/cl_runtime.h"
#include "preprocess/core/hash.h"

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
  d.extensions.erase(
      std::remove(d.extensions.begin(), d.extensions.end(), "cl_khr_int64_extended_atomics"),
      d.extensions.end());
  try {
    checkRequiredExtensions(d);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cl_khr_int64_extended_atomics"), std::string::npos);
  }
}

TEST(Host, LiveDeviceBytesAreCounted) {
  std::shared_ptr<ClRuntime> rt = ClRuntime::acquire("");
  rt->queue().finish();
  const uint64_t before = rt->liveBytes();
  {
    cl::Buffer a = rt->allocate(1 << 20, "test buffer");
    cl::Buffer b = rt->allocate(3 << 20, "test buffer");
    EXPECT_EQ(rt->liveBytes(), before + (4u << 20));
  }
  rt->queue().finish();
  EXPECT_EQ(rt->liveBytes(), before);  // released buffers no longer count
  // (The refusal past the device's memory is tested under Oclgrind with a 1 MB device.)
}

TEST(Host, DeviceChoiceByIndexAndName) {
  const std::vector<DeviceInfo> devices = listDevices();
  EXPECT_EQ(chooseDevice("0").index, 0);
  EXPECT_EQ(chooseDevice(devices[0].name.substr(0, 4)).index, devices[0].index);
  EXPECT_THROW(chooseDevice("99"), Error);
  EXPECT_EQ(chooseDevice("000").index, 0);
  // An index past any integer type is one that does not exist, not an internal error.
  try {
    chooseDevice("99999999999999999999999");
    ADD_FAILURE() << "a huge device index was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
  }
  EXPECT_THROW(chooseDevice("surely-no-such-device"), Error);
  // The library reads no environment: STRATA_DEVICE is the command line's business.
  setenv("STRATA_DEVICE", "surely-no-such-device", 1);
  EXPECT_NO_THROW(chooseDevice(""));
  unsetenv("STRATA_DEVICE");
}

TEST(Host, RuntimesAreSharedWhileOwnedAndReleasedWithTheLastOwner) {
  std::weak_ptr<ClRuntime> seen;
  long owners_before = 0;
  {
    std::shared_ptr<ClRuntime> a = ClRuntime::acquire("");
    owners_before = a.use_count();
    std::shared_ptr<ClRuntime> b = ClRuntime::acquire("");
    EXPECT_EQ(a.get(), b.get());
    EXPECT_EQ(a.use_count(), owners_before + 1);
    {
      // A renderer owns the runtime of its device while it lives, and only then.
      const std::unique_ptr<MethodRenderer> r = makeRenderer(Method::Ppll);
      EXPECT_EQ(a.use_count(), owners_before + 2);
    }
    EXPECT_EQ(a.use_count(), owners_before + 1);
    seen = a;
  }
  // What is left is the test environment's own reference (below), if any.
  EXPECT_EQ(seen.use_count(), owners_before - 1);
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
  const std::shared_ptr<ClRuntime> runtime = ClRuntime::acquire("");
  ClRuntime& rt = *runtime;
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

namespace {

// Every test of this binary renders on the default device: keep its runtime (context, built
// program) for the whole run rather than rebuilding it for every renderer. Released in
// TearDown, inside RUN_ALL_TESTS, so before main returns.
class DefaultDeviceEnvironment : public ::testing::Environment {
 public:
  void SetUp() override { runtime_ = strata::ClRuntime::acquire(""); }
  void TearDown() override { runtime_.reset(); }

 private:
  std::shared_ptr<strata::ClRuntime> runtime_;
};

[[maybe_unused]] ::testing::Environment* const kDefaultDevice =
    ::testing::AddGlobalTestEnvironment(new DefaultDeviceEnvironment);

}  // namespace
