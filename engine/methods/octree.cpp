// `octree`: per-block rendering of massive scenes (methods/octree-peeling.md, docs/octree.md).
// Per render call the scene's triangles, as one soup, are sorted into an octree (cached on
// disk, preprocess/octree.h). Per view the host lists the non-empty leaves front to back from
// the octant table (no sort) and streams them through the device in batches, as the cells
// method streams cells: setup of the batch's triangle references in leaf order, ordered
// binning, then one tile-owned kernel that resolves every leaf's claimed fragments in depth
// order and composites them (kernels/octree_resolve.cl). The `dp` and `histogram` variants
// render the whole scene as one block, for comparison on the same code.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include <sys/resource.h>

#include "engine/cells/ordered_bins.h"
#include "engine/features/device_atlas.h"
#include "engine/frontend/cl_pipeline.h"
#include "engine/frontend/frame_runner.h"
#include "engine/frontend/texture_shading.h"
#include "engine/frontend/view_constants.h"
#include "engine/octree/octree_leaves.h"
#include "preprocess/core/hash.h"
#include "preprocess/octree.h"
#include "preprocess/octree_scene.h"

namespace strata {

namespace {

// The pixel rectangle a leaf's box may cover (boxPixelRect; the whole image for a root face at
// infinity, whose fragments may lie beyond the cube), its box widened a little for rounding.
glm::ivec4 screenRect(const StOctreeLeaf& b, const OctreeNode& n, const StViewConstants& v) {
  if (!std::isfinite(b.lo[0]) || !std::isfinite(b.lo[1]) || !std::isfinite(b.lo[2]) ||
      !std::isfinite(b.hi[0]) || !std::isfinite(b.hi[1]) || !std::isfinite(b.hi[2]))
    return glm::ivec4(0, 0, v.width - 1, v.height - 1);
  return boxPixelRect(n.lo - glm::vec3(n.size * 1e-3f), n.hi() + glm::vec3(n.size * 1e-3f), v);
}

class OctreeRenderer final : public MethodRenderer, private FrameStages {
 public:
  explicit OctreeRenderer(const DeviceOptions& device)
      : runner_("octree", device),
        ordered_bins_(runner_, [this](DeviceBuffer& b, size_t bytes, const char* purpose) {
          ensure(b, bytes, purpose);
        }) {
    setup_ = runner_.kernel("cells_setup");
    resolve_ = runner_.kernel("octree_resolve");
    resolve_serial_ = runner_.kernel("octree_resolve_serial");
    compute_units_ = runner_.runtime().device().getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
    k_limit_ = runner_.localLayers(ST_OCTREE_MAX_K, 1, "octree");
    chunks_ = runner_.binRunLimit();
    transfer_ = cl::CommandQueue(runner_.runtime().context(), runner_.runtime().device());
  }
  ~OctreeRenderer() override {
    try {
      transfer_.finish();  // its writes read this renderer's staging sets
    } catch (const cl::Error&) {
    }
  }

  RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) override {
    return runner_.render(geometry, settings, *this);
  }

 private:
  // Every buffer goes through these, so the bytes held are known at any time (the budget).
  void ensure(DeviceBuffer& b, size_t bytes, const char* purpose) {
    held_ -= b.bytes;
    runner_.ensure(b, bytes, purpose);
    held_ += b.bytes;
    peak_ = std::max(peak_, held_);
  }
  void upload(DeviceBuffer& b, const void* data, size_t bytes, const char* purpose) {
    ensure(b, bytes, purpose);
    runner_.upload(b, data, bytes, purpose);
  }
  void release(DeviceBuffer& b) {
    held_ -= b.bytes;
    b = DeviceBuffer();
  }

  // Bytes per batch slot: the setup record and its packed bounds, its leaf, colour, normal,
  // clip-piece entry and triangle, two bin entries (with their sort keys in the group form of
  // the ordered binner) and the overflow share; and, streamed, its three corners and material
  // (and its texturing record) in each of the two device sets uploads alternate between.
  static constexpr uint64_t kSlotWorkBase = sizeof(StTriSetup) + 8 + 4 + 16 + 16 + 8 + 3 + 4;
  uint64_t binEntryBytes() const { return 4 + OrderedBins::bytesPerEntry(runner_.serialTiles()); }
  uint64_t slotWork() const { return kSlotWorkBase + 2 * binEntryBytes(); }
  uint64_t slotStream() const { return 2 * (36 + 4 + (textured_ ? sizeof(StTexTriangle) : 0)); }

  // What a frame holds besides the batch slots and the scene: per pixel, per tile, per leaf.
  uint64_t fixedBytes(const FrameSettings& s) const {
    const uint64_t px = uint64_t(s.width) * s.height;
    const uint64_t tiles = runner_.tileCount();
    const uint64_t n = blocks_.node.size();
    return px * (4 + 8 + 4 + (s.effect == Effect::Translucency ? 8 : 0)) +
           tiles * OrderedBins::bytesPerTile(runner_.serialTiles(), chunks_) + 4 +
           (tiles + 1024) * binEntryBytes() + 1024 * slotWork() + 3 * ST_COUNTER_COUNT * 8 +
           sizeof(StViewConstants) + n * (4 + 4 + 4 + 4 + 32) + 64 + material_colors_bytes_ +
           atlas_bytes_;
  }
  uint64_t residentBytes(const WorldGeometry& geo) const {
    return geo.positions.size() * 12 + geo.triangleCount() * (12 + 4) + octree_refs_ * 4 +
           blocks_.first.size() * 4 + (textured_ ? geo.triangleCount() * sizeof(StTexTriangle) : 0);
  }

  // Chooses resident or streamed triangles and the batch size for the budget.
  void planMemory(const WorldGeometry& geo, const FrameSettings& s) {
    budget_ = s.memory_budget;
    uint64_t largest = 1;
    for (uint32_t c : blocks_.count) largest = std::max<uint64_t>(largest, c);
    batch_slots_ = s.octree.batch_triangles;
    streamed_ = false;
    // An out-of-core scene is always streamed: its triangles are only in its file.
    const bool stream = s.octree.stream || scene_file_;
    if (budget_ == 0 && !stream) return;
    const uint64_t fixed = fixedBytes(s), resident = residentBytes(geo);
    const uint64_t want =
        std::min<uint64_t>(batch_slots_, std::max<uint64_t>(largest, octree_refs_));
    if (budget_ == 0) {
      streamed_ = true;
      return;
    }
    if (!stream && fixed + resident + largest * slotWork() <= budget_) {
      batch_slots_ = std::min<uint64_t>(want, (budget_ - fixed - resident) / slotWork());
      return;
    }
    const uint64_t per_slot = slotWork() + slotStream();
    const uint64_t smallest = fixed + largest * per_slot;
    if (smallest > budget_)
      throw Error("octree: a memory budget of " + megabytes(budget_) +
                  " is too small: the image and the largest leaf (" + std::to_string(largest) +
                  " triangle references) need at least " + megabytes(smallest));
    streamed_ = true;
    batch_slots_ = std::min<uint64_t>(want, (budget_ - fixed) / per_slot);
  }

  void prepareScene(const WorldGeometry& geo, const FrameSettings& s) {
    OctreeOptions options;
    options.leaf_triangles = s.octree.leaf_triangles;
    if (options.leaf_triangles < 1)
      throw Error("octree: the face limit of a leaf must be at least 1");
    std::string scene_options = std::to_string(options.leaf_triangles) + "|" +
                                (variant_.blocks ? "blocks" : "scene") + "|" + s.cell_cache_dir;
    if (s.octree_leaves) {
      if (!variant_.blocks)
        throw Error("octree: the " + variant_name_ +
                    " variant renders the whole scene as one block, not a share of it");
      const std::vector<uint32_t>& l = *s.octree_leaves;
      scene_options += "|leaves " + std::to_string(fnv1a64(l.data(), l.size() * 4));
    }
    if (s.geometry_generation != 0 && s.geometry_generation == scene_generation_ &&
        scene_options == scene_options_)
      return;  // the same geometry: skip even hashing it
    scene_generation_ = 0;
    if (geo.out_of_core) {
      prepareSceneFile(*geo.out_of_core, geo, s, scene_options);
      scene_generation_ = s.geometry_generation;
      scene_options_ = scene_options;
      return;
    }
    scene_file_.reset();
    const MeshView mesh{geo.positions.data(), geo.positions.size(), geo.indices.data(),
                        geo.triangleCount()};
    // The scene: its triangles and also their materials and colours (two scenes may share the
    // geometry and differ in colour).
    uint64_t key = fnv1a64(scene_options, meshCacheKey("strata-octree-scene", 1, mesh, 0));
    key = fnv1a64(geo.triangle_material.data(), geo.triangle_material.size() * 4, key);
    key = fnv1a64(geo.material_colors.data(), geo.material_colors.size() * sizeof(glm::vec4), key);
    if (key != scene_key_) {
      scene_key_ = 0;
      const auto t0 = std::chrono::steady_clock::now();
      blocks_ = BlockSet{};
      if (variant_.blocks) {
        const std::string dir =
            s.cell_cache_dir.empty() ? defaultOctreeCacheDir() : s.cell_cache_dir;
        tree_ = loadOrBuildOctree(mesh, options, dir, &from_cache_);
        adoptTree(s);
        refs_host_ = &tree_.refs;
      } else {
        tree_ = Octree{};
        identity_.resize(geo.triangleCount());
        for (uint32_t t = 0; t < identity_.size(); ++t) identity_[t] = t;
        if (!identity_.empty()) {
          blocks_.node.push_back(kNoChildren);
          blocks_.first.push_back(0);
          blocks_.count.push_back(uint32_t(identity_.size()));
          StOctreeLeaf everywhere{
              {-INFINITY, -INFINITY, -INFINITY}, {INFINITY, INFINITY, INFINITY}, {0, 0}};
          blocks_.box.push_back(everywhere);
        }
        refs_host_ = &identity_;
        from_cache_ = false;
        octree_refs_ = placed_ = identity_.size();
      }
      build_ms_ =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      sceneChanged(geo, key);
    }
    scene_generation_ = s.geometry_generation;
    scene_options_ = scene_options;
  }

  // tree_ as the blocks of a blocks variant: every leaf with references, or those of the
  // settings' share.
  void adoptTree(const FrameSettings& s) {
    blocks_.block_of_node.assign(tree_.nodes.size(), kNoChildren);
    octree_refs_ = tree_.stats.refs;
    placed_ = tree_.stats.triangles - tree_.stats.skipped;
    std::vector<uint32_t> share;
    if (s.octree_leaves) {
      share = *s.octree_leaves;
      std::sort(share.begin(), share.end());
    }
    for (const LeafPlanes& leaf : octreeLeafPlanes(tree_)) {
      if (s.octree_leaves && !std::binary_search(share.begin(), share.end(), leaf.node)) continue;
      blocks_.block_of_node[leaf.node] = uint32_t(blocks_.node.size());
      blocks_.node.push_back(leaf.node);
      blocks_.first.push_back(tree_.nodes[leaf.node].first_ref);
      blocks_.count.push_back(tree_.nodes[leaf.node].ref_count);
      blocks_.box.push_back(leaf.box);
    }
  }

  void sceneChanged(const WorldGeometry& geo, uint64_t key) {
    resident_uploaded_ = false;
    upload(material_colors_, geo.material_colors.data(),
           geo.material_colors.size() * sizeof(glm::vec4), "material colours");
    material_colors_bytes_ = material_colors_.bytes;
    ensure(no_flip_, 16, "cell facing (unused)");
    vertex_count_ = uint32_t(geo.positions.size());
    order_valid_ = false;
    scene_key_ = key;
  }

  // An out-of-core octree scene: its tree as built, its leaves read from the file per batch.
  void prepareSceneFile(const OutOfCoreTriangles& ooc, const WorldGeometry& geo,
                        const FrameSettings& s, const std::string& scene_options) {
    if (!variant_.blocks)
      throw Error(ooc.path + ": the " + variant_name_ +
                  " variant renders the whole scene as one block, which needs its triangles in "
                  "memory; an octree scene streams its leaves (variants kbuffer, "
                  "blocks-histogram, blocks)");
    uint64_t key = fnv1a64(scene_options + "|" + ooc.path, ooc.file->key());
    key = fnv1a64(geo.material_colors.data(), geo.material_colors.size() * sizeof(glm::vec4), key);
    if (key == scene_key_ && scene_file_ == ooc.file) return;
    scene_key_ = 0;
    scene_file_ = ooc.file;
    tree_ = scene_file_->tree();
    blocks_ = BlockSet{};
    adoptTree(s);
    refs_host_ = nullptr;
    from_cache_ = true;
    build_ms_ = tree_.stats.build_ms;
    sceneChanged(geo, key);
  }

  // The scene's triangles on the device for the whole call, or (streamed) only per batch.
  void placeGeometry(const WorldGeometry& geo) {
    if (streamed_) {
      for (DeviceBuffer* b : {&positions_, &indices_, &materials_, &refs_, &block_first_, &screen_})
        release(*b);
      resident_uploaded_ = false;
      projected_ = false;
      return;
    }
    for (DeviceSet& d : device_sets_)
      for (DeviceBuffer* b : {&d.positions, &d.materials, &d.tex}) release(*b);
    // Without a budget the vertices are projected once per view (transform_vertices; 16 bytes
    // each); under one, setup projects each corner and the budget holds no per-vertex buffers.
    projected_ = budget_ == 0;
    if (projected_) {
      ensure(screen_, std::max<size_t>(geo.positions.size(), 1) * sizeof(StScreenVertex),
             "screen vertices");
    } else {
      release(screen_);
    }
    if (resident_uploaded_) return;
    upload(positions_, geo.positions.data(), geo.positions.size() * sizeof(glm::vec3),
           "vertex positions");
    upload(indices_, geo.indices.data(), geo.indices.size() * 4, "triangle indices");
    upload(materials_, geo.triangle_material.data(), geo.triangle_material.size() * 4,
           "triangle materials");
    upload(refs_, refs_host_->data(), refs_host_->size() * 4, "leaf triangle references");
    upload(block_first_, blocks_.first.data(), blocks_.first.size() * 4, "leaf offsets");
    resident_uploaded_ = true;
  }

  // Streamed: gathers batch b's triangles in slot order (three corners, material, texturing
  // record each) and enqueues their upload on the transfer queue; returns the device set they
  // go to. Two host staging sets and two device sets alternate, so the host gathers (or reads
  // from disk) the next batch and the transfer queue uploads it while the device renders this
  // one; the rendering queue waits for a batch's upload only, and an upload into a device set
  // waits for the last batch that read it.
  int streamBatch(const LeafBatch& b) {
    Staging& st = staging_[staging_next_];
    staging_next_ ^= 1;
    if (st.written()) {
      runner_.runtime().queue().flush();  // the upload may wait on a batch still queued
      st.done.wait();                     // its last upload has left host memory
    }
    const WorldGeometry& geo = *geo_;
    st.positions.resize(size_t(b.refs) * 9);
    st.materials.resize(b.refs);
    if (textured_) st.tex.resize(b.refs);
    size_t slot = 0;
    for (uint32_t i = b.first; i < b.first + b.leaves; ++i) {
      const uint32_t block = order_host_[i];
      if (scene_file_) {
        // Out of core: each leaf's bytes straight from the file into the staging set.
        scene_file_->readLeaf(blocks_.node[block], st.positions.data() + slot * 9,
                              st.materials.data() + slot);
        slot += blocks_.count[block];
        disk_bytes_ += uint64_t(blocks_.count[block]) * OctreeSceneFile::kBytesPerReference;
        continue;
      }
      const uint32_t* refs = refs_host_->data() + blocks_.first[block];
      for (uint32_t j = 0; j < blocks_.count[block]; ++j, ++slot) {
        const uint32_t t = refs[j];
        for (int c = 0; c < 3; ++c) {
          const glm::vec3& p = geo.positions[geo.indices[size_t(t) * 3 + c]];
          st.positions[slot * 9 + c * 3] = p.x;
          st.positions[slot * 9 + c * 3 + 1] = p.y;
          st.positions[slot * 9 + c * 3 + 2] = p.z;
        }
        st.materials[slot] = geo.triangle_material[t];
        if (textured_) st.tex[slot] = tex_host_[t];
      }
    }
    const int set = device_next_;
    device_next_ ^= 1;
    DeviceSet& d = device_sets_[set];
    std::vector<cl::Event> after;
    if (d.free()) after.push_back(d.free);
    const size_t pos_bytes = st.positions.size() * 4, mat_bytes = st.materials.size() * 4;
    transfer_.enqueueWriteBuffer(d.positions.buffer, CL_FALSE, 0, pos_bytes, st.positions.data(),
                                 &after);
    transfer_.enqueueWriteBuffer(d.materials.buffer, CL_FALSE, 0, mat_bytes, st.materials.data(),
                                 &after);
    streamed_bytes_ += pos_bytes + mat_bytes;
    if (textured_) {
      const size_t tex_bytes = st.tex.size() * sizeof(StTexTriangle);
      transfer_.enqueueWriteBuffer(d.tex.buffer, CL_FALSE, 0, tex_bytes, st.tex.data(), &after);
      streamed_bytes_ += tex_bytes;
    }
    transfer_.enqueueMarkerWithWaitList(nullptr, &st.done);
    transfer_.flush();
    const std::vector<cl::Event> uploaded{st.done};
    runner_.runtime().queue().enqueueBarrierWithWaitList(&uploaded);
    return set;
  }

  // The blocks front to back for the view, cut into batches; uploads the per-view arrays. While
  // the view stays the same the last order is reused.
  const std::vector<LeafBatch>& orderForView(const FrameSettings& s) {
    if (order_valid_ && std::memcmp(&order_view_, &view_host_, sizeof(view_host_)) == 0)
      return batches_;
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<uint32_t> order;  // blocks
    if (variant_.blocks) {
      std::vector<uint32_t> leaves;
      if (!tree_.empty())
        frontToBackLeaves(tree_, s.camera.projection == Projection::Perspective, s.camera.eye,
                          s.camera.forward(), leaves);
      for (uint32_t node : leaves)
        if (blocks_.block_of_node[node] != kNoChildren)
          order.push_back(blocks_.block_of_node[node]);
    } else if (!blocks_.node.empty()) {
      order.push_back(0);
    }
    const uint32_t n = uint32_t(order.size());
    order_start_.assign(n + 1, 0);
    order_tag_.resize(n);
    order_box_.resize(n);
    order_refs_.resize(n);
    batches_.clear();
    LeafBatch cur;
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t b = order[i], refs = blocks_.count[b];
      order_start_[i + 1] = order_start_[i] + refs;
      order_tag_[i] = i;
      order_box_[i] = blocks_.box[b];
      order_refs_[i] = refs;
      if (cur.leaves > 0 && size_t(cur.refs) + refs > batch_slots_) {
        batches_.push_back(cur);
        cur = LeafBatch{i, 0, 0};
      }
      ++cur.leaves;
      cur.refs += refs;
      const glm::ivec4 r =
          blocks_.node[b] == kNoChildren
              ? glm::ivec4(0, 0, s.width - 1, s.height - 1)
              : screenRect(blocks_.box[b], tree_.nodes[blocks_.node[b]], view_host_);
      if (r.x <= r.z)
        cur.rect = glm::ivec4(std::min(cur.rect.x, r.x), std::min(cur.rect.y, r.y),
                              std::max(cur.rect.z, r.z), std::max(cur.rect.w, r.w));
    }
    if (cur.leaves > 0) batches_.push_back(cur);
    order_host_ = order;
    upload(order_blocks_, order.data(), size_t(n) * 4, "leaf order");
    upload(order_start_buf_, order_start_.data(), size_t(n + 1) * 4, "leaf order offsets");
    upload(order_tag_buf_, order_tag_.data(), size_t(n) * 4, "leaf order positions");
    upload(order_box_buf_, order_box_.data(), size_t(n) * sizeof(StOctreeLeaf), "leaf planes");
    ensure(leaf_walks_, size_t(n) * 4, "walks per leaf");
    order_ms_ =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    order_valid_ = true;
    order_view_ = view_host_;
    return batches_;
  }

  void sizeBuffers(uint32_t batch_capacity, const FrameSettings& s) {
    const size_t slots = size_t(batch_capacity) + overflow_capacity_;
    // Only translucency reads the normals (the budget's plan counts them either way).
    records_.size([this](auto&&... a) { ensure(a...); }, slots, s.effect == Effect::Translucency,
                  "leaf setup records", "record leaves");
    ensure(slot_extra_, size_t(batch_capacity) * 8, "clip pieces");
    ensure(slot_triangle_, streamed_ ? 16 : size_t(batch_capacity) * 4, "slot triangles");
    ordered_bins_.size(runner_.serialTiles(), chunks_, bin_capacity_);
    ensure(bins_, bin_capacity_ * 4, "tile bin entries");
    ensure(batch_counters_, ST_COUNTER_COUNT * 8, "batch counters");
    ensure(accum_, size_t(s.width) * s.height * 8, "accumulated colour and transmittance");
    ensure(accum_extra_, translucent_ ? size_t(s.width) * s.height * 8 : 16, "translucency state");
    ensure(depth_map_, size_t(s.width) * s.height * 4, "fragments per pixel");
    for (DeviceSet& d : device_sets_) {
      if (!streamed_) break;
      ensure(d.positions, size_t(batch_capacity) * 36, "batch triangle corners");
      ensure(d.materials, size_t(batch_capacity) * 4, "batch triangle materials");
      ensure(d.tex, textured_ ? size_t(batch_capacity) * sizeof(StTexTriangle) : 16,
             "batch texturing records");
    }
  }

  void enqueueBatch(const LeafBatch& b, uint32_t batch_capacity, bool first, bool last) {
    LaunchTimer& timer = runner_.timer();
    timer.fill("clear", batch_counters_.buffer, 0u, ST_COUNTER_COUNT * 8);
    const cl_uint overflow = cl_uint(overflow_capacity_);
    const int set = streamed_ && b.refs > 0 ? streamBatch(b) : -1;
    DeviceSet& d = device_sets_[std::max(set, 0)];
    cl::Buffer& positions = streamed_ ? d.positions.buffer : positions_.buffer;
    cl::Buffer& materials = streamed_ ? d.materials.buffer : materials_.buffer;
    cl::Buffer& indices = streamed_ ? no_flip_.buffer : indices_.buffer;
    cl::Buffer& refs = streamed_ ? no_flip_.buffer : refs_.buffer;
    cl::Buffer& first_ref = streamed_ ? no_flip_.buffer : block_first_.buffer;
    cl::Buffer& tex = streamed_ && textured_ ? d.tex.buffer : tex_tris_.buffer;
    ordered_bins_.enqueueSlotLayout(first_ref, refs, streamed_, order_blocks_.buffer,
                                    order_start_buf_.buffer, order_tag_buf_.buffer, b.first,
                                    b.leaves, b.refs, records_.group.buffer, slot_triangle_.buffer);
    setArgs(setup_, positions, indices, no_flip_.buffer, cl_int(0), materials,
            material_colors_.buffer, cl_uint(streamed_ ? 3 * batch_capacity : vertex_count_),
            no_flip_.buffer, cl_int(0), cl_int(0), cl_int(streamed_ ? 1 : 0), slot_triangle_.buffer,
            cl_uint(b.refs), cl_uint(batch_capacity), cl_int(projected_ ? 1 : 0),
            projected_ ? screen_.buffer : no_flip_.buffer, view_.buffer, records_.setup.buffer,
            records_.bounds.buffer, records_.group.buffer, records_.color.buffer,
            records_.normal.buffer, no_flip_.buffer, slot_extra_.buffer, overflow,
            batch_counters_.buffer, runner_.counters().buffer, cl_int(0));
    if (b.refs > 0)
      timer.launch("setup", setup_, cl::NDRange(roundUp(b.refs, ST_LINEAR_WG)),
                   cl::NDRange(ST_LINEAR_WG));
    ordered_bins_.enqueue(records_.bounds.buffer, slot_extra_.buffer, b.refs, batch_capacity,
                          overflow, batch_counters_.buffer, bins_.buffer, bin_capacity_,
                          runner_.counters().buffer);
    // A frame starts from the background, so each batch's resolve touches only the pixels it
    // composites a fragment at (the image holds the others' result so far) and skips empty
    // tiles; not a distributed share, left in the accumulator for every pixel (and maybe
    // started from a seed).
    const bool background_filled = !seed_ && !partial_;
    if (background_filled && first) runner_.fillBackground(view_.buffer, depth_map_, "resolve");
    // Only the blocks of tiles the batch's leaves may cover, but a distributed share's first
    // (and last) batch touches every pixel (starts the accumulator, finishes the image).
    const cl_uint4 block_range =
        runner_.blockRange(!background_filled && (first || last) ? runner_.imageRect() : b.rect);
    // Both forms take the same arguments (FrameRunner::serialTiles chooses).
    const bool serial = runner_.serialTiles();
    cl::Kernel& resolve = serial ? resolve_serial_ : resolve_;
    setArgs(resolve, records_.setup.buffer, records_.group.buffer, records_.color.buffer,
            records_.normal.buffer, tex, atlas_.buffer, bins_.buffer, ordered_bins_.offsets(),
            cl_uint(ordered_bins_.runs()), cl_uint(runner_.tilesX()), cl_uint(bin_capacity_),
            view_.buffer, order_box_buf_.buffer, cl_int(variant_.blocks ? 1 : 0), cl_uint(k_),
            cl_int(variant_.count_mode), cl_uint(tile_reads_),
            cl::Local(size_t(ST_TILE_PIXELS) * k_ * 8), accum_.buffer, accum_extra_.buffer,
            cl_int(first ? (seed_ ? ST_FIRST_BATCH_SEEDED : ST_FIRST_BATCH_FRESH) : 0),
            cl_int(last ? 1 : 0), cl_int(background_filled ? 1 : 0), runner_.image().buffer,
            runner_.counters().buffer, depth_map_.buffer, leaf_walks_.buffer,
            cl_float(early_out_ ? ST_OPAQUE_TRANSMITTANCE : 0.0f), block_range,
            batch_counters_.buffer);
    runner_.launchBlocks("resolve", resolve, block_range, serial);
    // The device set is free for the batch after next once this batch has read it.
    if (set >= 0) runner_.runtime().queue().enqueueMarkerWithWaitList(nullptr, &d.free);
  }

  void prepareTexturing(const WorldGeometry& geo, const FrameSettings& s) {
    bool atlas_changed = false;
    atlas_now_ = &atlas_cache_.get(geo, s.atlas, &atlas_changed);
    atlas_choice_ = s.atlas;
    const DeviceAtlas& atlas = *atlas_now_;
    if (atlas.empty()) {
      ensure(tex_tris_, 16, "texturing records (unused)");
      ensure(atlas_, 16, "texture atlas (unused)");
    } else {
      tex_host_ = makeTexTriangles(geo, atlas.material_entry, view_host_);
      if (atlas_changed ||
          atlas_.bytes != std::max<size_t>(atlas.words.size() * sizeof(uint32_t), 16))
        upload(atlas_, atlas.words.data(), atlas.words.size() * sizeof(uint32_t), "texture atlas");
    }
    view_host_.textured = atlas.empty() ? 0 : 1;
    textured_ = !atlas.empty();
    atlas_bytes_ = atlas.empty() ? 0 : atlas_.bytes;
  }

  // FrameStages
  void prepare(const WorldGeometry& geo, const FrameSettings& s) override {
    variant_ = parseVariant(s.octree);
    if (variant_.k > k_limit_)
      throw Error("octree: k = " + std::to_string(variant_.k) + " needs more local memory than " +
                  runner_.runtime().info().label() +
                  " has (at most k = " + std::to_string(k_limit_) + ")");
    k_ = variant_.k;
    variant_name_ = s.octree.variant;
    early_out_ = s.octree.early_out;
    tile_reads_ = s.octree.tile_reads;
    if (s.octree.batch_triangles < 1)
      throw Error("octree: the batch size must be at least one triangle reference");
    prepareScene(geo, s);
    view_host_ = makeViewConstants(s);
    prepareTexturing(geo, s);
    upload(view_, &view_host_, sizeof(view_host_), "view constants");
    geo_ = &geo;
    if (s.orbit_deg != 0.0f)
      order_valid_ = false;  // every frame of a moving camera orders its view
    if (s.memory_budget) {
      // Under a budget the last call's working buffers must not linger while new ones grow.
      for (DeviceBuffer* b :
           {&records_.setup, &records_.bounds, &records_.group, &records_.color, &records_.normal,
            &slot_extra_, &slot_triangle_, &screen_, &bins_, &device_sets_[0].positions,
            &device_sets_[0].materials, &device_sets_[0].tex, &device_sets_[1].positions,
            &device_sets_[1].materials, &device_sets_[1].tex})
        release(*b);
    }
    const uint64_t slots_before = batch_slots_;
    const bool streamed_before = streamed_;
    planMemory(geo, s);
    if (batch_slots_ != slots_before || streamed_ != streamed_before) {
      order_valid_ = false;
      overflow_capacity_ = bin_capacity_ = 0;
    }
    placeGeometry(geo);
    if (textured_ && !streamed_)
      upload(tex_tris_, tex_host_.data(), tex_host_.size() * sizeof(StTexTriangle),
             "texturing records");
    else
      ensure(tex_tris_, 16, "texturing records (unused or streamed)");
    peak_ = held_;
    triangles_ = scene_file_ ? scene_file_->triangles() : geo.triangleCount();
    translucent_ = s.effect == Effect::Translucency;
    partial_ = s.partial;
    seed_ = translucent_ ? s.translucency_seed : nullptr;
    if (seed_ && seed_->size() != size_t(s.width) * s.height * 2)
      throw Error("octree: the translucency seed does not cover the image");
  }

  // A moving camera: the frame's view constants and texturing records when the view changed
  // (non-blocking from members; the frame ends with a blocking read on this in-order queue).
  void updateView(const FrameSettings& s) {
    if (!updateViewConstants(view_host_, s)) return;
    cl::CommandQueue& q = runner_.runtime().queue();
    q.enqueueWriteBuffer(view_.buffer, CL_FALSE, 0, sizeof(view_host_), &view_host_);
    if (!textured_) return;
    tex_host_ = makeTexTriangles(*geo_, atlas_now_->material_entry, view_host_);
    if (!streamed_)  // streamed batches gather their records from tex_host_
      q.enqueueWriteBuffer(tex_tris_.buffer, CL_FALSE, 0, tex_host_.size() * sizeof(StTexTriangle),
                           tex_host_.data());
  }

  void enqueueFrame(const FrameSettings& s) override {
    updateView(s);
    const std::vector<LeafBatch>& batches = orderForView(s);
    uint32_t batch_capacity = 0;
    for (const LeafBatch& b : batches) batch_capacity = std::max(batch_capacity, b.refs);
    if (batches.size() > 1)
      batch_capacity = std::max<uint32_t>(batch_capacity, uint32_t(batch_slots_));
    streamed_bytes_ = disk_bytes_ = 0;
    staging_next_ = device_next_ = 0;
    if (overflow_capacity_ == 0) overflow_capacity_ = batch_capacity / 64 + 1024;
    if (bin_capacity_ == 0) bin_capacity_ = 2 * size_t(batch_capacity) + runner_.tileCount() + 1024;
    sizeBuffers(batch_capacity, s);
    if (seed_)  // the first batch starts each pixel from it (the vector outlives the call)
      runner_.runtime().queue().enqueueWriteBuffer(accum_extra_.buffer, CL_FALSE, 0,
                                                   seed_->size() * 4, seed_->data());
    runner_.timer().fill("clear", leaf_walks_.buffer, 0u, leaf_walks_.bytes);
    if (projected_ && vertex_count_ > 0) {
      // Resident triangles: every vertex projected and snapped once for the view.
      runner_.transformVertices(positions_.buffer, vertex_count_, view_.buffer, screen_.buffer);
    }
    // A share of a distributed frame is left in the accumulator: no batch finishes the image.
    for (size_t i = 0; i < batches.size(); ++i)
      enqueueBatch(batches[i], batch_capacity, i == 0, i + 1 == batches.size() && !partial_);
    if (batches.empty()) enqueueBatch(LeafBatch{}, batch_capacity, true, !partial_);
    batch_count_ = std::max<size_t>(1, batches.size());
  }

  bool growIfOverflowed(const uint64_t* counters) override {
    bool rerun = growCapacity(overflow_capacity_, counters[ST_COUNTER_SETUP_OVERFLOW], 1 << 16);
    rerun |= growCapacity(bin_capacity_, counters[ST_COUNTER_OCTREE_ENTRIES],
                          budget_ ? 1 << 12 : 1 << 20);
    if (rerun && budget_) {
      // Within the budget? Otherwise smaller batches (never smaller than the largest leaf).
      const uint64_t grown =
          (bin_capacity_ * binEntryBytes() > bins_.bytes / 4 * binEntryBytes()
               ? (bin_capacity_ - bins_.bytes / 4) * binEntryBytes()
               : 0) +
          (overflow_capacity_ + batch_slots_) * slotWork() -
          std::min<uint64_t>((overflow_capacity_ + batch_slots_) * slotWork(), records_.bytes());
      if (held_ + runner_.image().bytes + runner_.counters().bytes + grown > budget_) {
        uint64_t largest = 1;
        for (uint32_t c : blocks_.count) largest = std::max<uint64_t>(largest, c);
        if (batch_slots_ <= largest)
          throw Error("octree: a memory budget of " + megabytes(budget_) +
                      " is too small for this view: the largest leaf's bin lists need " +
                      megabytes(bin_capacity_ * 4) + " besides the rest");
        batch_slots_ = std::max<uint64_t>(largest, batch_slots_ / 2);
        order_valid_ = false;
        overflow_capacity_ = bin_capacity_ = 0;
      }
    }
    return rerun;
  }

  DeviceBuffer& depthComplexity() override { return depth_map_; }

  void addOutputs(RenderResult& result) override {
    if (!partial_) return;
    const size_t pixels = size_t(runner_.pixels());
    std::vector<uint16_t> words(pixels * 4);
    runner_.runtime().queue().enqueueReadBuffer(accum_.buffer, CL_TRUE, 0, pixels * 8,
                                                words.data());
    result.partial.resize(pixels * 4);
    for (size_t i = 0; i < words.size(); ++i) result.partial[i] = float(words[i]) / 65535.0f;
    if (translucent_) {
      result.partial_state.resize(pixels * 2);
      runner_.runtime().queue().enqueueReadBuffer(accum_extra_.buffer, CL_TRUE, 0, pixels * 8,
                                                  result.partial_state.data());
    }
  }

  void addStats(const uint64_t* counters, FrameStats& st) override {
    st.triangles = triangles_;
    st.tile_kernels = runner_.serialTiles() ? "serial" : "group";
    // Walks per leaf (its deepest tile's), read back once after the frames.
    std::vector<uint32_t> walks(order_refs_.size());
    if (!walks.empty())
      runner_.runtime().queue().enqueueReadBuffer(leaf_walks_.buffer, CL_TRUE, 0, walks.size() * 4,
                                                  walks.data());
    uint64_t read = 0, walk_sum = 0, walk_max = 0;
    for (size_t i = 0; i < walks.size(); ++i) {
      read += uint64_t(order_refs_[i]) * walks[i];
      walk_sum += walks[i];
      walk_max = std::max<uint64_t>(walk_max, walks[i]);
    }
    st.triangles_read = read;
    st.geometry_passes = walk_max;
    st.dp_triangles_read = triangles_ * (counters[ST_COUNTER_MAX_DEPTH] + 1);
    st.octree_variant = variant_name_;
    st.octree_early_out = early_out_;
    st.octree_leaves = blocks_.node.size();
    st.octree_refs = octree_refs_;
    st.octree_duplicate_refs = octree_refs_ - placed_;
    st.leaf_layers_max = walk_max;
    st.leaf_layers_mean = walks.empty() ? 0.0 : double(walk_sum) / double(walks.size());
    st.tile_walks = counters[ST_COUNTER_OCTREE_WALKS];
    st.bin_entry_reads = counters[ST_COUNTER_OCTREE_ENTRY_READS];
    st.fragments_lost = counters[ST_COUNTER_FRAGMENTS_LOST];
    st.preprocess_ms = build_ms_;
    st.preprocess_cached = from_cache_;
    st.order_ms = order_ms_;
    st.batches = batch_count_;
    const uint64_t local_layers = uint64_t(compute_units_) * ST_TILE_PIXELS * k_ * 8;
    st.fragment_bytes = accum_.bytes + (translucent_ ? accum_extra_.bytes : 0) + local_layers;
    st.device_bytes = records_.bytes() + slot_extra_.bytes + slot_triangle_.bytes + screen_.bytes +
                      ordered_bins_.bytes() + bins_.bytes + batch_counters_.bytes +
                      depth_map_.bytes + leaf_walks_.bytes + order_blocks_.bytes +
                      order_start_buf_.bytes + order_tag_buf_.bytes + order_box_buf_.bytes +
                      st.fragment_bytes;
    addAtlasStats(*atlas_now_, atlas_choice_, st);
    st.stage_ms["order (host, per view)"] = order_ms_;
    st.memory_budget = budget_;
    st.peak_device_bytes = peak_ + runner_.image().bytes + runner_.counters().bytes;
    st.streamed = streamed_;
    st.streamed_bytes = streamed_bytes_;
    st.stream_source = !streamed_ ? "" : scene_file_ ? "disk" : "host";
    st.disk_read_bytes = disk_bytes_;
    struct rusage usage {};
    if (getrusage(RUSAGE_SELF, &usage) == 0) st.host_peak_rss = uint64_t(usage.ru_maxrss) * 1024;
  }

  FrameRunner runner_;  // first member: released last
  OrderedBins ordered_bins_;
  cl::Kernel setup_, resolve_, resolve_serial_;
  bool early_out_ = false;
  uint32_t tile_reads_ = 0;
  Variant variant_;
  std::string variant_name_;
  uint32_t k_ = 1, k_limit_ = 1, compute_units_ = 1, chunks_ = 16;
  // Memory: bytes held by this renderer's buffers now and at most, the budget, and whether the
  // scene's triangles stay on the device (resident) or come per batch (streamed).
  uint64_t held_ = 0, peak_ = 0, budget_ = 0, batch_slots_ = OctreeMethodOptions{}.batch_triangles;
  uint64_t material_colors_bytes_ = 0, atlas_bytes_ = 0, streamed_bytes_ = 0, disk_bytes_ = 0;
  std::shared_ptr<const OctreeSceneFile> scene_file_;  // an out-of-core scene
  bool streamed_ = false, resident_uploaded_ = false, textured_ = false;
  const WorldGeometry* geo_ = nullptr;
  std::vector<StTexTriangle> tex_host_;
  struct Staging {
    std::vector<float> positions;
    std::vector<uint32_t> materials;
    std::vector<StTexTriangle> tex;
    cl::Event done;
    bool written() const { return done() != nullptr; }
  } staging_[2];
  int staging_next_ = 0, device_next_ = 0;
  struct DeviceSet {
    DeviceBuffer positions, materials, tex;
    cl::Event free;  // the last batch that read this set has
  } device_sets_[2];
  cl::CommandQueue transfer_;  // uploads of streamed batches, beside the rendering queue
  std::vector<uint32_t> order_host_;
  DeviceBuffer tex_tris_, atlas_;
  DeviceAtlasCache atlas_cache_;
  const DeviceAtlas* atlas_now_ = nullptr;
  AtlasChoice atlas_choice_ = AtlasChoice::Packed;
  StViewConstants view_host_{};
  uint64_t triangles_ = 0, octree_refs_ = 0, placed_ = 0;
  size_t batch_count_ = 0;
  bool translucent_ = false, from_cache_ = false, partial_ = false;
  std::shared_ptr<const std::vector<float>> seed_;  // translucency state where the share begins
  double build_ms_ = 0.0, order_ms_ = 0.0;
  // The scene: the octree (or the whole-scene block) and what was uploaded for it.
  Octree tree_;
  BlockSet blocks_;
  std::vector<uint32_t> identity_;
  const std::vector<uint32_t>* refs_host_ = nullptr;
  uint64_t scene_key_ = 0, scene_generation_ = 0;
  std::string scene_options_;
  uint32_t vertex_count_ = 0;
  // The view's order.
  bool order_valid_ = false;
  StViewConstants order_view_{};
  std::vector<LeafBatch> batches_;
  std::vector<uint32_t> order_start_, order_tag_, order_refs_;
  std::vector<StOctreeLeaf> order_box_;
  size_t overflow_capacity_ = 0, bin_capacity_ = 0;
  DeviceBuffer positions_, indices_, materials_, material_colors_, refs_, block_first_, no_flip_,
      view_, order_blocks_, order_start_buf_, order_tag_buf_, order_box_buf_, leaf_walks_;
  DeviceBuffer screen_;     // the scene's vertices projected for the view (projected_)
  bool projected_ = false;  // resident without a budget: setup reads screen_
  GroupRecords records_;
  DeviceBuffer slot_extra_, slot_triangle_, bins_, batch_counters_, accum_, accum_extra_,
      depth_map_;
};

}  // namespace

std::unique_ptr<MethodRenderer> makeOctreeRenderer(const DeviceOptions& device) {
  return std::make_unique<OctreeRenderer>(device);
}

}  // namespace strata
