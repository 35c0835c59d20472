// The renderer front door: one call renders a scene with a method and returns the image and the
// frame statistics. No OpenCL types here: this header is public.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "engine/features/draw_sort.h"
#include "preprocess/image_io.h"
#include "preprocess/scene/camera.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

enum class Method {
  Opaque,    // nearest fragment (64-bit visibility buffer)
  Ppll,      // per-pixel linked lists
  Abuffer,   // FreePipe ABS: K (depth, colour) records per pixel, appended, then sorted
  Mdts,      // FreePipe MDTS: K sorted slots, atomic-min insertion chain, 32-bit depth + colour
  Mdts32,    // MDTS as published: depth and colour packed into 32 bits
  Dp,        // depth peeling: one geometry pass per layer
  Ddp,       // dual depth peeling: front and back layer per pass
  Bdp,       // bucket depth peeling: 32 uniform depth buckets
  Bdp2,      // adaptive bucket depth peeling: histogram pass, then re-divided buckets
  Wboit,     // weighted blended OIT: weighted sums and revealage per pixel (approximate)
  Mlab,      // multi-layer alpha blending: k depth-sorted layers, the last two merged (approximate)
  Hybrid,    // hybrid transparency: k nearest fragments exact, the rest averaged (approximate)
  Adaptive,  // adaptive transparency: k-node visibility function per pixel (approximate)
  Stochastic,  // stochastic transparency: random coverage of S samples per pixel (approximate)
  Mboit,       // moment-based OIT: four power moments of optical depth per pixel (approximate)
  Cells,       // convex cells in visibility order, front and back layer per cell
  Octree,      // octree leaves in visibility order, each peeled or k-buffered on its own
  Embree       // the CPU reference
};

// Parses a method name ("opaque", "ppll", "embree"); throws Error naming the unknown method.
Method parseMethod(const std::string& name);
std::string methodName(Method m);
std::vector<std::string> methodNames();  // registry order

struct Background {
  bool checker = true;
  glm::vec3 color{0.92f, 0.92f, 0.92f};
  glm::vec3 color2{0.72f, 0.72f, 0.75f};  // the checker's second colour
};

// Effect (transparency, translucency) is public: include/strata/strata.h.
Effect parseEffect(const std::string& name);  // throws Error naming the bad value
std::string effectName(Effect e);

// Batch (engine/features/batching.h), AtlasChoice (engine/features/device_atlas.h) and their
// parsers are public: include/strata/strata.h. FrameSettings::tile_kernels: throws Error naming a
// value other than auto, group or serial.
void checkTileKernels(const std::string& name);
const char* atlasChoiceName(AtlasChoice c);
std::string batchName(Batch b);
std::vector<std::string> batchNames();

// MethodOptions (every method's own options) is public: include/strata/strata.h.

// The most frames one render() call times (each keeps its time until the call ends).
inline constexpr int kMaxFrames = 100000;
// Throws Error "<what> must be between 1 and kMaxFrames" unless 1 <= frames <= kMaxFrames.
void checkFrameCount(int frames, const std::string& what);

// With MethodOptions (include/strata/strata.h): each method's own options.
struct FrameSettings : MethodOptions {
  int width = 512, height = 512;
  Camera camera;
  Background background;
  int frames = 1;  // frames rendered; timings are over all of them
  // A moving camera: frame f is seen from camera.turned(f * orbit_deg) (degrees of azimuth
  // about the up axis through the target), so every frame is a new view and its time includes
  // all the per-view work; the image returned is the last frame's. 0: a still view.
  float orbit_deg = 0.0f;
  // Per-pixel layer budget of the fixed-size methods (abuffer, mdts, mdts32, mlab, hybrid,
  // adaptive).
  int k = 16;
  // How the OpenCL methods' per-tile kernels run where a method has both forms: "group" (a
  // work-group per tile, its items in parallel: the GPU kernels), "serial" (one work-item alone
  // per tile, no barriers or local atomics: what suits a CPU device that runs a group's items one
  // after another) or "auto" (serial on PoCL's CPU devices, else group). Same images and counts
  // (abuffer: while no pixel has more than k fragments; past k each form keeps the first k to
  // arrive, and the forms deliver them in different orders).
  std::string tile_kernels = "auto";
  Effect effect = Effect::Transparency;  // cells and embree; the other methods do transparency
  float sigma = 1.0f;  // translucency: absorption coefficient sigma_t per world unit
  // cells: decomposition test ("strict" or "paper") and cache folder (empty: the user's cache)
  std::string decompose = "strict";
  std::string cell_cache_dir;
  // Also return the number of fragments at every pixel (transparency methods and embree).
  bool capture_depth_complexity = false;
  // Called after each finished frame with (frames done, frames asked for): progress display.
  std::function<void(int, int)> on_frame;
  // OpenCL front end (not cells, not embree): draw-unit batching and the order units are drawn
  // in. Neither changes the image.
  Batch batch = Batch::Static;
  DrawSort sort = DrawSort::None;
  // Textured scenes: how textures reach the kernels (engine/features/device_atlas.h). Never changes
  // the image; off binds one texture per front-end launch.
  AtlasChoice atlas = AtlasChoice::Packed;
  // Device bytes a frame may use, scene and image included (0: no bound). octree keeps within it
  // (streaming its triangles when they do not fit); every other OpenCL method is refused with
  // what it needed when it does not fit.
  uint64_t memory_budget = 0;
  // One process's share of a distributed render (octree only): only these leaves (node indices
  // of the scene's octree, preprocess/octree_partition.h) are rendered (null: every leaf), and
  // with `partial` the frame is left unfinished: RenderResult::partial holds each pixel's
  // premultiplied colour and transmittance, to be composited with the other processes' shares
  // in visibility order, and the image stays unwritten.
  std::shared_ptr<const std::vector<uint32_t>> octree_leaves;
  bool partial = false;
  // Translucency of a share: per pixel the inside count and depth where the ray enters the
  // share's box (2 floats); null: outside every shell, from the first fragment on.
  std::shared_ptr<const std::vector<float>> translucency_seed;
  // Identifies the geometry's content: a renderer given the same non-zero generation as in its
  // last render() call keeps what it uploaded and prepared for it (the scene buffers, the draw
  // plan, the cells) instead of doing it again. 0: unknown, always prepared afresh. The
  // public strata::Geometry numbers each geometry it makes.
  uint64_t geometry_generation = 0;
};

// The camera of frame `frame` (0-based; -1 is the untimed warm-up, one step before the first).
Camera frameCamera(const FrameSettings& settings, int frame);

struct FrameTimes {
  // mean: with an order reused over several frames of a moving camera (cells), the frames that
  // make an order are the minority, so the median hides them and the mean does not.
  double median = 0.0, min = 0.0, max = 0.0, mean = 0.0;
  int runs = 0;
};

// A frame's statistics come in parts, one per feature that fills them; FrameStats is all of
// them, so code that reads one feature's figures can take its part alone. `--stats` writes
// every field under its own name (engine/report/stats_json.cpp), each part only where its
// feature ran.

// The OpenCL front end's draw units (engine/features/batching.h; not cells or embree): the
// batching and sort used, units drawn, front-end launches (runs of consecutive units with equal
// state, one transform and one setup kernel each), state bits switched between consecutive
// units, consecutive units with different material ids, host-to-device bytes per frame and once
// per render() call (the batched geometry), and the median per-frame sort time.
struct DrawStats {
  std::string batch, sort;
  uint64_t draw_units = 0;
  uint64_t launches = 0;
  uint64_t state_changes = 0;
  uint64_t material_changes = 0;
  uint64_t upload_bytes = 0;
  uint64_t scene_upload_bytes = 0;
  double sort_ms = 0.0;
};

// Textured scenes: atlas mode, entries (texture + sampler), placements, pages, occupancy
// (texture texels / page texels at level 0) and the atlas's device bytes (all kept levels).
struct AtlasStats {
  std::string atlas;
  uint64_t atlas_entries = 0, atlas_placements = 0, atlas_pages = 0, atlas_bytes = 0;
  double atlas_occupancy = 0.0;
};

// The methods that prepare the scene (cells: decomposition and pairs; octree: the tree), from
// the cache or not, and the batches streamed through the pipeline per frame.
struct PreparedSceneStats {
  double preprocess_ms = 0.0;
  bool preprocess_cached = false;
  uint64_t batches = 0;
};

// cells only: convex cells, the uniform grid and per-view ordering.
struct CellsStats {
  uint64_t cells = 0;
  uint64_t cell_copies = 0;  // cells that are copies of a coincident triangle (CellScene)
  // Instances whose mesh had more cell pairs than the bound: drawn as one merged group
  uint64_t cell_unpaired_parts = 0;
  uint64_t cell_groups = 0;  // ordered draws after merging cells that cannot be ordered
  uint64_t cell_passes = 0;  // passes of groups that do not overlap on screen
  // (tile, pass) pairs whose groups may cover a pixel centre of the tile, and the segments
  // they are composited in (passes sharing no centre in a tile join one segment there); both
  // 0 with the serial composite, which needs no segments
  uint64_t cell_tile_passes = 0, cell_tile_segments = 0;
  std::string cells_composite;  // the composite kernel that ran: "group" or "serial"
  uint64_t largest_group = 0;   // cells in the largest group
  // groups of several cells (no order among them: composited with a sorted per-pixel budget)
  // and the cells in them
  uint64_t merged_groups = 0, merged_cells = 0;
  int grid[3] = {0, 0, 0};
  double order_ms = 0.0;             // per view: paid in the frames whose view changed
  uint64_t order_cached_frames = 0;  // timed frames that reused the last view's order
  // A moving camera: timed frames whose order was made during the previous frame's device work,
  // and the median time such a frame still waited for it (0: the order was ready).
  uint64_t order_overlapped_frames = 0;
  double order_wait_ms = 0.0;
  // Timed frames drawn with the order of an earlier view (CellsOptions::order_reuse), and the
  // median numbers of tiles and pixels such a frame composited again because that order failed
  // its check there.
  uint64_t order_reused_frames = 0;
  double order_repair_tiles = 0.0, order_repair_pixels = 0.0;
  // Where the order's pixel masks were computed ("host" or "device"), and for how many cells
  // the device computed them in the last view ordered, and the device memory the order's
  // masks and pairs hold (in device_bytes too; it grows with the cells on screen, not depth).
  std::string order_masks;
  uint64_t order_device_cells = 0;
  uint64_t order_device_bytes = 0;
};

// octree only: the variant, non-empty leaves, references (a triangle once per leaf it meets)
// and those beyond the first of each triangle, the walks (peeling iterations or k-buffer
// fills) of the deepest tile per leaf: their largest and their mean over leaves; (tile, leaf)
// walks and the bin entries they read; what dp reads for the same frame (triangles x
// (max depth complexity + 1)).
struct OctreeFrameStats {
  std::string octree_variant;
  bool octree_early_out = false;  // fragments are then those composited, not all
  uint64_t octree_leaves = 0, octree_refs = 0, octree_duplicate_refs = 0;
  uint64_t leaf_layers_max = 0;
  double leaf_layers_mean = 0.0;
  uint64_t tile_walks = 0, bin_entry_reads = 0, dp_triangles_read = 0;
};

// Memory and streaming (octree): the budget (0: none), every device buffer of the frame at its
// peak (geometry and image included), whether triangles were streamed per batch, bytes
// streamed per frame, the process's peak resident host memory, and where streamed triangles
// came from: "host" (the scene in memory) or "disk" (an out-of-core octree scene file, read
// leaf by leaf: disk_read_bytes per frame); empty when resident.
struct StreamingStats {
  uint64_t memory_budget = 0, peak_device_bytes = 0, streamed_bytes = 0, host_peak_rss = 0;
  bool streamed = false;
  std::string stream_source;
  uint64_t disk_read_bytes = 0;
};

// Every method's figures, and the parts of the features that ran.
struct FrameStats : DrawStats,
                    AtlasStats,
                    PreparedSceneStats,
                    CellsStats,
                    OctreeFrameStats,
                    StreamingStats {
  std::string method, device;
  int width = 0, height = 0;
  uint64_t triangles = 0;
  uint64_t triangles_read = 0;        // triangle reads by the raster stage per frame
  uint64_t fragments = 0;             // fragments rasterized per frame
  uint64_t max_depth_complexity = 0;  // most fragments at one pixel
  uint64_t device_bytes = 0;          // peak working memory beyond the scene's own data
  uint64_t fragment_bytes = 0;        // the part of device_bytes holding fragments / layers
  uint64_t kernel_launches = 0;       // per frame
  uint64_t culled_degenerate = 0;     // zero-area triangles after snapping, per frame
  uint64_t culled_nonfinite = 0;
  uint64_t clipped = 0;          // triangles split by near-plane / guard-band clipping
  uint64_t reruns = 0;           // frames re-run because a buffer had to grow
  uint64_t geometry_passes = 1;  // raster passes over the triangles per frame
  uint64_t fragments_lost = 0;   // fragments a fixed-budget method could not keep
  uint64_t bytes_needed = 0;     // fragment memory it would have needed to keep them all
  // OpenCL methods: how the method's per-tile kernels ran ("group" or "serial")
  std::string tile_kernels;
  // The moving camera: degrees turned per frame (0: a still view, every frame the same).
  float orbit_deg = 0.0f;
  FrameTimes frame_ms;
  std::map<std::string, double> stage_ms;  // median per named stage
  // Per "stage/kernel function" of the OpenCL methods: median device ms per frame and launches
  // per frame, so a stage's cost can be traced to the kernel that pays it.
  struct KernelMs {
    double ms = 0.0;
    uint64_t launches = 0;
  };
  std::map<std::string, KernelMs> kernel_ms;
};

struct RenderResult {
  Image image;
  FrameStats stats;
  std::vector<uint32_t> depth_complexity;  // per pixel, row-major; empty unless asked for
  // With FrameSettings::partial: per pixel, row-major, premultiplied RGB and transmittance.
  std::vector<float> partial;
  // ... and for translucency the inside count and depth of the last fragment (2 floats).
  std::vector<float> partial_state;
};

struct DeviceOptions {
  std::string device;  // index or name substring; empty: STRATA_DEVICE, else GPU, else first
  // "auto": 64-bit atomics where the device has them; "64"; "32": the path without them, which
  // runs the serial forms of the tile kernels (host/cl_runtime.h).
  std::string atomics = "auto";
};

// Bytes of device buffers alive in this process (every OpenCL renderer's, every device's).
uint64_t deviceBytesInUse();

class MethodRenderer {
 public:
  virtual ~MethodRenderer() = default;
  virtual RenderResult render(const WorldGeometry& geometry, const FrameSettings& settings) = 0;
};

// What the library knows of a method, in one table (engine/renderer.cpp): the command line's
// help and `all`, the benchmark's exactness expectations and every renderer's check of its
// settings read it.
struct MethodTraits {
  Method method;
  const char* name;
  const char* summary;  // one line, for --help
  bool exact;           // equal to embree within 2/255 (the K-budget methods while K >= depth)
  bool opencl;          // false: the CPU reference
  bool takes_k;         // reads FrameSettings::k
  std::vector<Effect> effects;
  std::unique_ptr<MethodRenderer> (*make)(const DeviceOptions&);

  bool renders(Effect e) const;
};
const std::vector<MethodTraits>& methodRegistry();
const MethodTraits& methodInfo(Method m);
// Throws Error naming what the method cannot do with these settings (an effect it does not
// render, a bad frame size, k or sigma).
void checkSettings(const MethodTraits& method, const FrameSettings& settings);

// Creates a renderer for a method. Renderers of one device share its OpenCL runtime while any
// of them lives. Every render() checks the settings (checkSettings) and the geometry
// (validateWorldGeometry) first and throws Error rather than render what it cannot.
std::unique_ptr<MethodRenderer> makeRenderer(Method method, const DeviceOptions& device = {});

// Frame time summary of a list of per-frame times.
FrameTimes summarizeTimes(std::vector<double> ms);

}  // namespace strata
