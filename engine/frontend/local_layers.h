// The host side of a tile kernel that keeps each pixel's k nearest fragments as layers in the
// tile's local memory (kernels/local_layers.cl; mlab, hybrid; adaptive keeps nodes of a
// visibility function the same way): one launch per frame that walks each tile in drawing order
// and resolves it, its layers as __local arguments sized by settings.k. Nothing in global memory
// beyond the front end's, so no fragment bytes and nothing lost; k is bounded by the device's local
// memory. Private to the library.
#pragma once

#include <string>

#include "engine/frontend/cl_pipeline.h"

namespace strata {

class LocalLayersMethod : public ClMethod {
 public:
  // `kernel` (and kernel + "_serial") takes the arguments of ST_LAYERS_PARAMS; `fixed_local` is
  // the bytes of its own __local tables per tile. Each layer has `layer_floats` floats in the
  // `layer` table besides its depth (4: premultiplied colour and transmittance; 1: a
  // transmittance), and the kernel gets `spare_layers` layers per pixel beyond k.
  LocalLayersMethod(const char* method, const char* kernel, const char* stage, size_t fixed_local,
                    size_t layer_floats = 4, size_t spare_layers = 0)
      : method_(method),
        kernel_name_(kernel),
        stage_(stage),
        fixed_local_(fixed_local),
        layer_floats_(layer_floats),
        spare_layers_(spare_layers) {}

  void init(ClPipeline& p) override { kernel_.create(p, kernel_name_); }

  void prepare(ClPipeline& p, const FrameSettings& s) override {
    k_ = uint32_t(s.k);  // 1 to ST_MAX_K (checkSettings)
    const uint64_t per_layer = uint64_t(ST_TILE_PIXELS) * layerBytes();
    const uint64_t fixed = fixed_local_ + spare_layers_ * per_layer;
    const uint64_t available = localMemorySize(p);
    const uint64_t most = available > fixed ? (available - fixed) / per_layer : 0;
    requireLocalMemory(p, fixed + k_ * per_layer,
                       std::string(method_) + ": k = " + std::to_string(k_) + " layers",
                       " (at most k = " + std::to_string(most) + ")");
  }

  void enqueue(ClPipeline& p) override {
    const size_t layers = (size_t(k_) + spare_layers_) * ST_TILE_PIXELS;
    setArgs(
        kernel_.forFrame(p), p.records().buffer, p.bins().buffer, p.tileOffsets().buffer,
        cl_uint(p.tilesX()), p.binCapacity(), cl_uint(k_), p.triangleColors().buffer,
        p.texTriangles().buffer, p.atlas().buffer, p.view().buffer, p.image().buffer,
        p.counters().buffer, p.depthComplexity().buffer, cl_int(p.captureDepthComplexity() ? 1 : 0),
        cl::Local(layers * layer_floats_ * sizeof(cl_float)), cl::Local(layers * sizeof(cl_float)));
    kernel_.launch(p, stage_);
  }

  void addStats(ClPipeline&, const uint64_t*, FrameStats& st) override {
    st.geometry_passes = 1;
    st.fragment_bytes = 0;  // the layers live in the tile's local memory
  }

  uint64_t deviceBytes() const override { return 0; }

  // Which fragments a pixel keeps depends on their order: the tile lists keep the drawing order.
  bool needsDrawingOrder() const override { return true; }

  // A layer's bytes per pixel: its floats in the `layer` table, and its depth.
  size_t layerBytes() const { return (layer_floats_ + 1) * sizeof(float); }

 private:
  const char* method_;
  const char* kernel_name_;
  const char* stage_;
  size_t fixed_local_;
  size_t layer_floats_, spare_layers_;
  TileKernel kernel_;
  uint32_t k_ = 4;
};

}  // namespace strata
