// strata: exact order-independent transparency and translucency of triangle meshes, rendered by
// OpenCL kernels on any OpenCL device (a GPU, or PoCL on a CPU) and checkable against an
// independent Embree reference. The public C++ API: no OpenCL and no internal headers here.
//
//   strata::Device device = strata::Device::open();            // a GPU, else the first device
//   strata::Geometry mesh = strata::Geometry::load("bunny.obj");  // or builtin:NAME, or arrays
//   strata::Renderer cells(device, "cells");
//   cells.setGeometry(mesh);                                    // uploads, decomposes once
//   strata::Frame f = cells.render(strata::View{30, 20});        // then any number of views
//   f.image.rgba;  f.stats_json;
//
// Every failure (bad file, bad arrays, a method asked for what it cannot do, a device fault) is
// a strata::Error with a one-line message; memory that cannot be had (host or device) is an
// OutOfMemory, naming what did not fit. A Renderer or Picker keeps its device alive; the
// device's OpenCL objects are released when the last of them goes.
//
// Threads: every object may be used from several threads. Calls on one Renderer (or Picker) are
// serialised on it: a render() started while another runs on the same Renderer waits for it.
// setGeometry() and setOptions() do not wait: the running frame keeps the geometry and options
// it began with, and the next render() uses the new ones. Separate Renderers, on one Device or
// several, render concurrently. A Geometry is
// immutable and may be shared by any number of Renderers.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>
#if __cplusplus >= 202002L && __has_include(<span>)
#include <span>
#endif

#include "strata/error.h"

namespace strata {

// An RGBA8 image, row-major, top row first.
struct Image {
  int width = 0, height = 0;
  std::vector<uint8_t> rgba;

  Image() = default;
  Image(int w, int h) : width(w), height(h), rgba(size_t(w) * size_t(h) * 4, 0) {}
  uint8_t* pixel(int x, int y) { return &rgba[(size_t(y) * width + x) * 4]; }
  const uint8_t* pixel(int x, int y) const { return &rgba[(size_t(y) * width + x) * 4]; }
};

// What the fragments of a pixel are combined into.
enum class Effect {
  Transparency,  // front-to-back "under" compositing of flat-shaded colour and opacity
  Translucency,  // Beer-Lambert absorption between entering and leaving fragments, Schlick Fresnel
};

// How the OpenCL front end groups the scene into draw units.
enum class Batch {
  None,       // one unit per (instance, material), each with its own per-frame constants upload
  Static,     // units of one material merged once into one world-space range (ids kept)
  Instanced,  // one mesh copy plus a per-instance buffer applied in the transform kernel
  Auto,       // instanced when some mesh has many instances, else static
};
// The order the front end draws its units in (state changes against depth order).
enum class DrawSort { None, Material, Depth, Gray, Key };
// How textures share device memory: packed into shared pages, uniform slots, or off (a page and
// a launch per texture).
enum class AtlasChoice { Off, Uniform, Packed };
// How cells decompose a mesh into convex cells.
enum class DecomposeMode {
  Strict,  // every vertex of a cell on or behind every face plane of the cell (exact)
  Paper,   // the paper's local test: a neighbour joins if it lies below the face it is reached from
};
// How per-tile kernels run: a work-group per tile, its items in parallel (the GPU kernels); a
// work-item alone per tile, no barriers or local atomics (what suits a CPU device that runs a
// group's items one after another); or serial on PoCL's CPU devices, else group.
enum class TileKernels { Auto, Group, Serial };
// wboit's weight function w(z, a): the equations of McGuire and Bavoil 2013. Eq7, Eq8 and Eq9
// take the view distance z in the scene's units (the paper's constants suit scenes of a few to a
// few hundred units); Eq10 the depth-buffer value d = 1 - near / z, free of the scene's units.
enum class WboitWeight { Eq7, Eq8, Eq9, Eq10 };
// What the fixed-K A-buffer (abuffer) does with a pixel's fragments past its K records: drop
// them (counted as lost, as published) or blend them, order-independently, into a tail shown
// behind the K sorted ones.
enum class AbufferTail { Drop, Blend };

// The names the command line and Python use ("static", "gray", "packed", "strict", "serial"),
// and back; an unknown name throws Error naming it and the known ones.
const char* optionName(Batch value);
const char* optionName(DrawSort value);
const char* optionName(AtlasChoice value);
const char* optionName(DecomposeMode value);
const char* optionName(TileKernels value);
const char* optionName(WboitWeight value);
const char* optionName(AbufferTail value);
Batch parseBatch(const std::string& name);
DrawSort parseDrawSort(const std::string& name);
AtlasChoice parseAtlasChoice(const std::string& name);
DecomposeMode parseDecomposeMode(const std::string& name);
TileKernels parseTileKernels(const std::string& name);
WboitWeight parseWboitWeight(const std::string& name);
AbufferTail parseAbufferTail(const std::string& name);

// Per-method options, each read by its own method only.
struct AbufferOptions {
  AbufferTail tail = AbufferTail::Drop;
};
struct MdtsOptions {
  bool global_slots = false;  // keep the K slots in global memory, as published (else local)
};
struct BucketOptions {
  bool global_buckets = false;  // keep the 32 buckets per pixel in global memory (else local)
};
struct WboitOptions {
  WboitWeight weight = WboitWeight::Eq10;
};
// Stochastic transparency: samples per pixel (1..64), the seed of the coverage masks (a seed
// gives one image), and the paper's alpha correction (off: the plain estimator, whose
// expectation is the exact image).
struct StochasticOptions {
  uint32_t samples = 16;
  uint32_t seed = 0;
  bool alpha_correction = true;
};
struct CellsOptions {
  // Triangles streamed through the device per batch: large enough that a frame is a few
  // launches and each pixel's result is carried between batches rarely, small enough that the
  // working set (about 150 bytes per triangle, 600 MB at most) stays bounded.
  size_t batch_triangles = size_t(1) << 22;
  // A moving camera (orbit_deg): order the next frame's view on a host thread while the device
  // draws the current one (the images are the same either way).
  bool order_ahead = true;
  // A moving camera: how many frames after its own an order may still be drawn with (0: every
  // frame orders its view). Such a frame is checked as it is composited (every pixel's
  // fragments ascending in depth, none overwritten) and the pixels that fail are composited
  // again with every fragment sorted, so its image is exact whatever the order (fragments at
  // exactly one depth may come in either order, as with any order). Strict cells in frames of
  // one batch only; other frames order their own view.
  uint32_t order_reuse = 8;
  // Where the order's per-view pixel masks of the cells and the pairs that share a pixel centre
  // (with their relations) are found: "host", "device" (kernels; cells spanning more than 32
  // pixels keep their masks on the host), or "auto": the host (a CPU device shares the host's
  // cores, and on an H200 the device's masks halved the order's CPU time but did not make it
  // faster: the host's work around them remains, docs/results/gpu.md). The same order either
  // way.
  std::string order_masks = "auto";
  // The group composite takes a tile's consecutive passes that share no pixel centre there as
  // one segment (one raster and composite step for several passes), from tile segments the
  // order lists per view: "on"; "off": every pass a segment of its own, which spares the order
  // that step and the gathering of its masks (on an H200's host about 2 of the horse's 10 ms per
  // view) for a composite a fifth slower there (0.19 -> 0.23 ms); "auto": off for a moving
  // camera (FrameSettings::orbit_deg, every frame a new view), else on. Same images.
  std::string tile_segments = "auto";
  // The composite kernel: "group" (a work-group per block of tiles, its items in parallel over
  // each segment's triangles and pixels: the GPU kernel), "serial" (one work-item walks a
  // block's tiles alone, no barriers: what suits a CPU device that runs a group's items one
  // after another), or "auto" (as RenderOptions::tile_kernels). Same images.
  std::string composite = "auto";
};
// The octree method: how a leaf is resolved, and the tree it renders.
//   kbuffer           per leaf, the claimed fragments k at a time (counted in the first walk)
//   blocks-histogram  per leaf, a coverage walk (the leaf's depth histogram), then exactly that
//                     many peeling walks (the paper's method)
//   blocks            per leaf, peeling walks until one finds nothing (occlusion-query style)
//   histogram         the whole scene as one block: a coverage walk, then exact peeling walks
//   dp                the whole scene as one block, peeled until a walk finds nothing
struct OctreeMethodOptions {
  std::string variant = "kbuffer";
  uint32_t leaf_triangles = 16384;  // the face limit of a leaf (triangle references)
  uint32_t k = 32;                  // kbuffer: fragments per pixel taken per walk (1..64)
  // References set up per batch; a frame's working set is about 170 bytes per reference.
  size_t batch_triangles = size_t(1) << 20;
  // Under a memory budget (the renderer's settings), when the scene's triangles do not fit
  // beside the working set, each batch's triangles are streamed from host memory instead (from
  // disk for an octree scene, which always streams), and batches shrink until the frame fits.
  bool stream = false;  // stream the triangles per batch even when they would fit (measuring)
  // Stop taking fragments at a pixel once less than 0.5/255 of the light gets through (what
  // lies behind changes it by less than that), and skip a leaf where a whole tile is so: the
  // image stays within 1/255, but fragment counts are then those composited, not all.
  bool early_out = false;
  // A bound on the work of one screen tile: a leaf's walks stop once the tile's walks would read
  // more than this many triangle references, and the fragments behind its last walk are counted
  // lost (FrameStats::fragments_lost), not composited. Every leaf still takes one walk (its
  // nearest k fragments per pixel), the leaves in front first. Only leaves the tree cannot split
  // (thousands of coincident or closely stacked faces) reach it: the deepest tile of
  // builtin:hairball reads about 14 thousand. 0: no bound.
  uint32_t tile_reads = uint32_t(1) << 20;
};

// Every method's own options, each read by its own method only: part of RenderOptions (and of
// the engine's settings of a frame), so a method's options are declared once, here.
struct MethodOptions {
  AbufferOptions abuffer;
  MdtsOptions mdts;
  BucketOptions bucket;
  WboitOptions wboit;
  StochasticOptions stochastic;
  CellsOptions cells;
  OctreeMethodOptions octree;
};

// One rendering method, as the library describes it.
struct MethodInfo {
  std::string name;      // "cells", "ppll", ..., "embree"
  std::string summary;   // one line
  bool exact = false;    // equal to embree within 2/255 (K-budget methods while K >= depth)
  bool opencl = false;   // false: the CPU reference
  bool takes_k = false;  // reads RenderOptions::k
  bool translucency = false;
};
std::vector<MethodInfo> methods();

struct DeviceDescription {
  int index = 0;  // what Device::open takes
  std::string name, platform, driver;
  bool gpu = false;
};

// An OpenCL device chosen explicitly (the library reads no environment variable).
class Device {
 public:
  static std::vector<DeviceDescription> list();
  // `spec`: an index from list() or a case-insensitive substring of the device or platform
  // name; empty: the first GPU, else the first device. `atomics`: "auto" (64-bit atomics where
  // the device has them), "64", or "32": the path without 64-bit atomics, which runs every
  // method with the serial forms of its tile kernels (same images and counts).
  static Device open(const std::string& spec = "", const std::string& atomics = "auto");
  std::string label() const;  // "NAME (PLATFORM, DRIVER)"
  bool int64Atomics() const;  // the path this device was opened with

  struct State;
  std::shared_ptr<State> state;  // shared by every copy; internal
};

struct View;

// A triangle scene, validated: from a file, a built-in, or plain arrays.
class Geometry {
 public:
  // A mesh file (OBJ+MTL, PLY, OFF, STL, glTF 2.0/GLB, glTF 1.0), an octree scene (FILE.octree
  // from strata prep --octree -o: the octree method streams it from disk, other methods read it
  // whole; vertexCount() is 0) or builtin:NAME (demo, spheres:N, crowd:N, textured:N, hairball:N,
  // city:N, shells:N, soup:N). alpha in 0..1 replaces every material's opacity; < 0 keeps them.
  static Geometry load(const std::string& path, float alpha = -1.0f);
  // One mesh from arrays: vertex_count x 3 positions, triangle_count x 3 indices, and optional
  // per-triangle colours (triangle_count x 4 RGBA in 0..1, alpha = opacity; null: grey at
  // `alpha`, default 0.5). Positions must be finite, indices below vertex_count.
  static Geometry fromArrays(const float* positions, size_t vertex_count, const uint32_t* indices,
                             size_t triangle_count, const float* triangle_rgba = nullptr,
                             float alpha = -1.0f);
  // The same from flat containers: x, y, z per vertex; three indices per triangle; no colours or
  // four per triangle. Sizes that are not whole vertices, triangles or colours throw Error.
  static Geometry fromArrays(const std::vector<float>& positions,
                             const std::vector<uint32_t>& indices,
                             const std::vector<float>& triangle_rgba = {}, float alpha = -1.0f) {
    return fromFlatArrays(positions.data(), positions.size(), indices.data(), indices.size(),
                          triangle_rgba.data(), triangle_rgba.size(), alpha);
  }
#if __cplusplus >= 202002L && __has_include(<span>)
  static Geometry fromArrays(std::span<const float> positions, std::span<const uint32_t> indices,
                             std::span<const float> triangle_rgba = {}, float alpha = -1.0f) {
    return fromFlatArrays(positions.data(), positions.size(), indices.data(), indices.size(),
                          triangle_rgba.data(), triangle_rgba.size(), alpha);
  }
#endif
  // What the container forms call: sizes in floats and indices.
  static Geometry fromFlatArrays(const float* positions, size_t position_floats,
                                 const uint32_t* indices, size_t index_count,
                                 const float* triangle_rgba, size_t rgba_floats, float alpha);

  uint64_t triangleCount() const;
  uint64_t vertexCount() const;
  std::string source() const;
  // Bounding sphere: centre (x, y, z) and radius.
  void boundingSphere(float centre[3], float* radius) const;
  // The scene's own view, as `strata render` shows it without --view: builtin:spheres:N along
  // its stacking axis, orthographic; a mesh file at azimuth 30, elevation 20, perspective.
  View naturalView(int width = 512, int height = 512) const;

  struct State;
  std::shared_ptr<const State> state;  // immutable, shared by copies; internal
};

// A view of the geometry: orbit angles around its bounding sphere (as `strata render --view`),
// or an explicit eye and target when look_at is set (View::lookAt). Geometry::naturalView gives
// the scene's own.
struct View {
  float azimuth_deg = 30.0f;    // around +Y; 0 looks along -Z
  float elevation_deg = 20.0f;  // above the XZ plane
  float distance = 0.0f;        // in bounding-sphere radii; 0: auto-frame
  int width = 512, height = 512;
  bool orthographic = false;
  float fov_deg = 40.0f;      // perspective: vertical field of view
  float ortho_height = 0.0f;  // orthographic: world height seen (0: the bounding sphere's)
  bool look_at = false;
  float eye[3] = {0.0f, 0.0f, 3.0f}, target[3] = {0.0f, 0.0f, 0.0f}, up[3] = {0.0f, 1.0f, 0.0f};

  // A camera at `eye` looking at `target`, `up` pointing up in the image (world units).
  static View lookAt(const float eye[3], const float target[3], const float up[3], int width = 512,
                     int height = 512);
};

struct RenderOptions : MethodOptions {
  int frames = 1;  // frames rendered per render(); times are over all of them
  // A moving camera within one render(): frame f turned by f * orbit_deg degrees of azimuth
  // about the vertical axis through the target; the image is the last frame's (0: still).
  float orbit_deg = 0.0f;
  Effect effect = Effect::Transparency;
  float sigma = -1.0f;  // translucency: absorption per world unit (< 0: 1 / radius)
  // Per-pixel budget of abuffer, mdts, mdts32; mlab's and hybrid's layers, adaptive's nodes.
  int k = 16;
  // How per-tile kernels run (every OpenCL method and picking has both forms; for cells its
  // composite, for octree its resolve). The images and counts are the same (abuffer: while no
  // pixel loses fragments).
  TileKernels tile_kernels = TileKernels::Auto;
  bool checker_background = true;  // else background_rgb
  float background_rgb[3] = {0.92f, 0.92f, 0.92f};
  bool capture_depth_complexity = false;
  Batch batch = Batch::Static;
  DrawSort sort = DrawSort::None;
  AtlasChoice atlas = AtlasChoice::Packed;
  DecomposeMode decompose = DecomposeMode::Strict;  // cells
  std::string cell_cache_dir;  // cells and octree: empty: $XDG_CACHE_HOME/strata/{cells,octree}
  // Device bytes a frame may use, scene and image included (0: no bound): octree keeps within
  // it; the other OpenCL methods fail with what they needed.
  uint64_t memory_budget = 0;
};

struct Frame {
  Image image;
  std::vector<uint32_t> depth_complexity;  // per pixel, if RenderOptions asked for it
  // The common statistics (names as in stats_json); times in milliseconds over the frames of
  // one render(): median, fastest and slowest.
  double frame_ms = 0.0, frame_ms_min = 0.0, frame_ms_max = 0.0;
  uint64_t triangles = 0;       // in the scene
  uint64_t triangles_read = 0;  // per frame, by the kernels (more than triangles: several passes)
  uint64_t fragments = 0;       // per frame, every fragment rasterized
  uint64_t fragments_lost = 0;  // fragments a budget (k, memory, a tile bound) did not keep
  uint64_t max_depth_complexity = 0, device_bytes = 0, kernel_launches = 0;
  std::vector<std::pair<std::string, double>> stage_ms;  // median per named stage
  std::string stats_json;  // every statistic, as `strata render --stats` writes
};

// How far one image is from another (a reference), as `strata diff` and the tests measure it.
struct ImageDiff {
  double psnr = 0.0;      // dB over RGB; infinity when identical
  double rmse = 0.0;      // root mean square channel difference over RGB, 0..255
  int max_abs = 0;        // largest channel difference, 0..255
  double mean_abs = 0.0;  // mean channel difference over RGB, 0..255
  double within_1 = 0.0;  // fraction of pixels whose RGB channels all differ by <= 1
  double within_2 = 0.0;  // ... by <= 2 (the exact methods' tolerance against embree)
  uint64_t pixels = 0;
};
// Compares RGB channels (alpha is ignored: every renderer writes opaque images). Throws Error if
// the sizes differ.
ImageDiff compareImages(const Image& a, const Image& b);
// A visual difference image: |a - b| per channel, amplified x8, on black.
Image differenceImage(const Image& a, const Image& b);
// The structural similarity (SSIM; Wang, Bovik, Sheikh and Simoncelli 2004) of two images over
// their RGB channels: Gaussian weights of sigma 1.5 over an 11 x 11 window, C1 = (0.01 L)^2 and
// C2 = (0.03 L)^2 with L = 255, population (co)variances. Returns the mean over the channels and
// over the pixels whose window lies inside the image (1 when identical; what scikit-image's
// structural_similarity gives with gaussian_weights=True, sigma=1.5,
// use_sample_covariance=False, data_range=255); with `map`, also each pixel's value (the mean
// over its channels, windows reflected at the border), width x height. Throws Error if the sizes
// differ or either side is under kSsimMinSize pixels.
inline constexpr int kSsimMinSize = 11;
double structuralSimilarity(const Image& a, const Image& b, std::vector<float>* map = nullptr);

// Writes an image as PNG (or any format the file name's extension names that strata's image
// writer knows: .png, .exr, ...), atomically: a temporary file renamed over `path`, so a failure
// leaves what was there. Throws Error naming the path.
void saveImage(const std::string& path, const Image& image);

class Renderer {
 public:
  // `method`: a name from methods(). Throws Error for an unknown one.
  Renderer(const Device& device, const std::string& method, const RenderOptions& options = {});
  ~Renderer();
  Renderer(Renderer&&) noexcept;
  Renderer& operator=(Renderer&&) noexcept;

  // Once per scene: later render() calls reuse what it prepared (uploads, convex cells, atlas).
  void setGeometry(const Geometry& geometry);
  void setOptions(const RenderOptions& options);
  // Throws Error if no geometry is set, or the method cannot render the options (an effect it
  // does not render, k out of range).
  Frame render(const View& view);
  const MethodInfo& method() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// One fragment under a pixel.
struct PickLayer {
  uint32_t object = 0, triangle = 0;
  std::string name;                                      // the object's name, if the scene has one
  float depth = 0.0f;                                    // distance along the view axis
  float position[3] = {0, 0, 0}, normal[3] = {0, 0, 0};  // world; the winding's unit normal
  bool front_facing = true;
  float opacity = 0.0f;        // the material's
  float transmittance = 1.0f;  // light let through by the fragments in front (transparency)
};

// What is under one pixel.
struct PickHit : PickLayer {
  bool hit = false;  // false: background (or outside the image); the layer fields are the front's
  std::vector<PickLayer> layers;  // pick(..., all_layers): every fragment, the front first
};

// An object seen in a rectangle.
struct PickedObject {
  uint32_t object = 0;
  std::string name;
};

// ID picking: the front-most object under pixels, read from a 64-bit (depth, id) buffer, or every
// fragment under them.
class Picker {
 public:
  explicit Picker(const Device& device);
  ~Picker();
  Picker(Picker&&) noexcept;
  Picker& operator=(Picker&&) noexcept;

  void setGeometry(const Geometry& geometry);
  // Pixels as (x, y) pairs, 0,0 top-left; one hit per pixel, in the order asked. all_layers:
  // each hit also lists every fragment under its pixel, front to back.
  std::vector<PickHit> pick(const View& view, const std::vector<std::pair<int, int>>& pixels,
                            bool all_layers = false);
  // The distinct objects front-most at some pixel of the inclusive rectangle [x0, x1] x [y0, y1],
  // ascending by id. Throws Error for a rectangle not inside the image.
  std::vector<PickedObject> objectsInRect(const View& view, int x0, int y0, int x1, int y1);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace strata
