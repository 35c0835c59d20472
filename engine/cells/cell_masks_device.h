// The cells order's pixel masks and pairs on the OpenCL device (kernels/cells_order_masks.cl,
// kernels/cells_order_pairs.cl): the CellMaskDevice of engine/cells/cell_order.h for one cell scene. It
// has its own command queue, so the order can run on a host thread of its own while the renderer's
// queue draws a frame; calls are serialized. Private to the library.
#pragma once

#include <mutex>

#include "engine/cells/cell_order.h"
#include "host/cl_runtime.h"

namespace strata {

class ClCellMasks : public CellMaskDevice {
 public:
  // Uploads the scene's cell corners and triangles; `scene` must outlive this object.
  ClCellMasks(ClRuntime& runtime, const CellScene& scene);
  void cover(const Request& request, std::vector<uint64_t>& masks) override;
  void pairs(const PairRequest& request, std::vector<uint32_t>& out) override;
  const CellScene& scene() const { return scene_; }
  // Device bytes held (the scene's arrays and the largest call's).
  size_t bytes() const;

 private:
  struct Buffer {
    cl::Buffer buffer;
    size_t bytes = 0;
  };
  // Grows b to at least `bytes` (with half again to spare for per-view arrays).
  void ensure(Buffer& b, size_t bytes, const char* purpose, bool spare = true);
  void upload(Buffer& b, const void* data, size_t bytes, const char* purpose, bool spare = true);

  ClRuntime& runtime_;
  const CellScene& scene_;
  std::mutex mutex_;
  cl::CommandQueue queue_;
  cl::Kernel kernel_, pairs_kernel_;
  Buffer vertex_first_, vertex_index_, cell_first_, corners_, cell_box_, neighbour_first_,
      neighbours_;
  Buffer screen_, node_cell_, node_rect_, entry_first_, masks_;
  Buffer by_node_, by_tile_, tile_position_, tile_end_, node_first_, node_depth_, view_,
      pair_count_, pairs_;
  uint32_t pair_capacity_ = 0;
};

}  // namespace strata
