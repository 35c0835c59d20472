// The shared OpenCL front end and frame loop. One frame, as data flows (DESIGN.md):
//   sort draw units -> per run of equal state: transform (clip space, projection, snapping),
//   setup (clipping, edges, tile counts) -> bin (scan, fill) -> method raster/resolve
#include "engine/frontend/cl_pipeline.h"

#include <algorithm>
#include <cstring>

#include "engine/frontend/texture_shading.h"
#include "engine/frontend/view_constants.h"

namespace strata {

ClPipeline::ClPipeline(Method method, std::unique_ptr<ClMethod> impl, const DeviceOptions& device)
    : runner_(methodName(method), device), method_(method), impl_(std::move(impl)) {
  transform_ = runner_.kernel("transform_instances");
  setup_ = runner_.kernel("setup_draws");
  bin_scan_ = runner_.kernel("bin_scan");
  bin_fill_ = runner_.kernel("bin_fill");
  bin_count_serial_ = runner_.kernel("bin_count_serial");
  bin_fill_serial_ = runner_.kernel("bin_fill_serial");
  bin_tile_offsets_ = runner_.kernel("bin_tile_offsets");
  impl_->init(*this);
}

void ClPipeline::uploadScene(const WorldGeometry& geo, const DeviceAtlas& atlas,
                             bool atlas_changed) {
  scene_upload_bytes_ = 0;
  auto sceneUpload = [&](DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
    runner_.upload(b, data, bytes, purpose);
    scene_upload_bytes_ += bytes;
  };
  const std::vector<glm::vec3>& src_positions = plan_.sourcePositions(geo);
  const std::vector<uint32_t>& src_indices = plan_.sourceIndices(geo);
  sceneUpload(positions_, src_positions.data(), src_positions.size() * sizeof(glm::vec3),
              plan_.apply_instances ? "mesh positions" : "vertex positions");
  sceneUpload(indices_, src_indices.data(), src_indices.size() * sizeof(uint32_t),
              "triangle indices");
  if (plan_.source_mode == ST_SOURCE_INSTANCE) {
    ensure(materials_, 16, "triangle materials (unused)");
  } else {
    sceneUpload(materials_, geo.triangle_material.data(),
                geo.triangle_material.size() * sizeof(uint32_t), "triangle materials");
  }
  sceneUpload(material_colors_, geo.material_colors.data(),
              geo.material_colors.size() * sizeof(glm::vec4), "material colours");
  if (plan_.source_mode == ST_SOURCE_ID_MAP)
    sceneUpload(triangle_ids_, plan_.triangle_ids.data(),
                plan_.triangle_ids.size() * sizeof(uint32_t), "source triangle ids");
  else
    ensure(triangle_ids_, 16, "source triangle ids (unused)");
  if (atlas.empty()) {
    ensure(atlas_, 16, "texture atlas (unused)");
  } else if (atlas_changed ||
             atlas_.bytes != std::max<size_t>(atlas.words.size() * sizeof(uint32_t), 16)) {
    sceneUpload(atlas_, atlas.words.data(), atlas.words.size() * sizeof(uint32_t), "texture atlas");
  }
}

void ClPipeline::uploadTexturing(const WorldGeometry& geo, const DeviceAtlas& atlas) {
  if (atlas.empty()) {
    tex_host_.clear();
    ensure(tex_tris_, 16, "texturing records (unused)");
    return;
  }
  // Per view: the texture-coordinate planes.
  tex_host_ = makeTexTriangles(geo, atlas.material_entry, view_host_);
  runner_.upload(tex_tris_, tex_host_.data(), tex_host_.size() * sizeof(StTexTriangle),
                 "texturing records");
  scene_upload_bytes_ += tex_host_.size() * sizeof(StTexTriangle);
}

void ClPipeline::updateView(const FrameSettings& settings) {
  if (!updateViewConstants(view_host_, settings) || tex_host_.empty()) return;
  // A moving camera: the texturing records of the new view (non-blocking from the member; the
  // frame ends with a blocking read on this in-order queue).
  tex_host_ = makeTexTriangles(*geometry_, atlas_now_->material_entry, view_host_);
  runtime().queue().enqueueWriteBuffer(tex_tris_.buffer, CL_FALSE, 0,
                                       tex_host_.size() * sizeof(StTexTriangle), tex_host_.data());
  frame_upload_bytes_ += tex_host_.size() * sizeof(StTexTriangle);
}

void ClPipeline::prepare(const WorldGeometry& geo, const FrameSettings& settings) {
  // Textures: the atlas (rebuilt and uploaded only when the textures change) and the
  // per-triangle texturing records (per view, so per call).
  bool atlas_changed = false;
  const DeviceAtlas& atlas = atlas_cache_.get(geo, settings.atlas, &atlas_changed);
  atlas_now_ = &atlas;
  atlas_choice_ = settings.atlas;
  // Draw units (engine/features/batching.h): the batched source geometry is the scene's own data,
  // uploaded once per call; the per-frame part is uploaded in enqueueFrontEnd.
  const SceneKey key{settings.geometry_generation, settings.batch, settings.effect, settings.atlas};
  view_host_ = makeViewConstants(settings);
  geometry_ = &geo;
  if (key.generation == 0 || !(key == scene_key_) || atlas_changed) {
    scene_key_ = SceneKey{};  // nothing reusable until the uploads below have all succeeded
    plan_ = buildBatchPlan(
        geo, settings.batch, settings.effect,
        settings.atlas == AtlasChoice::Off && !atlas.empty() ? &atlas.material_entry : nullptr);
    uploadScene(geo, atlas, atlas_changed);
    scene_key_ = key;
  } else {
    scene_upload_bytes_ = 0;  // the same geometry: its buffers and plan are already here
  }
  uploadTexturing(geo, atlas);
  sort_ = settings.sort;
  sort_runs_.clear();
  triangle_count_ = plan_.triangle_count;
  view_host_.textured = atlas.empty() ? 0 : 1;

  // Working buffers sized by the frame.
  const uint32_t vertex_count = plan_.vertex_count;
  const uint32_t tile_count = runner_.tileCount();
  ensure(instances_, plan_.instances.size() * sizeof(StInstance), "instances");
  ensure(draws_, plan_.units.size() * sizeof(StDraw), "draw table");
  ensure(world_, plan_.apply_instances ? size_t(vertex_count) * sizeof(glm::vec3) : 16,
         "world positions");
  ensure(view_, sizeof(view_host_), "view constants");
  ensure(clip_, size_t(vertex_count) * 16, "clip-space vertices");
  ensure(screen_, size_t(vertex_count) * sizeof(StScreenVertex), "screen vertices");
  ensure(triangle_colors_, size_t(triangle_count_) * 16, "triangle colours");
  // The group binner counts per tile, the serial one per tile and run of records.
  bin_chunks_ = runner_.binRuns(triangle_count_);
  const size_t table = binTableSize();
  ensure(tile_counts_, countTableWords() * 4, "tile counts");
  ensure(tile_offsets_, size_t(tile_count + 1) * 4, "tile offsets");
  ensure(tile_cursors_, countTableWords() * 4, "tile cursors");
  ensure(chunk_offsets_, serialBins() ? (table + 1) * 4 : 16, "tile x chunk offsets");
  capture_depth_ = settings.capture_depth_complexity;
  ensure(depth_map_, capture_depth_ ? pixels() * 4 : 16, "depth-complexity map");
  if (overflow_capacity_ == 0) overflow_capacity_ = triangle_count_ / 64 + 1024;
  if (bin_capacity_ == 0) bin_capacity_ = 2 * size_t(triangle_count_) + tile_count + 1024;
  impl_->prepare(*this, settings);
}

// The raster stages read a record per bin entry: one cache line each.
static_assert(sizeof(StTriSetup) == 64, "a setup record is one 64-byte cache line");

void ClPipeline::beforeFrame() {
  ensure(records_, (triangle_count_ + overflow_capacity_) * sizeof(StTriSetup), "setup records");
  ensure(record_bounds_, (triangle_count_ + overflow_capacity_) * 8, "setup record bounds");
  ensure(bins_, bin_capacity_ * 4, "tile bin entries");
}

void ClPipeline::enqueueFrame(const FrameSettings& settings) {
  enqueueFrontEnd(settings);
  impl_->enqueue(*this);
}

bool ClPipeline::growIfOverflowed(const uint64_t* counters) {
  // Grow what overflowed to the count the kernels reported.
  if (counters[ST_COUNTER_SETUP_OVERFLOW] > overflow_capacity_) {
    overflow_capacity_ =
        counters[ST_COUNTER_SETUP_OVERFLOW] + counters[ST_COUNTER_SETUP_OVERFLOW] / 16;
    return true;
  }
  if (counters[ST_COUNTER_BIN_ENTRIES] > bin_capacity_) {
    bin_capacity_ = counters[ST_COUNTER_BIN_ENTRIES] + counters[ST_COUNTER_BIN_ENTRIES] / 16;
    return true;
  }
  return impl_->growIfOverflowed(*this, counters);
}

void ClPipeline::addStats(const uint64_t* counters, FrameStats& st) {
  st.triangles = triangle_count_;
  st.triangles_read = triangle_count_;  // single pass; multi-pass methods scale it in addStats
  st.tile_kernels = serialTiles() ? "serial" : "group";  // every method here has both forms
  st.batch = batchName(plan_.mode);
  st.sort = drawSortName(sort_);
  st.draw_units = plan_.units.size();
  st.launches = launches_.size();
  st.state_changes = sort_stats_.state_changes;
  st.material_changes = sort_stats_.material_changes;
  st.upload_bytes = frame_upload_bytes_;
  st.scene_upload_bytes = scene_upload_bytes_;
  st.sort_ms = summarizeTimes(sort_runs_).median;
  addAtlasStats(*atlas_now_, atlas_choice_, st);
  impl_->addStats(*this, counters, st);
  st.device_bytes = clip_.bytes + screen_.bytes + record_bounds_.bytes + world_.bytes +
                    instances_.bytes + draws_.bytes + triangle_colors_.bytes + tile_counts_.bytes +
                    tile_offsets_.bytes + tile_cursors_.bytes + chunk_offsets_.bytes +
                    records_.bytes + bins_.bytes + (capture_depth_ ? depth_map_.bytes : 0) +
                    // Layers a method keeps in local memory still count as fragment memory.
                    std::max<uint64_t>(impl_->deviceBytes(), st.fragment_bytes);
}

void ClPipeline::enqueueFrontEnd(const FrameSettings& settings) {
  const uint32_t tile_count = runner_.tileCount();
  const cl_uint overflow_cap = cl_uint(overflow_capacity_);
  const size_t record_slots = size_t(triangle_count_) + overflow_capacity_;

  // The order of the units, and the runs of equal state it gives.
  const DrawSortView sort_view{settings.camera.eye, settings.camera.forward()};
  sort_stats_ = sorter_.sort(plan_.units, sort_, sort_view, order_);
  buildDrawTable(plan_, order_, table_, launches_);

  // Per-frame uploads: view constants, the draw table, the instances. Non-blocking: the sources
  // are members, and the frame ends with a blocking read on this in-order queue.
  cl::CommandQueue& q = runtime().queue();
  frame_upload_bytes_ = 0;
  updateView(settings);
  auto write = [&](DeviceBuffer& b, const void* data, size_t bytes) {
    q.enqueueWriteBuffer(b.buffer, CL_FALSE, 0, bytes, data);
    frame_upload_bytes_ += bytes;
  };
  write(view_, &view_host_, sizeof(view_host_));
  if (!table_.empty()) write(draws_, table_.data(), table_.size() * sizeof(StDraw));
  // One write of the whole buffer in every batching mode: the draws differ in their launches,
  // not in how the instance records reach the device (and Oclgrind's uninitialised-value
  // checker, 21.10, corrupts its own memory on a write at an offset into a buffer).
  if (!plan_.instances.empty())
    write(instances_, plan_.instances.data(), plan_.instances.size() * sizeof(StInstance));

  LaunchTimer& timer = runner_.timer();
  // The serial binner (CPU devices, and methods that need the drawing order) counts in its own
  // pass, without atomics: setup is told tiles_x 0 and so leaves the counts alone.
  const bool serial = serialBins();
  const size_t table = binTableSize();
  timer.fill("clear", tile_counts_.buffer, 0u, countTableWords() * 4);
  const cl_uint apply = plan_.apply_instances ? 1u : 0u;
  cl::Buffer& world = plan_.apply_instances ? world_.buffer : positions_.buffer;
  for (const DrawLaunch& l : launches_) {
    if (l.vertex_total > 0) {
      setArgs(transform_, positions_.buffer, instances_.buffer, draws_.buffer,
              cl_uint(l.first_draw), cl_uint(l.draw_count), cl_uint(l.vertex_total), apply,
              view_.buffer, clip_.buffer, screen_.buffer, world_.buffer);
      timer.launch("transform", transform_, cl::NDRange(roundUp(l.vertex_total, ST_LINEAR_WG)),
                   cl::NDRange(ST_LINEAR_WG));
    }
    if (l.triangle_total > 0) {
      setArgs(setup_, world, indices_.buffer, draws_.buffer, cl_uint(l.first_draw),
              cl_uint(l.draw_count), cl_uint(l.triangle_total), cl_uint(plan_.source_mode),
              triangle_ids_.buffer, instances_.buffer, materials_.buffer, material_colors_.buffer,
              cl_uint(triangle_count_), clip_.buffer, screen_.buffer, view_.buffer,
              triangle_colors_.buffer, records_.buffer, record_bounds_.buffer, tile_counts_.buffer,
              cl_uint(serial ? 0u : tilesX()), overflow_cap, counters().buffer);
      timer.launch("setup", setup_, cl::NDRange(roundUp(l.triangle_total, ST_LINEAR_WG)),
                   cl::NDRange(ST_LINEAR_WG));
    }
  }
  if (serial) {
    // Count per (tile, chunk), scan the table, gather each tile's offsets, fill in slot order.
    const cl_uint chunks = cl_uint(bin_chunks_);
    setArgs(bin_count_serial_, record_bounds_.buffer, cl_uint(triangle_count_), overflow_cap,
            counters().buffer, chunks, cl_uint(tilesX()), cl_uint(tile_count), tile_counts_.buffer);
    timer.launch("bin", bin_count_serial_, cl::NDRange(chunks), cl::NDRange(1));
    setArgs(bin_scan_, tile_counts_.buffer, cl_uint(table), chunk_offsets_.buffer,
            tile_cursors_.buffer, counters().buffer, chunks);
    timer.launch("bin", bin_scan_, cl::NDRange(ST_SCAN_WG), cl::NDRange(ST_SCAN_WG));
    setArgs(bin_tile_offsets_, chunk_offsets_.buffer, chunks, cl_uint(tile_count),
            tile_offsets_.buffer);
    timer.launch("bin", bin_tile_offsets_,
                 cl::NDRange(roundUp(size_t(tile_count) + 1, ST_LINEAR_WG)),
                 cl::NDRange(ST_LINEAR_WG));
    setArgs(bin_fill_serial_, record_bounds_.buffer, cl_uint(triangle_count_), overflow_cap,
            counters().buffer, chunks, cl_uint(tilesX()), cl_uint(tile_count), tile_cursors_.buffer,
            bins_.buffer, binCapacity());
    timer.launch("bin", bin_fill_serial_, cl::NDRange(chunks), cl::NDRange(1));
    return;
  }
  setArgs(bin_scan_, tile_counts_.buffer, cl_uint(tile_count), tile_offsets_.buffer,
          tile_cursors_.buffer, counters().buffer, cl_uint(1));
  timer.launch("bin", bin_scan_, cl::NDRange(ST_SCAN_WG), cl::NDRange(ST_SCAN_WG));
  setArgs(bin_fill_, record_bounds_.buffer, cl_uint(triangle_count_), overflow_cap,
          counters().buffer, cl_uint(tilesX()), tile_offsets_.buffer, tile_cursors_.buffer,
          bins_.buffer, binCapacity());
  timer.launch("bin", bin_fill_, cl::NDRange(roundUp(record_slots, ST_LINEAR_WG)),
               cl::NDRange(ST_LINEAR_WG));
}

}  // namespace strata
