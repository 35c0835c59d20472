#include "engine/features/device_atlas.h"

#include <algorithm>
#include <map>
#include <tuple>

#include "engine/features/texture_atlas.h"
#include "preprocess/core/enum_table.h"

namespace strata {

const char* atlasChoiceName(AtlasChoice c) {
  static constexpr const char* kNames[] = {"off", "uniform", "packed"};
  return enumLookup(c, kNames, "packed");
}

const char* optionName(AtlasChoice value) { return atlasChoiceName(value); }

AtlasChoice parseAtlasChoice(const std::string& name) {
  if (name == "off") return AtlasChoice::Off;
  if (name == "uniform") return AtlasChoice::Uniform;
  if (name == "packed") return AtlasChoice::Packed;
  throw Error("--atlas: unknown value '" + name + "' (known: uniform, packed, off)");
}

namespace {

int stWrap(Wrap w) {
  static constexpr int kWraps[] = {ST_WRAP_REPEAT, ST_WRAP_MIRRORED_REPEAT, ST_WRAP_CLAMP};
  return enumLookup(w, kWraps, int(ST_WRAP_CLAMP));
}

int stFilter(Filter f) {
  static constexpr int kFilters[] = {ST_FILTER_NEAREST, ST_FILTER_BILINEAR, ST_FILTER_TRILINEAR};
  return enumLookup(f, kFilters, int(ST_FILTER_TRILINEAR));
}

uint32_t packRgba8(const glm::vec4& c) {
  uint32_t w = 0;
  for (int k = 0; k < 4; ++k) w |= st_to_unorm8(c[k]) << (8 * k);
  return w;
}

// The page side that needs the fewest atlas texels for these textures (pages are trimmed to
// their lowest cell, so a side that fits the set snugly wins), trying sides from the largest
// cell up to kMaxAtlasPage in steps of about 12%; ties go to fewer pages.
int bestPageSide(const std::vector<glm::ivec2>& sizes, int largest_cell, AtlasMode mode) {
  int best = 0;
  double best_texels = 0.0;
  int best_pages = 0;
  for (int side = std::max(largest_cell, 64);;
       side = std::min(kMaxAtlasPage, side + std::max(64, side / 8))) {
    const AtlasLayout l = packAtlas(sizes, side, mode);
    double texels = 0.0;
    for (int h : l.page_heights) texels += double(side) * h;
    if (best == 0 || texels < best_texels || (texels == best_texels && l.pages < best_pages)) {
      best = side;
      best_texels = texels;
      best_pages = l.pages;
    }
    if (side >= kMaxAtlasPage) break;
  }
  return best;
}

template <class T>
void appendWords(std::vector<uint32_t>& words, const T& value) {
  static_assert(sizeof(T) % 4 == 0, "shared structs are whole words");
  const auto* p = reinterpret_cast<const uint32_t*>(&value);
  words.insert(words.end(), p, p + sizeof(T) / 4);
}

}  // namespace

const DeviceAtlas& DeviceAtlasCache::get(const WorldGeometry& g, AtlasChoice choice,
                                         bool* changed) {
  std::vector<int> samplers;
  for (const Sampler& s : g.material_sampler)
    samplers.push_back(int(s.wrap_s) * 9 + int(s.wrap_t) * 3 + int(s.filter));
  const bool same = choice_ == int(choice) && g.textures == textures_ &&
                    g.material_texture == material_texture_ && samplers == samplers_;
  *changed = !same;
  if (!same) {
    atlas_ = buildDeviceAtlas(g, choice);  // may throw: the key is updated only on success
    choice_ = int(choice);
    textures_ = g.textures;
    material_texture_ = g.material_texture;
    samplers_ = std::move(samplers);
  }
  return atlas_;
}

void addAtlasStats(const DeviceAtlas& atlas, AtlasChoice choice, FrameStats& st) {
  if (atlas.empty()) return;
  st.atlas = atlasChoiceName(choice);
  st.atlas_entries = atlas.entries;
  st.atlas_placements = atlas.placements;
  st.atlas_pages = atlas.pages;
  st.atlas_bytes =
      atlas.words.size() * sizeof(uint32_t) + size_t(st.triangles) * sizeof(StTexTriangle);
  st.atlas_occupancy = atlas.occupancy;
}

namespace {

// A texture placed once per pair of wrap modes (the gutters depend on them).
using PlacementKey = std::tuple<int32_t, Wrap, Wrap>;

// The atlas's entries (texture, wraps, filter), each with its placement (texture, wraps).
struct AtlasEntries {
  std::vector<PlacementKey> placements;
  std::vector<StAtlasTexture> entries;
  std::vector<uint32_t> entry_placement;
};

// The entries and placements the materials use; material_entry gets every material's entry
// (ST_NO_TEXTURE for the untextured).
AtlasEntries collectEntries(const WorldGeometry& g, std::vector<uint32_t>& material_entry) {
  AtlasEntries out;
  std::map<PlacementKey, uint32_t> placement_of;
  std::map<std::tuple<int32_t, Wrap, Wrap, Filter>, uint32_t> entry_of;
  material_entry.assign(g.material_texture.size(), ST_NO_TEXTURE);
  for (size_t m = 0; m < g.material_texture.size(); ++m) {
    const int32_t tex = g.material_texture[m];
    if (tex < 0 || size_t(tex) >= g.textures.size() || !g.textures[size_t(tex)]) continue;
    const Sampler& s = g.material_sampler[m];
    const PlacementKey pk{tex, s.wrap_s, s.wrap_t};
    auto [pit, new_placement] = placement_of.emplace(pk, uint32_t(out.placements.size()));
    if (new_placement) out.placements.push_back(pk);
    auto [eit, new_entry] = entry_of.emplace(std::make_tuple(tex, s.wrap_s, s.wrap_t, s.filter),
                                             uint32_t(out.entries.size()));
    if (new_entry) {
      StAtlasTexture e{};
      e.wrap_s = stWrap(s.wrap_s);
      e.wrap_t = stWrap(s.wrap_t);
      e.filter = stFilter(s.filter);
      out.entries.push_back(e);
      out.entry_placement.push_back(pit->second);
    }
    material_entry[m] = eit->second;
  }
  return out;
}

// The placements laid out on pages: one atlas for uniform / packed, one page per placement for
// off (page_size 0: pages of their own sizes).
struct PlacedPages {
  std::vector<std::vector<TextureImage>> pages;  // [page][level]
  std::vector<AtlasPlacement> where;             // per placement
  double used = 0, page_texels = 0;
  int page_size = 0;
};

PlacedPages placeTextures(const WorldGeometry& g, const std::vector<PlacementKey>& placements,
                          AtlasChoice choice) {
  std::vector<TextureImage> images;  // copies only for buildAtlas's interface
  std::vector<Sampler> samplers;
  for (const auto& [tex, ws, wt] : placements) {
    validateTexture(*g.textures[size_t(tex)], "texture");
    images.push_back(*g.textures[size_t(tex)]);
    Sampler s;
    s.wrap_s = ws;
    s.wrap_t = wt;
    samplers.push_back(s);
  }
  PlacedPages out;
  out.where.resize(placements.size());
  auto take = [&](Atlas&& a, const std::vector<size_t>& ids) {
    const int first_page = int(out.pages.size());
    for (size_t k = 0; k < ids.size(); ++k) {
      out.where[ids[k]] = a.layout.placements[k];
      out.where[ids[k]].page += first_page;
      out.used += double(a.layout.placements[k].w) * a.layout.placements[k].h;
    }
    for (auto& pg : a.pages) {
      out.page_texels += double(pg[0].width) * pg[0].height;
      out.pages.push_back(std::move(pg));
    }
  };
  int largest_cell = 1;
  for (const TextureImage& im : images) {
    const int gut = gutterTexels(keptMipLevels({im.width, im.height}));
    largest_cell = std::max({largest_cell, im.width + 2 * gut, im.height + 2 * gut});
  }
  if (largest_cell > kMaxAtlasPageSide)  // cannot happen for textures that pass validateTexture
    throw Error("atlas: a texture with its gutter is " + std::to_string(largest_cell) +
                " texels wide, more than the largest page (" + std::to_string(kMaxAtlasPageSide) +
                ")");
  if (choice == AtlasChoice::Off) {
    for (size_t i = 0; i < images.size(); ++i) {
      const int gut = gutterTexels(keptMipLevels({images[i].width, images[i].height}));
      const int side = std::max(images[i].width, images[i].height) + 2 * gut;
      take(buildAtlas({images[i]}, {samplers[i]}, side, AtlasMode::Packed), {i});
    }
    return out;
  }
  std::vector<glm::ivec2> sizes;
  for (const TextureImage& im : images) sizes.push_back({im.width, im.height});
  const AtlasMode mode = choice == AtlasChoice::Uniform ? AtlasMode::Uniform : AtlasMode::Packed;
  // Uniform slots: pages of the smallest power of two >= 2048 holding a slot (a side chosen
  // for fewest texels would put every slot on a page of its own). Packed: the best side.
  if (largest_cell > kMaxAtlasPage) {
    out.page_size = largest_cell;
  } else if (mode == AtlasMode::Uniform) {
    out.page_size = 2048;
    while (out.page_size < largest_cell) out.page_size *= 2;
    out.page_size = std::min(out.page_size, kMaxAtlasPageSide);
  } else {
    out.page_size = bestPageSide(sizes, largest_cell, mode);
  }
  std::vector<size_t> ids(images.size());
  for (size_t i = 0; i < ids.size(); ++i) ids[i] = i;
  take(buildAtlas(images, samplers, out.page_size, mode), ids);
  return out;
}

// The word array the kernels read: header, entries, pages, then every page's texels. Returns
// the texel count.
uint64_t writeAtlasWords(const std::vector<StAtlasTexture>& entries,
                         const std::vector<std::vector<TextureImage>>& pages,
                         std::vector<uint32_t>& words) {
  StAtlasHeader header{};
  header.texture_count = uint32_t(entries.size());
  header.page_count = uint32_t(pages.size());
  const size_t texel_base =
      4 + entries.size() * (sizeof(StAtlasTexture) / 4) + pages.size() * (sizeof(StAtlasPage) / 4);
  if (texel_base > 0xFFFFFFFFull) throw Error("atlas: too many textures");
  header.texel_word_offset = uint32_t(texel_base);
  appendWords(words, header);
  for (const StAtlasTexture& e : entries) appendWords(words, e);
  uint64_t offset = 0;
  for (const auto& levels : pages) {
    if (levels.size() > ST_ATLAS_MAX_LEVELS) throw Error("atlas: page with too many mip levels");
    StAtlasPage page{};
    page.width = levels[0].width;
    page.height = levels[0].height;
    for (size_t l = 0; l < levels.size(); ++l) {
      page.offset[l] = uint32_t(offset);
      offset += uint64_t(levels[l].width) * uint64_t(levels[l].height);
    }
    appendWords(words, page);
  }
  if (texel_base + offset > 0xFFFFFFFFull)
    throw Error("atlas: " + std::to_string(offset) +
                " texels exceed the 32-bit addressing of one atlas");
  words.reserve(texel_base + offset);
  for (const auto& levels : pages)
    for (const TextureImage& im : levels)
      for (const glm::vec4& c : im.texels) words.push_back(packRgba8(c));
  return offset;
}

}  // namespace

DeviceAtlas buildDeviceAtlas(const WorldGeometry& g, AtlasChoice choice) {
  DeviceAtlas out;
  if (!g.textured()) return out;
  AtlasEntries e = collectEntries(g, out.material_entry);
  const PlacedPages placed = placeTextures(g, e.placements, choice);
  for (size_t i = 0; i < e.entries.size(); ++i) {
    const AtlasPlacement& p = placed.where[e.entry_placement[i]];
    e.entries[i].page = p.page;
    e.entries[i].cell_x = p.cell_x;
    e.entries[i].cell_y = p.cell_y;
    e.entries[i].width = p.w;
    e.entries[i].height = p.h;
    e.entries[i].levels = p.levels;
  }
  out.texels = writeAtlasWords(e.entries, placed.pages, out.words);
  out.page_size = placed.page_size;
  out.entries = uint32_t(e.entries.size());
  out.placements = uint32_t(e.placements.size());
  out.pages = uint32_t(placed.pages.size());
  out.occupancy = placed.page_texels > 0 ? placed.used / placed.page_texels : 0.0;
  return out;
}

}  // namespace strata
