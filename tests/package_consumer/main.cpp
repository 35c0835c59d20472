// Renders builtin:demo with the headline method and the Embree reference through the public API
// only, and exits non-zero unless both images agree and a bad input is a strata::Error.
#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include <strata/strata.h>

int main() {
  try {
    strata::Device device = strata::Device::open();
    strata::Geometry demo = strata::Geometry::load("builtin:demo");
    strata::Renderer cells(device, "cells"), embree(device, "embree");
    cells.setGeometry(demo);
    embree.setGeometry(demo);
    strata::View view;
    view.width = view.height = 96;
    const strata::Frame a = cells.render(view), b = embree.render(view);
    // Exact within 2/255 (the project's image-test tolerance: 99.5% of pixels, silhouettes
    // excepted).
    size_t close = 0;
    const size_t pixels = a.image.rgba.size() / 4;
    for (size_t p = 0; p < pixels; ++p) {
      int worst = 0;
      for (int c = 0; c < 3; ++c)
        worst =
            std::max(worst, std::abs(int(a.image.rgba[4 * p + c]) - int(b.image.rgba[4 * p + c])));
      close += worst <= 2;
    }
    const double within = double(close) / double(pixels);
    std::printf("%s: %llu fragments, %.2f%% of pixels within 2/255 of embree\n",
                device.label().c_str(), (unsigned long long)a.fragments, 100.0 * within);
    if (a.fragments == 0 || within < 0.995) return 1;
    try {
      const uint32_t bad[3] = {0, 1, 7};
      const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
      strata::Geometry::fromArrays(p, 3, bad, 1);
      return 1;
    } catch (const strata::Error& e) {
      std::printf("bad input: %s\n", e.what());
    }
    return 0;
  } catch (const strata::Error& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
}
