// A mesh file to images through the public C++ API: the headline method and the Embree
// reference from the same view, both saved, the share of pixels within 2/255 printed.
//
//   render_mesh [MESH] [OUT_PREFIX]      (defaults: builtin:demo, "render")
#include <strata/strata.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  const std::string mesh_path = argc > 1 ? argv[1] : "builtin:demo";
  const std::string prefix = argc > 2 ? argv[2] : "render";
  try {
    strata::Device device = strata::Device::open();  // a GPU, else the first device
    strata::Geometry mesh = strata::Geometry::load(mesh_path);
    strata::View view = mesh.naturalView(256, 256);  // the scene's own view
    strata::Frame frames[2];
    const char* methods[2] = {"cells", "embree"};
    for (int i = 0; i < 2; ++i) {
      strata::Renderer renderer(device, methods[i]);
      renderer.setGeometry(mesh);
      frames[i] = renderer.render(view);
      strata::saveImage(prefix + "-" + methods[i] + ".png", frames[i].image);
    }
    size_t close = 0;
    const size_t pixels = frames[0].image.rgba.size() / 4;
    for (size_t p = 0; p < pixels; ++p) {
      int worst = 0;
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs(int(frames[0].image.rgba[4 * p + c]) -
                                         int(frames[1].image.rgba[4 * p + c])));
      close += worst <= 2;
    }
    std::printf("%s on %s: %.2f ms, %llu fragments, depth %llu; %.2f%% of pixels within 2/255 "
                "of embree\n",
                mesh.source().c_str(), device.label().c_str(), frames[0].frame_ms,
                (unsigned long long)frames[0].fragments,
                (unsigned long long)frames[0].max_depth_complexity,
                100.0 * double(close) / double(pixels));
    return 0;
  } catch (const strata::Error& e) {
    std::fprintf(stderr, "render_mesh: %s\n", e.what());
    return 1;
  }
}
