// Ordered tile binning for methods that draw a batch of slots in visibility order (cells, octree
// leaves): every record is listed in each tile its pixel bounds touch, each tile's list in slot
// order, a clipped slot's extra pieces right after it (kernels/cells_bin.cl). Two forms, the same
// lists: serial (CPU devices: runs of slots walked by a work-item each into a tile x run table,
// no atomics) and group (GPUs: atomic counts and appends keyed by slot, then a work-group per
// tile sorts its list). The tile kernels read a tile's list as
// offsets()[tile * runs()] .. offsets()[(tile + 1) * runs()]. Private to the library.
#pragma once

#include <cstdint>
#include <functional>

#include "engine/frontend/frame_runner.h"

namespace strata {

// The setup records of a batch of slots that OrderedBins lists (cells, octree leaves): per slot
// the triangle's setup, its pixel bounds, its group (cell or leaf), its colour and, read only
// for translucency, its normal.
struct GroupRecords {
  DeviceBuffer setup, bounds, group, color, normal;

  template <class Ensure>
  void size(Ensure&& ensure, size_t slots, bool translucent, const char* setup_purpose,
            const char* group_purpose) {
    ensure(setup, slots * sizeof(StTriSetup), setup_purpose);
    ensure(bounds, slots * 8, "record pixel bounds");
    ensure(group, slots * 4, group_purpose);
    ensure(color, slots * 16, "record colours");
    ensure(normal, translucent ? slots * 16 : 16, "record normals");
  }
  uint64_t bytes() const {
    return setup.bytes + bounds.bytes + group.bytes + color.bytes + normal.bytes;
  }
};

class OrderedBins {
 public:
  // Buffers are sized through `ensure` (a method that counts the bytes it holds passes its own);
  // by default FrameRunner::ensure.
  using Ensure = std::function<void(DeviceBuffer&, size_t, const char*)>;
  explicit OrderedBins(FrameRunner& runner, Ensure ensure = {});
  OrderedBins(const OrderedBins&) = delete;  // the default Ensure refers to this object
  OrderedBins& operator=(const OrderedBins&) = delete;

  // Sizes the tables for the current tiles: `runs` slot runs in the serial form (the group form
  // uses one per tile), and keys for up to bin_capacity entries in the group form.
  void size(bool serial, uint32_t runs, size_t bin_capacity);
  // Enqueues the batch's slot layout (stage "setup"; kernels/cells_setup.cl): slot i gets the
  // i-th triangle of the ordered cells [first, first + cells) with its group tag, a work-item per
  // cell in the serial form, per slot in the group form (a large cell walked by one work-item
  // holds a GPU up). With batch_local the triangles come in slot order (no slot_triangle).
  void enqueueSlotLayout(const cl::Buffer& cell_first, const cl::Buffer& cell_triangles,
                         bool batch_local, const cl::Buffer& order_cells,
                         const cl::Buffer& order_start, const cl::Buffer& order_group,
                         uint32_t first, uint32_t cells, uint32_t slots,
                         const cl::Buffer& record_group, const cl::Buffer& slot_triangle);
  // Enqueues the binning of one batch (stage "bin"): records' packed bounds and slots' extra
  // pieces as cells_setup writes them; per-batch counters for the scan; the total entry count
  // is raised into counters[ST_COUNTER_CELLS_ENTRIES] so the caller can grow `bins`.
  void enqueue(const cl::Buffer& record_bounds, const cl::Buffer& slot_extra, uint32_t slots,
               uint32_t batch_capacity, uint32_t overflow_capacity,
               const cl::Buffer& batch_counters, cl::Buffer& bins, size_t bin_capacity,
               const cl::Buffer& counters);

  const cl::Buffer& offsets() const { return offsets_.buffer; }
  uint32_t runs() const { return serial_ ? runs_ : 1; }
  bool serial() const { return serial_; }
  size_t bytes() const { return counts_.bytes + offsets_.bytes + cursors_.bytes + keys_.bytes; }
  // Device bytes per tile and per bin entry the group or serial form takes (for memory budgets).
  static size_t bytesPerTile(bool serial, uint32_t runs) { return size_t(serial ? runs : 1) * 12; }
  static size_t bytesPerEntry(bool serial) { return serial ? 0 : 8; }

 private:
  FrameRunner& runner_;
  Ensure ensure_;
  cl::Kernel slots_per_cell_, slots_per_slot_;
  cl::Kernel count_serial_, fill_serial_, count_atomic_, fill_atomic_, scan_, sort_;
  DeviceBuffer counts_, offsets_, cursors_, keys_;
  bool serial_ = true;
  uint32_t runs_ = 1;
};

}  // namespace strata
