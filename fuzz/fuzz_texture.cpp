// libFuzzer target: texture decoding from memory (the path of embedded glTF images; texture
// files take the same decoder after the file checks).
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_support.h"
#include "preprocess/texture_loader.h"
#include "strata/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    const auto texture = strata::loadTextureMemory(data, size, "fuzz-texture");
    (void)texture;
  } catch (const strata::Error& e) {
    strata::fuzz::checkErrorMessage(e.what(), "fuzz-texture");
  }
  return 0;
}
