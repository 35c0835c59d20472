#include "engine/report/stats_json.h"

#include "preprocess/core/files.h"

#include <unistd.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace strata {

nlohmann::json statsToJson(const FrameStats& s, const std::string& scene) {
  nlohmann::json j;
  j["method"] = s.method;
  j["scene"] = scene;
  j["width"] = s.width;
  j["height"] = s.height;
  j["device"] = s.device;
  j["triangles"] = s.triangles;
  j["triangles_read"] = s.triangles_read;
  j["fragments"] = s.fragments;
  j["max_depth_complexity"] = s.max_depth_complexity;
  j["device_bytes"] = s.device_bytes;
  j["fragment_bytes"] = s.fragment_bytes;
  j["kernel_launches"] = s.kernel_launches;
  j["culled_degenerate"] = s.culled_degenerate;
  j["culled_nonfinite"] = s.culled_nonfinite;
  j["clipped"] = s.clipped;
  j["reruns"] = s.reruns;
  j["geometry_passes"] = s.geometry_passes;
  j["fragments_lost"] = s.fragments_lost;
  j["bytes_needed"] = s.bytes_needed;
  if (!s.tile_kernels.empty()) j["tile_kernels"] = s.tile_kernels;
  if (!s.batch.empty()) {  // the OpenCL front end's draw units (not cells, not embree)
    j["batch"] = s.batch;
    j["sort"] = s.sort;
    j["draw_units"] = s.draw_units;
    j["launches"] = s.launches;
    j["state_changes"] = s.state_changes;
    j["material_changes"] = s.material_changes;
    j["upload_bytes"] = s.upload_bytes;
    j["scene_upload_bytes"] = s.scene_upload_bytes;
    j["sort_ms"] = s.sort_ms;
  }
  if (!s.atlas.empty()) {  // textured scenes
    j["atlas"] = s.atlas;
    j["atlas_entries"] = s.atlas_entries;
    j["atlas_placements"] = s.atlas_placements;
    j["atlas_pages"] = s.atlas_pages;
    j["atlas_bytes"] = s.atlas_bytes;
    j["atlas_occupancy"] = s.atlas_occupancy;
  }
  if (s.method == "cells") {
    j["cells"] = s.cells;
    j["cell_copies"] = s.cell_copies;
    j["cell_unpaired_parts"] = s.cell_unpaired_parts;
    j["cell_groups"] = s.cell_groups;
    j["cell_passes"] = s.cell_passes;
    j["cell_tile_passes"] = s.cell_tile_passes;
    j["cell_tile_segments"] = s.cell_tile_segments;
    j["cells_composite"] = s.cells_composite;
    j["largest_group"] = s.largest_group;
    j["merged_groups"] = s.merged_groups;
    j["merged_cells"] = s.merged_cells;
    j["grid"] = {s.grid[0], s.grid[1], s.grid[2]};
    j["preprocess_ms"] = s.preprocess_ms;
    j["preprocess_cached"] = s.preprocess_cached;
    j["order_ms"] = s.order_ms;
    j["order_cached_frames"] = s.order_cached_frames;
    j["order_overlapped_frames"] = s.order_overlapped_frames;
    j["order_wait_ms"] = s.order_wait_ms;
    j["order_reused_frames"] = s.order_reused_frames;
    j["order_repair_tiles"] = s.order_repair_tiles;
    j["order_repair_pixels"] = s.order_repair_pixels;
    j["order_masks"] = s.order_masks;
    j["order_device_cells"] = s.order_device_cells;
    j["order_device_bytes"] = s.order_device_bytes;
    j["batches"] = s.batches;
  }
  if (s.method == "octree") {
    j["octree_variant"] = s.octree_variant;
    j["octree_early_out"] = s.octree_early_out;
    j["octree_leaves"] = s.octree_leaves;
    j["octree_refs"] = s.octree_refs;
    j["octree_duplicate_refs"] = s.octree_duplicate_refs;
    j["leaf_layers_max"] = s.leaf_layers_max;
    j["leaf_layers_mean"] = s.leaf_layers_mean;
    j["tile_walks"] = s.tile_walks;
    j["bin_entry_reads"] = s.bin_entry_reads;
    j["dp_triangles_read"] = s.dp_triangles_read;
    j["triangles_read_vs_dp"] =
        s.dp_triangles_read ? double(s.triangles_read) / double(s.dp_triangles_read) : 0.0;
    j["preprocess_ms"] = s.preprocess_ms;
    j["preprocess_cached"] = s.preprocess_cached;
    j["batches"] = s.batches;
    j["memory_budget"] = s.memory_budget;
    j["peak_device_bytes"] = s.peak_device_bytes;
    j["streamed"] = s.streamed;
    j["streamed_bytes"] = s.streamed_bytes;
    j["stream_source"] = s.stream_source;
    j["disk_read_bytes"] = s.disk_read_bytes;
    j["host_peak_rss"] = s.host_peak_rss;
  }
  // Whether the view moved between frames (then every frame paid for a new view).
  j["moving"] = s.orbit_deg != 0.0f;
  j["orbit_deg"] = s.orbit_deg;
  j["frame_ms"] = {{"median", s.frame_ms.median},
                   {"min", s.frame_ms.min},
                   {"max", s.frame_ms.max},
                   {"mean", s.frame_ms.mean},
                   {"runs", s.frame_ms.runs}};
  j["stage_ms"] = nlohmann::json::object();
  for (const auto& [name, ms] : s.stage_ms) j["stage_ms"][name] = ms;
  if (!s.kernel_ms.empty()) {
    j["kernel_ms"] = nlohmann::json::object();
    for (const auto& [name, k] : s.kernel_ms)
      j["kernel_ms"][name] = {{"ms", k.ms}, {"launches", k.launches}};
  }
  return j;
}

void writeTextFileAtomically(const std::string& path, const std::string& text) {
  writeFileAtomically(path, "file", text);
}

}  // namespace strata
