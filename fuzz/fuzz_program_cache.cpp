// libFuzzer target: the framing of the OpenCL program cache (magic, length, checksum). What it
// accepts is handed to the OpenCL driver, so it must be exactly the stored payload.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

#include "preprocess/core/files.h"
#include "preprocess/core/hash.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static constexpr char kMagic[8] = {'S', 'T', 'R', 'A', 'T', 'A', 'P', 'B'};
  std::string file(reinterpret_cast<const char*>(data), size);
  // As for the other caches, fix the checksum so the length checks are what is fuzzed.
  if (file.size() >= 24) {
    const uint64_t sum = strata::fnv1a64(std::string_view(file).substr(24));
    std::memcpy(file.data() + 16, &sum, 8);
  }
  const std::optional<std::string_view> payload = strata::unframeCachePayload(kMagic, file);
  if (!payload) return 0;
  if (payload->empty() || payload->size() + 24 != file.size() ||
      strata::frameCachePayload(kMagic, *payload) != file)
    std::abort();
  return 0;
}
