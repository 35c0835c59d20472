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

struct ImageDiff {
  double psnr = 0.0;      // dB over RGB; infinity when identical
  int max_abs = 0;        // largest channel difference, 0..255
  double mean_abs = 0.0;  // mean channel difference over RGB, 0..255
  double within_1 = 0.0;  // fraction of pixels whose RGB channels all differ by <= 1
  double within_2 = 0.0;  // ... by <= 2
  uint64_t pixels = 0;
};

// Compares RGB channels (alpha is ignored: every renderer writes opaque images). Throws Error if
// the sizes differ.
ImageDiff compareImages(const Image& a, const Image& b);
// A visual difference image: |a - b| per channel, amplified x8, on black.
Image differenceImage(const Image& a, const Image& b);

}  // namespace strata
