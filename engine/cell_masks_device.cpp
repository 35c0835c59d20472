#include "engine/cell_masks_device.h"

#include <algorithm>

#include "engine/frame_runner.h"

namespace strata {

ClCellMasks::ClCellMasks(ClRuntime& runtime, const CellScene& scene)
    : runtime_(runtime), scene_(scene) {
  try {
    queue_ = cl::CommandQueue(runtime_.context(), runtime_.device());
    kernel_ = runtime_.kernel("cells_order_masks");
  } catch (const cl::Error& e) {
    rethrowClError(e, "cells order masks: command queue");
  }
  // The scene's arrays at their own size (they never grow), finished here: the object may go
  // before any call would have waited for them, and the scene with it.
  upload(vertex_first_, scene.cell_vertex_first.data(), scene.cell_vertex_first.size() * 4,
         "cell corner offsets (order masks)", false);
  upload(vertex_index_, scene.cell_vertex_index.data(), scene.cell_vertex_index.size() * 4,
         "cell corners (order masks)", false);
  upload(cell_first_, scene.cell_first.data(), scene.cell_first.size() * 4,
         "cell offsets (order masks)", false);
  upload(corners_, scene.cell_corners.data(), scene.cell_corners.size() * 2,
         "cell triangle corners (order masks)", false);
  try {
    queue_.finish();
  } catch (const cl::Error& e) {
    rethrowClError(e, "cells order masks: uploads");
  }
}

size_t ClCellMasks::bytes() const {
  return vertex_first_.bytes + vertex_index_.bytes + cell_first_.bytes + corners_.bytes +
         screen_.bytes + node_cell_.bytes + node_rect_.bytes + entry_first_.bytes + masks_.bytes;
}

void ClCellMasks::ensure(Buffer& b, size_t bytes, const char* purpose, bool spare) {
  bytes = std::max<size_t>(bytes, 16);
  if (b.bytes >= bytes) return;
  b.buffer = cl::Buffer();  // released before the larger one is made
  b.bytes = 0;
  const size_t grown = spare ? bytes + bytes / 2 : bytes;  // room for the next views' few more
  b.buffer = runtime_.allocate(grown, purpose);
  b.bytes = grown;
}

void ClCellMasks::upload(Buffer& b, const void* data, size_t bytes, const char* purpose,
                         bool spare) {
  ensure(b, bytes, purpose, spare);
  if (bytes == 0) return;
  try {
    queue_.enqueueWriteBuffer(b.buffer, CL_FALSE, 0, bytes, data);
  } catch (const cl::Error& e) {
    rethrowClError(e, std::string("upload of ") + purpose);
  }
}

void ClCellMasks::cover(const Request& r, std::vector<uint64_t>& masks) {
  std::lock_guard<std::mutex> lock(mutex_);
  // The uploads read the caller's memory until the queue is done with them: on any error the
  // queue is drained before the error leaves (and the caller's vectors with it).
  struct Drain {
    cl::CommandQueue& q;
    bool done = false;
    ~Drain() {
      if (done) return;
      try {
        q.finish();
      } catch (...) {
      }
    }
  } drain{queue_};
  const uint32_t nodes = uint32_t(r.cells->size());
  const uint32_t entries = r.entry_first->back();
  masks.resize(entries);
  if (nodes == 0 || entries == 0) return;
  upload(screen_, r.screen, size_t(r.vertex_count) * sizeof(glm::vec2), "vertex pixel positions");
  upload(node_cell_, r.cells->data(), size_t(nodes) * 4, "cells to mask");
  upload(node_rect_, r.rects->data(), size_t(nodes) * sizeof(glm::ivec4), "cell pixel rectangles");
  upload(entry_first_, r.entry_first->data(), (size_t(nodes) + 1) * 4, "cell mask offsets");
  ensure(masks_, size_t(entries) * 8, "cell pixel masks");
  try {
    setArgs(kernel_, screen_.buffer, r.first_vertex, vertex_first_.buffer, vertex_index_.buffer,
            cell_first_.buffer, corners_.buffer, node_cell_.buffer, node_rect_.buffer,
            entry_first_.buffer, nodes, cl_int(r.width), cl_int(r.height), masks_.buffer);
    queue_.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(roundUp(entries, ST_LINEAR_WG)),
                                cl::NDRange(ST_LINEAR_WG));
    queue_.enqueueReadBuffer(masks_.buffer, CL_TRUE, 0, size_t(entries) * 8, masks.data());
    drain.done = true;
  } catch (const cl::Error& e) {
    rethrowClError(e, "cells order masks");
  }
}

}  // namespace strata
