// The public header in a C++20 project: std::span geometry and the typed options.
#include <array>
#include <cstdio>
#include <span>

#include <strata/strata.h>

int main() {
  try {
    const std::array<float, 9> p{0, 0, 0, 1, 0, 0, 0, 1, 0};
    const std::array<uint32_t, 3> idx{0, 1, 2};
    const strata::Geometry g =
        strata::Geometry::fromArrays(std::span<const float>(p), std::span<const uint32_t>(idx));
    strata::RenderOptions o;
    o.batch = strata::parseBatch("instanced");
    o.tile_kernels = strata::TileKernels::Serial;
    strata::Renderer r(strata::Device::open(), "ppll", o);
    r.setGeometry(g);
    strata::View v;
    v.width = v.height = 32;
    const strata::Frame f = r.render(v);
    std::printf("C++20: %llu fragments, batch %s\n", (unsigned long long)f.fragments,
                strata::optionName(o.batch));
    return f.fragments > 0 ? 0 : 1;
  } catch (const strata::Error& e) {
    std::fprintf(stderr, "cxx20: %s\n", e.what());
    return 1;
  }
}
