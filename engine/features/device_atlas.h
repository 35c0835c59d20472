// The texture atlas as the OpenCL methods read it: one word array (StAtlasHeader, the entries,
// the pages, the RGBA8 texels of every page's kept levels) and each material's entry (the
// per-triangle records are per view: makeTexTriangles in engine/frontend/texture_shading.h). Built on the
// host from the world geometry's textures; no OpenCL here.
//
// An entry is a texture with one sampler. Entries with equal texture and wrap modes share one
// placement; a texture sampled with two wrap modes is placed twice, each copy's gutter filled by
// its own wrap rule.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

// AtlasChoice (engine/renderer.h, --atlas): uniform slots, packed (stb_rect_pack), or off: every
// texture on a page of its own and bound per draw (one front-end launch per texture, as an engine
// without an atlas issues).

// Largest side of an atlas page the packer chooses (a larger texture gets a page of its own size).
// The side is chosen per texture set: the one that needs the fewest atlas texels.
inline constexpr int kMaxAtlasPage = 8192;

struct DeviceAtlas {
  std::vector<uint32_t> words;           // empty when the geometry is not textured
  std::vector<uint32_t> material_entry;  // per material: its entry, or ST_NO_TEXTURE
  uint32_t entries = 0, placements = 0, pages = 0;
  int page_size = 0;
  uint64_t texels = 0;     // atlas texels over every page and kept level
  double occupancy = 0.0;  // texture texels / page texels at level 0 (AtlasLayout::occupancy)

  bool empty() const { return words.empty(); }
};

DeviceAtlas buildDeviceAtlas(const WorldGeometry& g, AtlasChoice choice);

// Keeps the last atlas built, so rendering the same textures again (another view, size or
// method settings) neither rebuilds its mip chains nor uploads it again. Texture images are
// immutable and shared; the cache holds the ones it was built from, so no other texture can
// take their place at the same address while it compares against them.
class DeviceAtlasCache {
 public:
  // The atlas of g's textures in mode `choice`; *changed says whether it differs from the one
  // the last call returned (then it must be uploaded).
  const DeviceAtlas& get(const WorldGeometry& g, AtlasChoice choice, bool* changed);

 private:
  std::vector<std::shared_ptr<const TextureImage>> textures_;
  std::vector<int32_t> material_texture_;
  std::vector<int> samplers_;
  int choice_ = -1;
  DeviceAtlas atlas_;
};

// Fills FrameStats' atlas fields (left empty for an untextured scene); set stats.triangles first
// (atlas_bytes counts the per-triangle records).
void addAtlasStats(const DeviceAtlas& atlas, AtlasChoice choice, FrameStats& stats);

}  // namespace strata
