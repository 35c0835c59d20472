// `cells`: the convex-polyhedra method (methods/convex-cells.md). Per render call the scene's
// meshes are decomposed into convex cells (cached on disk); per frame the host orders the cells
// for the view (engine/cells/cell_order.cpp) and streams them through the device in batches: setup
// in drawing order, ordered binning, then one tile-owned kernel that composites every group's front
// and back layers in order. Device memory depends on the batch size, the image and the scene's
// vertices (uploaded once, projected once per view), never on the depth complexity or the
// scene's triangle count beyond one batch.
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <future>
#include <optional>

#include "engine/cells/cell_masks_device.h"
#include "engine/cells/cell_order.h"
#include "engine/cells/ordered_bins.h"
#include "engine/features/device_atlas.h"
#include "engine/frontend/cl_pipeline.h"
#include "engine/frontend/frame_runner.h"
#include "engine/frontend/texture_shading.h"
#include "engine/frontend/view_constants.h"
#include "preprocess/core/hash.h"

namespace strata {

namespace {

struct Batch {
  uint32_t first = 0, cells = 0, triangles = 0;   // ordered cells [first, first + cells)
  glm::ivec4 rect{INT32_MAX, INT32_MAX, -1, -1};  // pixels its groups may cover
};

class CellsRenderer final : public MethodRenderer, private FrameStages {
 public:
  explicit CellsRenderer(const DeviceOptions& device)
      : runner_("cells", device), ordered_bins_(runner_) {
    setup_ = runner_.kernel("cells_setup");
    normals_ = runner_.kernel("triangle_normals");
    composite_ = runner_.kernel("cells_composite");
    composite_serial_ = runner_.kernel("cells_composite_serial");
    compute_units_ = runner_.runtime().device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
    k_limit_ = runner_.localLayers(ST_MAX_K, 2, "cells");
  }

  ~CellsRenderer() override { dropNextOrder(); }

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override {
    return runner_.render(geometry, settings, *this);
  }

 private:
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
    runner_.ensure(b, bytes, purpose);
  }
  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
    runner_.upload(b, data, bytes, purpose);
  }

  // Which composite kernel CellsOptions::composite asks for on this device (auto: as the tile
  // kernels of every method, FrameSettings::tile_kernels).
  bool compositeIsSerial(const FrameSettings& s) {
    const std::string& choice = s.cells.composite;
    if (choice == "serial") return true;
    if (choice == "group") return false;
    if (choice != "auto")
      throw Error("cells: unknown composite kernel '" + choice + "' (auto, group or serial)");
    return runner_.serialTilesFor(s.tile_kernels);
  }

  // Where CellsOptions::order_masks asks for the order's pixel masks (auto: the host; a CPU
  // device shares its cores with it, and on an H200 the device's were not faster).
  static bool orderMasksOnDevice(const FrameSettings& s) {
    const std::string& choice = s.cells.order_masks;
    if (choice != "auto" && choice != "host" && choice != "device")
      throw Error("cells: unknown place for the order masks '" + choice +
                  "' (auto, host or device)");
    return choice == "device";
  }
  // Whether CellsOptions::tile_segments asks the order for tile segments (auto: for a still
  // camera, whose order serves every frame; a moving one orders every frame).
  static bool tileSegmentsFor(const FrameSettings& s) {
    const std::string& choice = s.cells.tile_segments;
    if (choice != "auto" && choice != "on" && choice != "off")
      throw Error("cells: tile segments '" + choice + "': expected auto, on or off");
    return choice == "on" || (choice == "auto" && s.orbit_deg == 0.0f);
  }
  // Held only while the masks are on the device (null otherwise).
  CellMaskDevice* orderMasks() { return order_masks_.get(); }

  // A moving camera's next view, ordered on a host thread while the device draws the current
  // one (willRender). At most one is in flight; the scene it reads must outlive it.
  struct NextOrder {
    StViewConstants view;
    CellOrder order;
    double ms = 0.0;
  };
  // The serial composite has no use for the tile segments (empty segments are also right for
  // the group kernel: every pass one segment).
  bool segmentsWanted() const { return !serial_composite_ && tile_segments_; }

  // Whether the next frame draws the current order again (CellsOptions::order_reuse): the
  // composite checks it and repairs it, for strict cells (one fragment per layer, so a second
  // one there is a disorder) in a frame of one batch (the repair composites a tile's whole list
  // at once).
  bool reuseNext() const {
    return moving_ && order_valid_ && order_scene_key_ == scene_key_ && !reuse_blocked_ &&
           order_age_ < order_reuse_ && order_batches_.size() <= 1 &&
           scene_->mode == DecomposeMode::Strict && order_view_.width == view_host_.width &&
           order_view_.height == view_host_.height;
  }

  void dropNextOrder() {
    if (next_order_.valid()) next_order_.wait();
    next_order_ = {};
    next_ready_.reset();
  }

  void willRender(const FrameSettings& next) override {
    if (!moving_ || !scene_ || !order_ahead_ || reuseNext()) return;
    dropNextOrder();
    StViewConstants view = view_host_;
    updateViewConstants(view, next);
    const CellScene* scene = scene_.get();
    const bool segments = segmentsWanted();
    CellMaskDevice* masks = orderMasks();
    next_order_ = std::async(std::launch::async, [scene, view, next, segments, masks] {
      const auto t0 = std::chrono::steady_clock::now();
      NextOrder o{view, orderCells(*scene, next.camera, next.width, next.height, segments, masks),
                  0.0};
      o.ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      return o;
    });
  }

  void prepareScene(const WorldGeometry& geo, const FrameSettings& s) {
    DecomposeOptions options;
    options.mode = parseDecomposeMode(s.decompose);
    const std::string cell_options = s.decompose + "|" + s.cell_cache_dir;
    if (s.geometry_generation != 0 && s.geometry_generation == scene_generation_ && scene_ &&
        cell_options == scene_options_)
      return;  // the same geometry: skip even hashing it
    scene_generation_ = 0;
    std::string key(reinterpret_cast<const char*>(geo.positions.data()),
                    geo.positions.size() * sizeof(glm::vec3));
    uint64_t h = fnv1a64(key);
    h = fnv1a64(
        std::string(reinterpret_cast<const char*>(geo.indices.data()), geo.indices.size() * 4), h);
    h = fnv1a64(s.decompose + "|" + s.cell_cache_dir, h);
    // Materials and colours too: two scenes may share the geometry and differ in colour.
    h = fnv1a64(geo.triangle_material.data(), geo.triangle_material.size() * 4, h);
    h = fnv1a64(geo.material_colors.data(), geo.material_colors.size() * sizeof(glm::vec4), h);
    for (const GeometryPart& p : geo.parts)
      h = fnv1a64(std::string(reinterpret_cast<const char*>(&p.mesh), sizeof(p.mesh)), h);
    if (h == scene_key_ && scene_) {
      scene_generation_ = s.geometry_generation;
      scene_options_ = cell_options;
      return;
    }
    order_masks_.reset();  // it refers to the scene
    // The clip pieces' and tile lists' capacities are sized anew from the new scene's first
    // frame, not kept from an earlier, larger scene (a benchmark's working set per scene).
    overflow_capacity_ = bin_capacity_ = 0;
    scene_ = std::make_unique<CellScene>(CellScene::build(geo, options, s.cell_cache_dir));
    scene_key_ = h;
    scene_bounds_ = Bounds{};
    for (const Bounds& c : scene_->cell_box) {
      if (c.empty()) continue;
      scene_bounds_.extend(c.min);
      scene_bounds_.extend(c.max);
    }
    upload(positions_, geo.positions.data(), geo.positions.size() * sizeof(glm::vec3),
           "vertex positions");
    upload(indices_, geo.indices.data(), geo.indices.size() * 4, "triangle indices");
    upload(materials_, geo.triangle_material.data(), geo.triangle_material.size() * 4,
           "triangle materials");
    upload(material_colors_, geo.material_colors.data(),
           geo.material_colors.size() * sizeof(glm::vec4), "material colours");
    upload(cell_first_, scene_->cell_first.data(), scene_->cell_first.size() * 4, "cell offsets");
    upload(cell_triangles_, scene_->cell_triangles.data(), scene_->cell_triangles.size() * 4,
           "cell triangles");
    upload(triangle_flip_, scene_->triangle_flip.data(), scene_->triangle_flip.size(),
           "triangle facing in cells");
    vertex_count_ = uint32_t(geo.positions.size());
    // Every triangle's unit normal, once per scene: setup shades from it each view.
    const uint32_t triangles = uint32_t(geo.triangleCount());
    ensure(triangle_normals_, std::max<size_t>(triangles, 1) * 12, "triangle normals");
    setArgs(normals_, positions_.buffer, indices_.buffer, cl_uint(triangles),
            cl_uint(vertex_count_), triangle_normals_.buffer);
    if (triangles > 0)
      runner_.timer().launch("setup", normals_, cl::NDRange(roundUp(triangles, ST_LINEAR_WG)),
                             cl::NDRange(ST_LINEAR_WG));
    scene_generation_ = s.geometry_generation;
    scene_options_ = cell_options;
  }

  // Orders the cells for the view and cuts the order into batches; uploads the per-view arrays.
  // The order depends on the view only: while the camera and the image size stay the same
  // (a still view rendered again) the last one is reused and *order_ms is 0.
  std::vector<Batch> orderForView(const FrameSettings& s, const StViewConstants& view,
                                  double* order_ms) {
    stale_frame_ = false;
    if (order_valid_ && order_scene_key_ == scene_key_ &&
        std::memcmp(&order_view_, &view, sizeof(view)) == 0) {
      *order_ms = 0.0;
      return order_batches_;
    }
    // A moving camera may draw the last order again for a few frames: checked as it is
    // composited, repaired where it fails.
    if (reuseNext()) {
      ++order_age_;
      stale_frame_ = true;
      *order_ms = 0.0;
      return order_batches_;
    }
    order_age_ = 0;
    auto t0 = std::chrono::steady_clock::now();
    // The order a previous frame started for this view (willRender), else one made now.
    double ahead_ms = 0.0;  // the time of an order made ahead, on its own thread
    if (next_order_.valid()) {
      next_ready_.emplace(next_order_.get());
      order_wait_ms_ =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    }
    if (next_ready_ && std::memcmp(&next_ready_->view, &view, sizeof(view)) == 0) {
      order_ = std::move(next_ready_->order);
      ahead_ms = next_ready_->ms;
      next_ready_.reset();
      t0 = std::chrono::steady_clock::now();
    } else {
      order_wait_ms_ = -1.0;
      order_ = orderCells(*scene_, s.camera, s.width, s.height, segmentsWanted(), orderMasks());
    }
    const CellScene& sc = *scene_;
    const uint32_t n = uint32_t(order_.cells.size());
    order_start_.assign(n + 1, 0);
    order_group_.resize(n);
    std::vector<Batch> batches;
    Batch cur;
    for (uint32_t g = 0; g < order_.groupCount(); ++g) {
      uint32_t tris = 0;
      for (uint32_t k = order_.group_first[g]; k < order_.group_first[g + 1]; ++k) {
        const uint32_t c = order_.cells[k];
        tris += sc.cell_first[c + 1] - sc.cell_first[c];
        order_start_[k + 1] = order_start_[k] + (sc.cell_first[c + 1] - sc.cell_first[c]);
      }
      const uint32_t cells = order_.group_first[g + 1] - order_.group_first[g];
      // The group composite walks a tile's list by passes (groups that share no pixel centre),
      // or by tile segments of them. The serial one flushes a pixel's group when a later one
      // reaches it, so its records carry their group's rank instead: the same flushes for
      // this view's order, and for an earlier view's, whose groups of one pass may now overlap,
      // still one group at a time (the group kernel's check flags such overlaps instead).
      const uint32_t rank = serial_composite_ ? g : uint32_t(order_.group_pass[g]);
      const uint32_t tag = rank | (cells == 1 ? ST_CELLS_SINGLE_CELL : 0u);
      for (uint32_t k = order_.group_first[g]; k < order_.group_first[g + 1]; ++k)
        order_group_[k] = tag;
      if (cur.cells > 0 && size_t(cur.triangles) + tris > batch_triangles_) {
        batches.push_back(cur);
        cur = Batch{order_.group_first[g], 0, 0};
      }
      cur.cells += cells;
      cur.triangles += tris;
      const glm::ivec4 r = order_.group_rect[g];
      if (r.x <= r.z)
        cur.rect = glm::ivec4(std::min(cur.rect.x, r.x), std::min(cur.rect.y, r.y),
                              std::max(cur.rect.z, r.z), std::max(cur.rect.w, r.w));
    }
    if (cur.cells > 0) batches.push_back(cur);
    upload(order_cells_, order_.cells.data(), size_t(n) * 4, "cell order");
    upload(order_start_buf_, order_start_.data(), size_t(n + 1) * 4, "cell order offsets");
    upload(order_group_buf_, order_group_.data(), size_t(n) * 4, "cell order groups");
    upload(tile_break_first_, order_.tile_break_first.data(), order_.tile_break_first.size() * 4,
           "tile segment offsets");
    upload(tile_breaks_, order_.tile_breaks.data(), order_.tile_breaks.size() * 4,
           "tile segment passes");
    *order_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    *order_ms += ahead_ms;
    order_valid_ = true;
    order_scene_key_ = scene_key_;
    order_view_ = view;
    order_batches_ = batches;
    last_order_ms_ = *order_ms;
    return batches;
  }

  // The batch limit: the option's, or under a memory budget the most triangles whose buffers fit
  // beside what the frame needs whatever the batch (the scene, its projected vertices, the
  // per-pixel state, the largest k-buffers), with a quarter to spare for what grows with the
  // scene's coverage (bin entries, clipped pieces). A batch still holds at least one whole
  // group; a budget too small for that is reported after the frame (the renderer's check).
  size_t batchForBudget(const WorldGeometry& geo, const FrameSettings& s) const {
    const uint64_t budget = s.memory_budget;
    if (budget == 0) return s.cells.batch_triangles;
    const bool translucent = s.effect == Effect::Translucency;
    const uint64_t pixels = uint64_t(s.width) * uint64_t(s.height);
    const uint64_t tiles = uint64_t((s.width + 7) / 8) * uint64_t((s.height + 7) / 8);
    const uint64_t fixed = geo.positions.size() * (12 + sizeof(StScreenVertex)) +
                           geo.indices.size() * 4 + geo.triangle_material.size() * 4 +
                           geo.material_colors.size() * 16 + pixels * (translucent ? 20 : 12) +
                           tiles * 8 + ST_COUNTER_COUNT * 8 +
                           uint64_t(compute_units_) * ST_TILE_PIXELS * k_limit_ * 8;
    // Per triangle slot: its record, bounds, group, colour, (normal), depth bounds, clip piece
    // and triangle; two bin entries with their sort keys; the tile x run tables.
    const uint64_t per_triangle = (sizeof(StTriSetup) + 8 + 4 + 16 + (translucent ? 16 : 0) + 8 +
                                   8 + 4 + 2 * (4 + 8) + 3 * 2 * 4) *
                                  5 / 4;
    if (budget <= fixed)
      throw Error("cells: a memory budget of " + megabytes(budget) +
                  " is too small: the scene, its projected vertices and the image need " +
                  megabytes(fixed) + " before any triangle is drawn");
    return size_t(std::clamp<uint64_t>((budget - fixed) / per_triangle, 1,
                                       uint64_t(s.cells.batch_triangles)));
  }

  void sizeBuffers(uint32_t batch_capacity, const FrameSettings& s) {
    const size_t slots = size_t(batch_capacity) + overflow_capacity_;
    const bool translucent = s.effect == Effect::Translucency;  // the normals' only reader
    records_.size([this](auto&&... a) { ensure(a...); }, slots, translucent, "cell setup records",
                  "record groups");
    ensure(record_depths_, slots * 8, "record depth bounds");
    ensure(slot_extra_, size_t(batch_capacity) * 8, "clip pieces");
    ensure(slot_triangle_, size_t(batch_capacity) * 4, "slot triangles");
    ensure(screen_, std::max<size_t>(vertex_count_, 1) * sizeof(StScreenVertex), "screen vertices");
    // The binner takes the composite's form: serial on CPU devices, group on GPUs.
    ordered_bins_.size(serial_composite_, runner_.binRuns(batch_capacity), bin_capacity_);
    ensure(bins_, bin_capacity_ * 4, "tile bin entries");
    ensure(batch_counters_, ST_COUNTER_COUNT * 8, "batch counters");
    ensure(accum_, size_t(s.width) * s.height * 8, "accumulated colour and transmittance");
    ensure(accum_extra_, translucent ? size_t(s.width) * s.height * 8 : 16, "translucency state");
    ensure(depth_map_, size_t(s.width) * s.height * 4, "fragments per pixel");
    // Only the group kernel's repair launch reads them (the serial kernel repairs in place).
    ensure(tile_flags_, serial_composite_ ? 8 : size_t(tile_count_) * 8, "pixels to repair");
  }

  void enqueueBatch(const Batch& b, uint32_t batch_capacity, bool first, bool last,
                    const FrameSettings& s) {
    runner_.timer().fill("clear", batch_counters_.buffer, 0u, ST_COUNTER_COUNT * 8);
    // The frame starts from the background, so each batch's composite touches only the pixels
    // it composites a fragment at (the image holds the others' result so far) and skips empty
    // tiles. Every batch then costs its own pixels, not the image's.
    const bool background_filled = true;
    const cl_int layer_write =
        scene_->mode == DecomposeMode::Strict ? ST_CELLS_LAYER_STORE : ST_CELLS_LAYER_ATOMIC_MAX;
    // A frame whose composite reads no depth (the serial kernel's plain tiles: flat colours,
    // strict cells, no order check; and no merged group to sort) has each record carry its
    // colour in place of its depth planes: one cache line per record in the composite.
    const bool colour_in_record = serial_composite_ && !stale_frame_ && !view_host_.textured &&
                                  s.effect != Effect::Translucency &&
                                  layer_write == ST_CELLS_LAYER_STORE && background_filled &&
                                  order_.merged_groups == 0;
    const cl_uint overflow = cl_uint(overflow_capacity_);
    ordered_bins_.enqueueSlotLayout(cell_first_.buffer, cell_triangles_.buffer, false,
                                    order_cells_.buffer, order_start_buf_.buffer,
                                    order_group_buf_.buffer, b.first, b.cells, b.triangles,
                                    records_.group.buffer, slot_triangle_.buffer);
    setArgs(setup_, positions_.buffer, indices_.buffer, triangle_normals_.buffer, cl_int(1),
            materials_.buffer, material_colors_.buffer, cl_uint(vertex_count_),
            triangle_flip_.buffer, cl_int(1), cl_int(stale_frame_ ? 1 : 0), cl_int(0),
            slot_triangle_.buffer, cl_uint(b.triangles), cl_uint(batch_capacity), cl_int(1),
            screen_.buffer, view_.buffer, records_.setup.buffer, records_.bounds.buffer,
            records_.group.buffer, records_.color.buffer, records_.normal.buffer,
            record_depths_.buffer, slot_extra_.buffer, overflow, batch_counters_.buffer,
            runner_.counters().buffer, cl_int(colour_in_record ? 1 : 0));
    runner_.timer().launch("setup", setup_, cl::NDRange(roundUp(b.triangles, ST_LINEAR_WG)),
                           cl::NDRange(ST_LINEAR_WG));
    ordered_bins_.enqueue(records_.bounds.buffer, slot_extra_.buffer, b.triangles, batch_capacity,
                          overflow, batch_counters_.buffer, bins_.buffer, bin_capacity_,
                          runner_.counters().buffer);
    if (first) runner_.fillBackground(view_.buffer, depth_map_, "composite");
    // Only the blocks of tiles the batch's groups may cover: as the order found them for its
    // view, or, in a frame drawn with an earlier view's order (one batch), the scene's box.
    const glm::ivec4 rect =
        stale_frame_ ? boxPixelRect(scene_bounds_.min, scene_bounds_.max, view_host_) : b.rect;
    const cl_uint4 block_range = runner_.blockRange(rect);
    if (block_range.s[2] == 0) return;  // nothing on screen
    // Both composite kernels take the same arguments (the serial one ignores the segments).
    cl::Kernel& composite = serial_composite_ ? composite_serial_ : composite_;
    // The serial kernel repairs a frame drawn with an earlier view's order in the same launch,
    // tile by tile: its k-buffer holds the repair's too.
    const bool repair_apart = stale_frame_ && !serial_composite_;
    const uint32_t k =
        stale_frame_ && serial_composite_ ? std::max(k_capacity_, repair_k_) : k_capacity_;
    setArgs(composite, records_.setup.buffer, records_.group.buffer, records_.color.buffer,
            records_.normal.buffer, tex_tris_.buffer, atlas_.buffer, bins_.buffer,
            ordered_bins_.offsets(), cl_uint(ordered_bins_.runs()), cl_uint(tiles_x_),
            cl_uint(bin_capacity_), cl_int(order_.tile_break_first.empty() ? 0 : 1),
            tile_break_first_.buffer, tile_breaks_.buffer, view_.buffer, layer_write,
            cl::Local(size_t(ST_TILE_PIXELS) * k * 8), cl_uint(k), accum_.buffer,
            accum_extra_.buffer, cl_int(first ? ST_FIRST_BATCH_FRESH : 0), cl_int(last ? 1 : 0),
            cl_int(background_filled ? 1 : 0), runner_.image().buffer, runner_.counters().buffer,
            depth_map_.buffer, cl_int(stale_frame_ ? ST_CELLS_ORDER_CHECK : ST_CELLS_ORDER_TRUSTED),
            tile_flags_.buffer, record_depths_.buffer, block_range, batch_counters_.buffer,
            cl_int(colour_in_record ? 1 : 0));
    if (repair_apart) runner_.timer().fill("composite", tile_flags_.buffer, 0u, tile_flags_.bytes);
    runner_.launchBlocks("composite", composite, block_range, serial_composite_);
    if (repair_apart) {
      // The pixels whose check failed, composited again with every fragment sorted, in a
      // k-buffer of their own size (a whole pixel's fragments, not a merged group's).
      composite.setArg(kLayersArg, cl::Local(size_t(ST_TILE_PIXELS) * repair_k_ * 8));
      composite.setArg(kLayersArg + 1, cl_uint(repair_k_));
      composite.setArg(kOrderCheckArg, cl_int(ST_CELLS_ORDER_REPAIR));
      runner_.launchBlocks("repair", composite, block_range, false);
    }
  }
  // The composite kernels' arguments: the k-buffer (then its capacity), and order_check.
  static constexpr cl_uint kLayersArg = 16, kOrderCheckArg = 26;

  // FrameStages
  void prepare(const WorldGeometry& geo, const FrameSettings& s) override {
    dropNextOrder();  // it reads the scene, which may change now
    if (s.cells.batch_triangles < 1)
      throw Error("cells: the batch size must be at least one triangle");
    const bool serial = compositeIsSerial(s);
    if (serial != serial_composite_) {
      serial_composite_ = serial;
      order_valid_ = false;  // only the group composite has the order cut into tile segments
    }
    const bool tile_segments = tileSegmentsFor(s);
    if (tile_segments != tile_segments_) {
      tile_segments_ = tile_segments;
      order_valid_ = false;
    }
    const size_t batch = batchForBudget(geo, s);
    if (batch != batch_triangles_) {
      batch_triangles_ = batch;
      order_valid_ = false;  // the batches are cut from the order
    }
    prepareScene(geo, s);
    if (!orderMasksOnDevice(s))
      order_masks_.reset();  // its scene arrays and buffers on the device
    else if (!order_masks_ || &order_masks_->scene() != scene_.get())
      order_masks_ = std::make_unique<ClCellMasks>(runner_.runtime(), *scene_);
    tiles_x_ = runner_.tilesX();
    tiles_y_ = runner_.tilesY();
    tile_count_ = runner_.tileCount();
    // Textures: the atlas (rebuilt and uploaded only when the textures change) and the
    // per-triangle texturing records (per view, so per call).
    bool atlas_changed = false;
    atlas_now_ = &atlas_cache_.get(geo, s.atlas, &atlas_changed);
    atlas_choice_ = s.atlas;
    const DeviceAtlas& atlas = *atlas_now_;
    view_host_ = makeViewConstants(s);
    if (atlas.empty()) {
      ensure(tex_tris_, 16, "texturing records (unused)");
      ensure(atlas_, 16, "texture atlas (unused)");
    } else {
      tex_host_ = makeTexTriangles(geo, atlas.material_entry, view_host_);
      upload(tex_tris_, tex_host_.data(), tex_host_.size() * sizeof(StTexTriangle),
             "texturing records");
      if (atlas_changed ||
          atlas_.bytes != std::max<size_t>(atlas.words.size() * sizeof(uint32_t), 16))
        upload(atlas_, atlas.words.data(), atlas.words.size() * sizeof(uint32_t), "texture atlas");
    }
    if (atlas.empty()) tex_host_.clear();
    view_host_.textured = atlas.empty() ? 0 : 1;
    upload(view_, &view_host_, sizeof(view_host_), "view constants");
    geometry_ = &geo;
    moving_ = s.orbit_deg != 0.0f;
    // An order made ahead runs on a thread of its own, and with the masks on the device it makes
    // OpenCL calls beside the frame's: not under Oclgrind, whose runtime is not thread-safe.
    order_ahead_ = s.cells.order_ahead && !(order_masks_ && runner_.runtime().info().isOclgrind());
    if (moving_) order_valid_ = false;  // every frame of a moving camera orders its view
    order_reuse_ = s.cells.order_reuse;
    reuse_blocked_ = false;
    order_age_ = 0;
    stale_frame_ = false;
    order_reused_frames_ = 0;
    repair_tiles_.clear();
    repair_pixels_.clear();
    order_runs_.clear();
    order_waits_.clear();
    triangles_ = geo.triangleCount();
    translucent_ = s.effect == Effect::Translucency;
    order_cached_frames_ = 0;
  }

  // A moving camera: the frame's view constants and texturing records when the view changed
  // (non-blocking from members; the frame ends with a blocking read on this in-order queue).
  void updateView(const FrameSettings& s) {
    if (!updateViewConstants(view_host_, s)) return;
    cl::CommandQueue& q = runner_.runtime().queue();
    q.enqueueWriteBuffer(view_.buffer, CL_FALSE, 0, sizeof(view_host_), &view_host_);
    if (tex_host_.empty()) return;
    tex_host_ = makeTexTriangles(*geometry_, atlas_now_->material_entry, view_host_);
    q.enqueueWriteBuffer(tex_tris_.buffer, CL_FALSE, 0, tex_host_.size() * sizeof(StTexTriangle),
                         tex_host_.data());
  }

  void enqueueFrame(const FrameSettings& s) override {
    updateView(s);
    frame_order_ms_ = 0.0;
    order_wait_ms_ = -1.0;
    const std::vector<Batch> batches = orderForView(s, view_host_, &frame_order_ms_);
    // Buffers are sized by the batch limit once a scene needs more than one batch (by its
    // largest batch otherwise), so they never depend on the depth of the scene.
    uint32_t batch_capacity = 0;
    triangles_read_ = 0;
    for (const Batch& b : batches) {
      batch_capacity = std::max(batch_capacity, b.triangles);
      triangles_read_ += b.triangles;
    }
    if (batches.size() > 1) batch_capacity = std::max<uint32_t>(batch_capacity, batch_triangles_);
    if (overflow_capacity_ == 0) overflow_capacity_ = batch_capacity / 64 + 1024;
    if (bin_capacity_ == 0) bin_capacity_ = 2 * size_t(batch_capacity) + tile_count_ + 1024;
    sizeBuffers(batch_capacity, s);
    // Every vertex projected and snapped once for the view; batches set up from them.
    runner_.transformVertices(positions_.buffer, vertex_count_, view_.buffer, screen_.buffer);
    for (size_t i = 0; i < batches.size(); ++i)
      enqueueBatch(batches[i], batch_capacity, i == 0, i + 1 == batches.size(), s);
    if (batches.empty()) enqueueBatch(Batch{}, batch_capacity, true, true, s);
    batch_count_ = std::max<size_t>(1, batches.size());
  }

  bool growIfOverflowed(const uint64_t* counters) override {
    bool rerun = growCapacity(overflow_capacity_, counters[ST_COUNTER_SETUP_OVERFLOW], 1 << 16);
    rerun |= growCapacity(bin_capacity_, counters[ST_COUNTER_CELLS_ENTRIES], 1 << 20);
    bool grew = false;
    const uint64_t group_depth = counters[ST_COUNTER_CELLS_GROUP_DEPTH];
    if (group_depth > k_capacity_ && k_capacity_ < k_limit_) {
      k_capacity_ = uint32_t(std::min<uint64_t>(k_limit_, group_depth));
      grew = true;
    }
    const uint64_t repair_depth = counters[ST_COUNTER_CELLS_REPAIR_DEPTH];
    if (repair_depth > repair_k_ && repair_k_ < k_limit_) {
      repair_k_ = uint32_t(std::min<uint64_t>(k_limit_, repair_depth));
      grew = true;
    }
    rerun = rerun || grew;
    if (!grew && stale_frame_ && counters[ST_COUNTER_FRAGMENTS_LOST] > 0) {
      // A frame drawn with an earlier view's order that lost fragments with the largest
      // k-buffers (a pixel deeper than they hold) is drawn again with its own order, as are the
      // later ones.
      reuse_blocked_ = true;
      rerun = true;
    }
    last_repair_tiles_ = counters[ST_COUNTER_CELLS_REPAIR_TILES];
    last_repair_pixels_ = counters[ST_COUNTER_CELLS_REPAIR_PIXELS];
    // A moving camera's frame run again orders its view again, so its time includes the order
    // (an earlier view's order, run again with a larger k-buffer for its repair, stays).
    if (rerun && stale_frame_ && !reuse_blocked_)
      --order_age_;  // the same frame again
    else if (rerun && moving_)
      order_valid_ = false;
    return rerun;
  }

  void frameTimed() override {
    if (stale_frame_) {
      ++order_reused_frames_;
      repair_tiles_.push_back(double(last_repair_tiles_));
      repair_pixels_.push_back(double(last_repair_pixels_));
    } else if (frame_order_ms_ == 0.0)
      ++order_cached_frames_;
    else
      order_runs_.push_back(frame_order_ms_);
    if (order_wait_ms_ >= 0.0) order_waits_.push_back(order_wait_ms_);
  }

  DeviceBuffer& depthComplexity() override { return depth_map_; }

  void addStats(const uint64_t* counters, FrameStats& st) override {
    st.triangles = triangles_;
    st.triangles_read = triangles_read_;
    st.fragments_lost = counters[ST_COUNTER_FRAGMENTS_LOST];
    // Fragment memory: the accumulator (the paper's intermediate buffer) and the layers each
    // resident work-group keeps in local memory.
    const uint32_t k = std::max(k_capacity_, order_reused_frames_ ? repair_k_ : 0u);
    const uint64_t local_layers = uint64_t(compute_units_) * ST_TILE_PIXELS * k * 8;
    st.fragment_bytes = accum_.bytes + (translucent_ ? accum_extra_.bytes : 0) + local_layers;
    st.device_bytes = records_.bytes() + record_depths_.bytes + slot_extra_.bytes +
                      slot_triangle_.bytes + screen_.bytes + ordered_bins_.bytes() + bins_.bytes +
                      batch_counters_.bytes + depth_map_.bytes + tile_flags_.bytes +
                      st.fragment_bytes;
    st.cells = scene_->cellCount();
    st.cell_copies = scene_->copy_cells;
    st.cell_unpaired_parts = scene_->unpaired_parts;
    st.cell_groups = order_.groupCount();
    st.cell_passes = order_.passes;
    st.cell_tile_passes = order_.tile_passes;
    st.cell_tile_segments = order_.tile_breaks.size();
    st.cells_composite = serial_composite_ ? "serial" : "group";
    st.tile_kernels = st.cells_composite;  // the composite is its one per-tile kernel
    st.largest_group = order_.largest_group;
    st.merged_groups = order_.merged_groups;
    st.merged_cells = order_.merged_cells;
    st.grid[0] = scene_->grid.dims.x;
    st.grid[1] = scene_->grid.dims.y;
    st.grid[2] = scene_->grid.dims.z;
    st.preprocess_ms = scene_->preprocess_ms;
    st.preprocess_cached = scene_->from_cache;
    // Per view: the median over the timed frames that ordered a new view (a moving camera),
    // else what the view cost when it was ordered.
    st.order_ms = order_runs_.empty() ? last_order_ms_ : summarizeTimes(order_runs_).median;
    st.order_cached_frames = order_cached_frames_;
    st.order_overlapped_frames = order_waits_.size();
    st.order_wait_ms = order_waits_.empty() ? 0.0 : summarizeTimes(order_waits_).median;
    st.order_reused_frames = order_reused_frames_;
    st.order_repair_tiles = repair_tiles_.empty() ? 0.0 : summarizeTimes(repair_tiles_).median;
    st.order_repair_pixels = repair_pixels_.empty() ? 0.0 : summarizeTimes(repair_pixels_).median;
    st.order_masks = order_masks_ ? "device" : "host";
    st.order_device_cells = order_.device_mask_cells;
    st.order_device_bytes = order_masks_ ? order_masks_->bytes() : 0;
    st.device_bytes += st.order_device_bytes;
    st.batches = batch_count_;
    addAtlasStats(*atlas_now_, atlas_choice_, st);
    st.stage_ms["order (host, per view)"] = st.order_ms;
  }

  FrameRunner runner_;  // first member: released last
  OrderedBins ordered_bins_;
  cl::Kernel normals_, setup_, composite_, composite_serial_;
  DeviceBuffer tex_tris_, atlas_;
  DeviceAtlasCache atlas_cache_;
  const DeviceAtlas* atlas_now_ = nullptr;  // the atlas of the current render() call
  AtlasChoice atlas_choice_ = AtlasChoice::Packed;
  StViewConstants view_host_{};
  std::vector<StTexTriangle> tex_host_;      // the current view's texturing records
  const WorldGeometry* geometry_ = nullptr;  // of the current render() call
  std::vector<double> order_runs_;           // timed frames that ordered a new view
  uint64_t triangles_ = 0, triangles_read_ = 0, order_cached_frames_ = 0;
  size_t batch_count_ = 0;
  double frame_order_ms_ = 0.0;
  bool order_ahead_ = false;
  bool serial_composite_ = false;
  bool tile_segments_ = true;
  double order_wait_ms_ = -1.0;      // this frame: waited for an order made ahead (-1: none)
  std::vector<double> order_waits_;  // per timed frame that used an order made ahead
  // CellsOptions::order_reuse; frames since order_ was made for its view; whether this frame
  // draws it for another view; whether such a frame lost fragments (no more reuse this call).
  uint32_t order_reuse_ = 0, order_age_ = 0;
  uint32_t repair_k_ = 8;  // the repair's k-buffer: grown, like k_capacity_, from what it needed
  bool stale_frame_ = false, reuse_blocked_ = false;
  Bounds scene_bounds_;  // the cells' world-space box
  uint64_t order_reused_frames_ = 0, last_repair_tiles_ = 0, last_repair_pixels_ = 0;
  // per timed frame drawn with an earlier view's order
  std::vector<double> repair_tiles_, repair_pixels_;
  DeviceBuffer tile_flags_;  // per tile, the pixels whose order check failed
  std::future<NextOrder> next_order_;
  std::optional<NextOrder> next_ready_;
  bool translucent_ = false, moving_ = false;
  uint32_t compute_units_ = 1, k_limit_ = 2, k_capacity_ = 8;
  size_t batch_triangles_ = CellsOptions{}.batch_triangles;
  std::unique_ptr<CellScene> scene_;
  std::unique_ptr<ClCellMasks> order_masks_;  // refers to scene_, so declared after it
  uint64_t scene_key_ = 0;
  uint64_t scene_generation_ = 0;  // FrameSettings::geometry_generation of scene_ (0: unknown)
  std::string scene_options_;
  uint32_t vertex_count_ = 0, tiles_x_ = 0, tiles_y_ = 0, tile_count_ = 0;
  size_t overflow_capacity_ = 0, bin_capacity_ = 0;
  CellOrder order_;
  bool order_valid_ = false;
  uint64_t order_scene_key_ = 0;
  StViewConstants order_view_{};
  std::vector<Batch> order_batches_;
  double last_order_ms_ = 0.0;
  std::vector<uint32_t> order_start_, order_group_;
  DeviceBuffer positions_, indices_, triangle_normals_, materials_, material_colors_, cell_first_,
      cell_triangles_, triangle_flip_, view_, order_cells_, order_start_buf_, order_group_buf_,
      tile_break_first_, tile_breaks_;
  DeviceBuffer screen_;  // the scene's vertices projected for the current view
  GroupRecords records_;
  DeviceBuffer record_depths_, slot_extra_, slot_triangle_, bins_, batch_counters_, accum_,
      accum_extra_, depth_map_;
};

}  // namespace

std::unique_ptr<MethodRenderer> makeCellsRenderer(const DeviceOptions& device) {
  return std::make_unique<CellsRenderer>(device);
}

}  // namespace strata
