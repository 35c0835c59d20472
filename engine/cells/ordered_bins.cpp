#include "engine/cells/ordered_bins.h"

#include <algorithm>
#include <utility>

namespace strata {

OrderedBins::OrderedBins(FrameRunner& runner, Ensure ensure)
    : runner_(runner), ensure_(std::move(ensure)) {
  if (!ensure_)
    ensure_ = [this](DeviceBuffer& b, size_t bytes, const char* purpose) {
      runner_.ensure(b, bytes, purpose);
    };
  slots_per_cell_ = runner_.kernel("cells_slots");
  slots_per_slot_ = runner_.kernel("cells_slots_by_slot");
  count_serial_ = runner_.kernel("cells_bin_count");
  fill_serial_ = runner_.kernel("cells_bin_fill");
  count_atomic_ = runner_.kernel("cells_bin_count_atomic");
  fill_atomic_ = runner_.kernel("cells_bin_fill_atomic");
  scan_ = runner_.kernel("bin_scan");
  sort_ = runner_.kernel("cells_bin_sort");
}

void OrderedBins::size(bool serial, uint32_t runs, size_t bin_capacity) {
  serial_ = serial;
  runs_ = std::max<uint32_t>(runs, 1);
  const size_t table = size_t(runner_.tileCount()) * this->runs();
  const size_t counters = size_t(runner_.binRunTableWords(this->runs()));  // padded per run
  ensure_(counts_, counters * 4, "tile x run counts");
  ensure_(offsets_, (table + 1) * 4, "tile x run offsets");
  ensure_(cursors_, counters * 4, "tile x run cursors");
  if (!serial_) ensure_(keys_, std::max<size_t>(bin_capacity, 1) * 8, "tile bin sort keys");
}

void OrderedBins::enqueueSlotLayout(const cl::Buffer& cell_first, const cl::Buffer& cell_triangles,
                                    bool batch_local, const cl::Buffer& order_cells,
                                    const cl::Buffer& order_start, const cl::Buffer& order_group,
                                    uint32_t first, uint32_t cells, uint32_t slots,
                                    const cl::Buffer& record_group,
                                    const cl::Buffer& slot_triangle) {
  if (cells == 0) return;
  cl::Kernel& k = serial_ ? slots_per_cell_ : slots_per_slot_;
  setArgs(k, cell_first, cell_triangles, cl_int(batch_local ? 1 : 0), order_cells, order_start,
          order_group, cl_uint(first), cl_uint(cells), record_group, slot_triangle);
  if (!serial_) k.setArg(10, cl_uint(slots));
  runner_.timer().launch("setup", k, cl::NDRange(roundUp(serial_ ? cells : slots, ST_LINEAR_WG)),
                         cl::NDRange(ST_LINEAR_WG));
}

void OrderedBins::enqueue(const cl::Buffer& record_bounds, const cl::Buffer& slot_extra,
                          uint32_t slots, uint32_t batch_capacity, uint32_t overflow_capacity,
                          const cl::Buffer& batch_counters, cl::Buffer& bins, size_t bin_capacity,
                          const cl::Buffer& counters) {
  LaunchTimer& timer = runner_.timer();
  const uint32_t tiles = runner_.tileCount();
  const cl_uint table = cl_uint(size_t(tiles) * runs());
  const cl_uint tiles_x = cl_uint(runner_.tilesX());
  timer.fill("bin", counts_.buffer, 0u, size_t(runner_.binRunTableWords(runs())) * 4);
  if (serial_) {
    const cl_uint run_slots = cl_uint((slots + runs_ - 1) / runs_);
    setArgs(count_serial_, record_bounds, slot_extra, cl_uint(slots), cl_uint(batch_capacity),
            cl_uint(overflow_capacity), run_slots, cl_uint(runs_), tiles_x, cl_uint(tiles),
            counts_.buffer);
    timer.launch("bin", count_serial_, cl::NDRange(runs_), cl::NDRange(1));
  } else if (slots > 0) {
    setArgs(count_atomic_, record_bounds, slot_extra, cl_uint(slots), cl_uint(batch_capacity),
            cl_uint(overflow_capacity), tiles_x, counts_.buffer);
    timer.launch("bin", count_atomic_, cl::NDRange(roundUp(slots, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));
  }
  setArgs(scan_, counts_.buffer, table, offsets_.buffer, cursors_.buffer, batch_counters,
          cl_uint(runs()));
  timer.launch("bin", scan_, cl::NDRange(ST_SCAN_WG), cl::NDRange(ST_SCAN_WG));
  if (serial_) {
    const cl_uint run_slots = cl_uint((slots + runs_ - 1) / runs_);
    setArgs(fill_serial_, record_bounds, slot_extra, cl_uint(slots), cl_uint(batch_capacity),
            cl_uint(overflow_capacity), run_slots, cl_uint(runs_), tiles_x, cl_uint(tiles),
            cursors_.buffer, offsets_.buffer, table, bins, cl_uint(bin_capacity), counters);
    timer.launch("bin", fill_serial_, cl::NDRange(runs_), cl::NDRange(1));
    return;
  }
  // The fill's first work-item also reports the entry count, so it runs even for no slots.
  setArgs(fill_atomic_, record_bounds, slot_extra, cl_uint(slots), cl_uint(batch_capacity),
          cl_uint(overflow_capacity), tiles_x, cursors_.buffer, offsets_.buffer, table,
          keys_.buffer, cl_uint(bin_capacity), counters);
  timer.launch("bin", fill_atomic_, cl::NDRange(roundUp(std::max<uint32_t>(slots, 1), ST_LINEAR_WG)),
               cl::NDRange(ST_LINEAR_WG));
  setArgs(sort_, keys_.buffer, offsets_.buffer, cl_uint(bin_capacity), bins);
  timer.launch("bin", sort_, cl::NDRange(size_t(tiles) * ST_BIN_SORT_WG),
               cl::NDRange(ST_BIN_SORT_WG));
}

}  // namespace strata
