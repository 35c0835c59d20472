#include "engine/cells/cell_masks_device.h"

#include <algorithm>
#include <cstring>

#include "engine/frontend/frame_runner.h"

namespace strata {

namespace {
// The uploads of a call read the caller's memory until the queue is done with them: on any error
// the queue is drained before the error leaves the call (and the caller's vectors with it).
struct DrainOnError {
  cl::CommandQueue& queue;
  bool done = false;
  ~DrainOnError() {
    if (done) return;
    try {
      queue.finish();
    } catch (...) {
    }
  }
};
}  // namespace

ClCellMasks::ClCellMasks(ClRuntime& runtime, const CellScene& scene)
    : runtime_(runtime), scene_(scene) {
  try {
    queue_ = cl::CommandQueue(runtime_.context(), runtime_.device());
    kernel_ = runtime_.kernel("cells_order_masks");
    pairs_kernel_ = runtime_.kernel("cells_order_pairs");
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
  // The relation's inputs: each cell's box (lo, hi), its neighbours (other, separable, plane).
  std::vector<float> boxes(size_t(scene.cellCount()) * 6);
  for (uint32_t c = 0; c < scene.cellCount(); ++c)
    for (int k = 0; k < 3; ++k) {
      boxes[6 * size_t(c) + k] = scene.cell_box[c].min[k];
      boxes[6 * size_t(c) + 3 + k] = scene.cell_box[c].max[k];
    }
  std::vector<float> neighbours(scene.neighbours.size() * 6);
  for (size_t i = 0; i < scene.neighbours.size(); ++i) {
    const CellNeighbour& n = scene.neighbours[i];
    const uint32_t separable = n.separable ? 1u : 0u;
    std::memcpy(&neighbours[6 * i], &n.other, 4);
    std::memcpy(&neighbours[6 * i + 1], &separable, 4);
    neighbours[6 * i + 2] = n.plane.n.x;
    neighbours[6 * i + 3] = n.plane.n.y;
    neighbours[6 * i + 4] = n.plane.n.z;
    neighbours[6 * i + 5] = n.plane.d;
  }
  upload(cell_box_, boxes.data(), boxes.size() * 4, "cell boxes (order pairs)", false);
  upload(neighbour_first_, scene.neighbour_first.data(), scene.neighbour_first.size() * 4,
         "cell neighbour offsets (order pairs)", false);
  upload(neighbours_, neighbours.data(), neighbours.size() * 4, "cell neighbours (order pairs)",
         false);
  try {
    queue_.finish();
  } catch (const cl::Error& e) {
    rethrowClError(e, "cells order masks: uploads");
  }
}

size_t ClCellMasks::bytes() const {
  size_t total = 0;
  for (const Buffer* b : {&vertex_first_, &vertex_index_,    &cell_first_,    &corners_,
                          &cell_box_,     &neighbour_first_, &neighbours_,    &screen_,
                          &node_cell_,    &node_rect_,       &entry_first_,   &masks_,
                          &by_node_,      &by_tile_,         &tile_position_, &tile_end_,
                          &node_first_,   &node_depth_,      &view_,          &pair_count_,
                          &pairs_})
    total += b->bytes;
  return total;
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
  DrainOnError drain{queue_};
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

void ClCellMasks::pairs(const PairRequest& r, std::vector<uint32_t>& out) {
  std::lock_guard<std::mutex> lock(mutex_);
  out.clear();
  if (r.entries == 0) return;
  DrainOnError drain{queue_};
  upload(by_node_, r.by_node, size_t(r.entries) * 16, "cell masks by cell");
  upload(by_tile_, r.by_tile, size_t(r.entries) * 16, "cell masks by tile");
  upload(tile_position_, r.tile_position, size_t(r.entries) * 4, "cell mask places by tile");
  upload(tile_end_, r.tile_end, size_t(r.tiles) * 4, "tile list ends");
  upload(node_first_, r.node_first, (size_t(r.nodes) + 1) * 4, "cell mask offsets by cell");
  upload(node_cell_, r.node_cell, size_t(r.nodes) * 4, "cells to pair");
  upload(node_depth_, r.node_depth, size_t(r.nodes) * sizeof(glm::vec2), "cell depth ranges");
  ensure(pair_count_, 4, "pair count");
  // About one pair per entry on a fine mesh; more, and the search runs again with room for all.
  if (pair_capacity_ < r.entries * 2) pair_capacity_ = r.entries * 2;
  const float view[6] = {r.eye.x, r.eye.y, r.eye.z, r.forward.x, r.forward.y, r.forward.z};
  upload(view_, view, sizeof(view), "view (order pairs)");
  try {
    for (;;) {
      ensure(pairs_, size_t(pair_capacity_) * 8, "cell pairs");
      static const cl_uint zero = 0;  // outlives the write whatever happens
      queue_.enqueueWriteBuffer(pair_count_.buffer, CL_FALSE, 0, 4, &zero);
      setArgs(pairs_kernel_, by_node_.buffer, node_first_.buffer, by_tile_.buffer,
              tile_position_.buffer, tile_end_.buffer, cl_uint(r.entries), node_cell_.buffer,
              node_depth_.buffer, cell_box_.buffer, neighbour_first_.buffer, neighbours_.buffer,
              view_.buffer, cl_int(r.perspective ? 1 : 0), pair_count_.buffer,
              cl_uint(pair_capacity_), pairs_.buffer);
      queue_.enqueueNDRangeKernel(pairs_kernel_, cl::NullRange,
                                  cl::NDRange(roundUp(r.entries, ST_LINEAR_WG)),
                                  cl::NDRange(ST_LINEAR_WG));
      cl_uint count = 0;
      queue_.enqueueReadBuffer(pair_count_.buffer, CL_TRUE, 0, 4, &count);
      if (count > pair_capacity_) {
        pair_capacity_ = count + count / 4;
        continue;
      }
      out.resize(size_t(count) * 2);
      if (count) queue_.enqueueReadBuffer(pairs_.buffer, CL_TRUE, 0, size_t(count) * 8, out.data());
      drain.done = true;
      return;
    }
  } catch (const cl::Error& e) {
    rethrowClError(e, "cells order pairs");
  }
}

}  // namespace strata
