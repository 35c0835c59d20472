// libFuzzer target: one scene file format read through loadSceneFile, as the command line reads
// it (from a file, with its companions beside it). STRATA_FUZZ_FILE_NAME is the main file's name;
// its extension chooses the reader.
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz/fuzz_support.h"
#include "preprocess/mesh_loader.h"
#include "strata/error.h"

#ifndef STRATA_FUZZ_FILE_NAME
#error "STRATA_FUZZ_FILE_NAME must name the main file (scene.obj, scene.gltf, ...)"
#endif

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::filesystem::path path = strata::fuzz::writeInput(input, STRATA_FUZZ_FILE_NAME);
  try {
    const strata::Scene scene = strata::loadSceneFile(path.string());
    (void)scene;
  } catch (const strata::Error& e) {
    strata::fuzz::checkErrorMessage(e.what(), strata::fuzz::workFolder().string());
  }
  return 0;
}
