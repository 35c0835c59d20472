// RGBA8 images: PNG/EXR output through OpenImageIO (written to a temporary name, then renamed),
// input of any format OpenImageIO reads, and the comparison metrics of `strata diff`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace strata {

struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;  // row-major, top row first, 4 bytes per pixel

  Image() = default;
  Image(int w, int h) : width(w), height(h), rgba(size_t(w) * size_t(h) * 4, 0) {}
  uint8_t* pixel(int x, int y) { return &rgba[(size_t(y) * width + x) * 4]; }
  const uint8_t* pixel(int x, int y) const { return &rgba[(size_t(y) * width + x) * 4]; }
};

// Writes atomically: a temporary file beside `path`, renamed over it on success. Throws Error
// naming the path on failure; never leaves a partial file at `path`.
void writeImage(const Image& image, const std::string& path);
Image readImage(const std::string& path);

struct ImageDiff {
  double psnr = 0.0;           // dB over RGB; infinity when identical
  int max_abs = 0;             // largest channel difference, 0..255
  double mean_abs = 0.0;       // mean channel difference over RGB, 0..255
  double within_1 = 0.0;       // fraction of pixels whose RGB channels all differ by <= 1
  double within_2 = 0.0;       // ... by <= 2
  uint64_t pixels = 0;
};

// Compares RGB channels (alpha is ignored: every renderer writes opaque images). Throws Error if
// the sizes differ.
ImageDiff compareImages(const Image& a, const Image& b);
// A visual difference image: |a - b| per channel, amplified x8, on black.
Image differenceImage(const Image& a, const Image& b);

}  // namespace strata
