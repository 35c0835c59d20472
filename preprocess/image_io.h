// RGBA8 images: PNG/EXR output through OpenImageIO (written to a temporary name, then renamed),
// input of any format OpenImageIO reads, and the comparison metrics of `strata diff`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "strata/strata.h"

namespace strata {

// Image (RGBA8, row-major) is public: include/strata/strata.h.

// Writes atomically: a temporary file beside `path`, renamed over it on success. Throws Error
// naming the path on failure; never leaves a partial file at `path`.
void writeImage(const Image& image, const std::string& path);
Image readImage(const std::string& path);

// ImageDiff, compareImages and differenceImage (the metrics of `strata diff`) are public:
// include/strata/strata.h.

}  // namespace strata
