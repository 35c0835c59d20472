#include "engine/report/stats_json.h"

#include "preprocess/core/files.h"

#include <unistd.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace strata {

// Each part of FrameStats under its fields' own names (nlohmann's field lists: each name once).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(DrawStats, batch, sort, draw_units, launches, state_changes,
                                   material_changes, upload_bytes, scene_upload_bytes, sort_ms)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(AtlasStats, atlas, atlas_entries, atlas_placements, atlas_pages,
                                   atlas_bytes, atlas_occupancy)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PreparedSceneStats, preprocess_ms, preprocess_cached, batches)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CellsStats, cells, cell_copies, cell_unpaired_parts,
                                   cell_groups, cell_passes, cell_tile_passes, cell_tile_segments,
                                   cells_composite, largest_group, merged_groups, merged_cells,
                                   grid, order_ms, order_cached_frames, order_overlapped_frames,
                                   order_wait_ms, order_reused_frames, order_repair_tiles,
                                   order_repair_pixels, order_masks, order_device_cells,
                                   order_device_bytes)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(OctreeFrameStats, octree_variant, octree_early_out,
                                   octree_leaves, octree_refs, octree_duplicate_refs,
                                   leaf_layers_max, leaf_layers_mean, tile_walks, bin_entry_reads,
                                   dp_triangles_read)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(StreamingStats, memory_budget, peak_device_bytes,
                                   streamed_bytes, host_peak_rss, streamed, stream_source,
                                   disk_read_bytes)

namespace {

// Adds a part's fields to j.
template <typename Part>
void addPart(nlohmann::json& j, const Part& part) {
  j.update(nlohmann::json(part));
}

}  // namespace

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
  // The OpenCL front end's draw units (not cells, not embree), and textured scenes' atlas.
  if (!s.batch.empty()) addPart(j, static_cast<const DrawStats&>(s));
  if (!s.atlas.empty()) addPart(j, static_cast<const AtlasStats&>(s));
  if (s.method == "cells") {
    addPart(j, static_cast<const CellsStats&>(s));
    addPart(j, static_cast<const PreparedSceneStats&>(s));
  }
  if (s.method == "octree") {
    addPart(j, static_cast<const OctreeFrameStats&>(s));
    addPart(j, static_cast<const PreparedSceneStats&>(s));
    addPart(j, static_cast<const StreamingStats&>(s));
    j["triangles_read_vs_dp"] =
        s.dp_triangles_read ? double(s.triangles_read) / double(s.dp_triangles_read) : 0.0;
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
