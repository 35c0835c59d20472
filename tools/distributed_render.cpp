#include "tools/distributed_render.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <vector>

#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "engine/report/stats_json.h"
#include "engine/frontend/view_constants.h"
#include "kernels/strata_shared.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/core/hash.h"
#include "preprocess/image_io.h"
#include "preprocess/octree_partition.h"
#include "preprocess/octree_scene.h"
#include "strata/strata.h"

#ifdef STRATA_WITH_MPI
#include <mpi.h>

#include "tools/rank_watch.h"
#endif

namespace strata {

bool firstMpiProcess() {
  for (const char* name : {"OMPI_COMM_WORLD_RANK", "PMIX_RANK", "PMI_RANK"})
    if (const char* rank = std::getenv(name)) return std::string(rank) == "0";
  return true;
}

#ifndef STRATA_WITH_MPI

bool distributedAvailable() { return false; }

int runDistributedRender(const DistributedJob&) {
  throw Error(
      "--distributed: this strata was built without MPI (install libopenmpi-dev and "
      "build again)");
}

#else

bool distributedAvailable() { return true; }

namespace {

// MPI for the lifetime of one distributed render, every collective waited for under the
// rank watch (threads: a rank answers the others' pings from a thread of its own).
class MpiSession {
 public:
  explicit MpiSession(double rank_timeout_s) {
    int initialized = 0, threads = MPI_THREAD_SINGLE;
    MPI_Initialized(&initialized);
    if (!initialized) MPI_Init_thread(nullptr, nullptr, MPI_THREAD_MULTIPLE, &threads);
    else MPI_Query_thread(&threads);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    watch = std::make_unique<RankWatch>(MPI_COMM_WORLD, rank_timeout_s,
                                        threads == MPI_THREAD_MULTIPLE);
  }
  ~MpiSession() {
    watch.reset();
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Finalize();
  }
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  // Waits for a nonblocking collective.
  void wait(MPI_Request& request, const char* what) const { watch->wait(request, what); }
  int rank = 0, size = 1;
  std::unique_ptr<RankWatch> watch;
};

// Runs a step that may fail on some ranks; returns its message, empty when it succeeded.
template <typename Step>
std::string attempt(Step&& step) {
  try {
    step();
  } catch (const std::exception& e) {
    return e.what()[0] ? e.what() : "unknown failure";
  }
  return {};
}

// Collective, after every step that may fail: every rank learns whether one failed, and the
// first failing rank's message. So no rank waits in a collective for a rank that gave up.
std::optional<std::string> firstFailure(const std::string& mine, const MpiSession& mpi) {
  const int me = mine.empty() ? mpi.size : mpi.rank;
  int first = mpi.size;
  MPI_Request r;
  MPI_Iallreduce(&me, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the check after a step");
  if (first == mpi.size) return std::nullopt;
  int length = mpi.rank == first ? int(std::min<size_t>(mine.size(), 4096)) : 0;
  MPI_Ibcast(&length, 1, MPI_INT, first, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the check after a step");
  std::string message(size_t(length), ' ');
  if (mpi.rank == first) message = mine.substr(0, size_t(length));
  MPI_Ibcast(message.data(), length, MPI_CHAR, first, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the check after a step");
  return "rank " + std::to_string(first) + ": " + message;
}

// The options every rank must share: those that size or count a collective (image size,
// frames), decide what is composited (effect, scene, view, opacity, absorption) or how the
// leaves are shared out (the face limit), each as a 64-bit value.
std::vector<std::pair<const char*, uint64_t> > sharedOptions(const DistributedJob& job) {
  const auto text = [](const std::string& s) { return fnv1a64(s.data(), s.size()); };
  const auto bits = [](float f) {
    uint32_t b = 0;
    std::memcpy(&b, &f, 4);
    return uint64_t(b);
  };
  const FrameSettings& s = job.settings;
  const Background& bg = s.background;
  return {
      {"scene", text(job.scene)},
      {"--size", uint64_t(uint32_t(s.width)) << 32 | uint32_t(s.height)},
      {"--frames", uint64_t(uint32_t(s.frames))},
      {"--effect", uint64_t(s.effect)},
      {"--view", text(job.view_options)},
      {"--alpha", bits(job.alpha)},
      {"--sigma", job.sigma_given ? bits(s.sigma) : ~uint64_t(0)},
      {"--background", fnv1a64(&bg.color, sizeof(bg.color), uint64_t(bg.checker))},
      {"--leaf-tris", s.octree.leaf_triangles},
      {"--octree-variant", text(s.octree.variant)},
      {"--octree-k", s.octree.k},
      {"--octree-early-out", uint64_t(s.octree.early_out)},
      {"--octree-tile-reads", s.octree.tile_reads},
  };
}

// The first collective of a distributed render: whether every rank was started with the same
// scene and options (ranks that disagree would otherwise meet in collectives of different
// sizes, or different numbers of them: corrupted memory, or a deadlock). Every rank gets the
// same answer: the first rank and option that differ from rank 0's.
std::optional<std::string> optionsDisagree(const DistributedJob& job, const MpiSession& mpi) {
  const std::vector<std::pair<const char*, uint64_t> > options = sharedOptions(job);
  const size_t n = options.size();
  std::vector<uint64_t> mine(n), all(n * size_t(mpi.size));
  for (size_t i = 0; i < n; ++i) mine[i] = options[i].second;
  MPI_Request r;
  MPI_Iallgather(mine.data(), int(n), MPI_UINT64_T, all.data(), int(n), MPI_UINT64_T,
                 MPI_COMM_WORLD, &r);
  mpi.wait(r, "the check of the options");
  for (int r = 1; r < mpi.size; ++r)
    for (size_t i = 0; i < n; ++i)
      if (all[size_t(r) * n + i] != all[i])
        return "--distributed: rank " + std::to_string(r) + " was started with another " +
               options[i].first + " than rank 0 (every rank renders the same scene with the same " +
               "options)";
  return std::nullopt;
}

// The "under" operator on (premultiplied RGB, transmittance) pixels: MPI applies a
// non-commutative operation in rank order, `in` holding the lower ranks' (nearer) result.
void compositeUnder(void* in, void* inout, int* length, MPI_Datatype*) {
  const float* front = static_cast<const float*>(in);
  float* back = static_cast<float*>(inout);
  for (int i = 0; i < *length; ++i, front += 4, back += 4) {
    const float t = front[3];
    back[0] = front[0] + t * back[0];
    back[1] = front[1] + t * back[1];
    back[2] = front[2] + t * back[2];
    back[3] = t * back[3];
  }
}

// The inside-count effect of a run of fragments, n -> max(n - a, 0) + b, as (a, b); composed
// in rank order (`in` nearer): first (a1, b1), then (a2, b2).
void composeInside(void* in, void* inout, int* length, MPI_Datatype*) {
  const int* first = static_cast<const int*>(in);
  int* then = static_cast<int*>(inout);
  for (int i = 0; i < *length; ++i, first += 2, then += 2) {
    const int a1 = first[0], b1 = first[1], a2 = then[0], b2 = then[1];
    if (b1 >= a2) {
      then[0] = a1;
      then[1] = b1 - a2 + b2;
    } else {
      then[0] = a1 + a2 - b1;
      then[1] = b2;
    }
  }
}

// More shells than any ray meets: a share rendered from inside this many never leaves them.
constexpr int kDeep = 1 << 20;

// Per pixel, where its ray (as the octree kernels form it: view distance as the parameter)
// enters and leaves one part's box, and the ray's length per unit of view distance.
struct BoxRays {
  std::vector<float> entry, exit, length;

  BoxRays(const FrameSettings& s, const OctreePartition& p, int part) {
    const StViewConstants v = makeViewConstants(s);
    float lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
      lo[a] = float(p.box_lo[size_t(part)][a]);
      hi[a] = float(p.box_hi[size_t(part)][a]);
    }
    const glm::vec3 fwd(v.forward[0], v.forward[1], v.forward[2]);
    const glm::vec3 right(v.right[0], v.right[1], v.right[2]), up(v.up[0], v.up[1], v.up[2]);
    const glm::vec3 eye(v.eye[0], v.eye[1], v.eye[2]);
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x) {
        const float ndc_x = ((float(x) + 0.5f) / float(v.width)) * 2.0f - 1.0f;
        const float ndc_y = 1.0f - ((float(y) + 0.5f) / float(v.height)) * 2.0f;
        const glm::vec3 o = eye + right * (ndc_x * v.ray_tan[2]) + up * (ndc_y * v.ray_tan[3]);
        const glm::vec3 d = fwd + right * (ndc_x * v.ray_tan[0]) + up * (ndc_y * v.ray_tan[1]);
        const float ro[3] = {o.x, o.y, o.z}, rd[3] = {d.x, d.y, d.z};
        const float inv[3] = {1.0f / d.x, 1.0f / d.y, 1.0f / d.z};
        float t_in = 0.0f, t_out = 0.0f;
        st_octree_leaf_interval(lo, hi, ro, rd, inv, &t_in, &t_out);
        entry.push_back(std::max(t_in, 0.0f));
        exit.push_back(t_out);
        length.push_back(glm::length(d));
      }
  }
};

// The octree scene a mesh scene is rendered from: written once by rank 0 into the octree cache
// folder, keyed on the scene's triangles, materials and face limit.
std::string octreeSceneFor(const DistributedJob& job) {
  const Scene scene = loadScene(job.scene);
  const WorldGeometry geometry = WorldGeometry::fromScene(scene);
  if (geometry.textured())
    throw Error(job.scene + ": a textured scene cannot be rendered distributed");
  OctreeOptions options;
  options.leaf_triangles = job.settings.octree.leaf_triangles;
  const MeshView mesh{geometry.positions.data(), geometry.positions.size(), geometry.indices.data(),
                      geometry.triangleCount()};
  const std::string dir = job.cache.empty() ? defaultOctreeCacheDir() : job.cache;
  uint64_t key = fnv1a64(geometry.triangle_material.data(), geometry.triangle_material.size() * 4);
  key = fnv1a64(geometry.material_colors.data(),
                geometry.material_colors.size() * sizeof(glm::vec4), key);
  std::filesystem::path path = octreeCachePath(mesh, options, dir);
  char suffix[40];
  std::snprintf(suffix, sizeof(suffix), "-%016llx.scene.octree", (unsigned long long)key);
  path.replace_filename(path.stem().string() + suffix);
  try {
    OctreeSceneFile::open(path.string());
    return path.string();  // already written (a damaged one is written again)
  } catch (const Error&) {
  }
  const Octree tree = loadOrBuildOctree(mesh, options, dir);
  std::error_code ec;
  std::filesystem::create_directories(path.parent_path(), ec);
  writeOctreeScene(path.string(), scene, geometry, tree);
  return path.string();
}

// What each rank reports to rank 0.
struct RankFigures {
  double render_ms = 0.0, composite_ms = 0.0;
  uint64_t leaves = 0, refs = 0, fragments = 0, peak_device_bytes = 0, host_peak_rss = 0,
           disk_read_bytes = 0, composite_bytes = 0;
  int position = 0;  // in the visibility order
  char device[96] = {};
};

// One rank's part of a distributed render (runDistributedRender).
int renderShare(const DistributedJob& job, MpiSession& mpi) {
  const auto fail = [&](const std::string& message) {
    if (mpi.rank == 0) std::cerr << "strata: error: " << message << "\n";
    return 1;
  };
  if (auto differ = optionsDisagree(job, mpi)) return fail(*differ);
  // --device local-rank: the processes of one node take its devices in turn.
  DeviceOptions device = job.device;
  if (device.device == "local-rank") {
    MPI_Comm node;
    MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node);
    int local = 0;
    MPI_Comm_rank(node, &local);
    MPI_Comm_free(&node);
    const std::string e = attempt([&] {
      const size_t devices = Device::list().size();
      if (devices == 0) throw Error("no OpenCL device found");
      device.device = std::to_string(size_t(local) % devices);
    });
    if (auto f = firstFailure(e, mpi)) return fail(*f);
  }

  // The octree scene every rank reads its own leaves from.
  std::string path = job.scene;
  std::string error;
  if (mpi.rank == 0)
    error = attempt([&] {
      const bool octree_scene = std::filesystem::path(job.scene).extension() == ".octree";
      if (!octree_scene) path = octreeSceneFor(job);
    });
  if (auto e = firstFailure(error, mpi)) return fail(*e);
  int length = int(path.size());
  MPI_Request r;
  MPI_Ibcast(&length, 1, MPI_INT, 0, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the octree scene's path");
  path.resize(size_t(length));
  MPI_Ibcast(path.data(), length, MPI_CHAR, 0, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the octree scene's path");

  // Each rank's share: the leaves of its box.
  FrameSettings settings = job.settings;
  WorldGeometry geometry;
  OctreePartition partition;
  std::shared_ptr<const OctreeSceneFile> file;
  RankFigures mine;
  error = attempt([&] {
    const Scene scene = loadScene(path);
    if (!scene.out_of_core) throw Error(path + ": not an octree scene");
    file = scene.out_of_core->file;
    settings.camera = job.camera(scene);
    if (!job.sigma_given) settings.sigma = 1.0f / std::max(scene.boundingSphere().radius, 1e-6f);
    geometry = WorldGeometry::fromScene(scene, job.alpha);
    partition = partitionOctree(file->tree(), uint32_t(mpi.size));
    auto leaves = std::make_shared<std::vector<uint32_t> >(partition.leaves[size_t(mpi.rank)]);
    mine.leaves = leaves->size();
    mine.refs = partition.refs[size_t(mpi.rank)];
    settings.octree_leaves = std::move(leaves);
    settings.partial = true;
    settings.capture_depth_complexity = true;  // summed over the ranks: the true deepest pixel
  });
  if (auto e = firstFailure(error, mpi)) return fail(*e);

  // Visibility order of the boxes for the view, as the ranks' order in a communicator (and
  // the reverse order, for what lies behind).
  const std::vector<uint32_t> order =
      partsFrontToBack(partition, settings.camera.projection == Projection::Perspective,
                       settings.camera.eye, settings.camera.forward());
  int position = 0, root = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    if (int(order[i]) == mpi.rank) position = int(i);
    if (order[i] == 0) root = int(i);
  }
  mine.position = position;
  MPI_Comm ordered, reversed;
  MPI_Comm_split(MPI_COMM_WORLD, 0, position, &ordered);
  MPI_Comm_split(MPI_COMM_WORLD, 0, mpi.size - 1 - position, &reversed);
  const size_t pixels = size_t(settings.width) * size_t(settings.height);

  std::unique_ptr<MethodRenderer> renderer;
  RenderResult result;
  double render_ms = 0.0;
  const bool translucent = settings.effect == Effect::Translucency;
  std::vector<int> later(pixels, 0);  // translucency: some box behind this one has a fragment
  std::unique_ptr<BoxRays> rays;      // translucency: each pixel's ray through this box
  if (translucent) {
    // Where each pixel's ray enters this box, what shells it is inside there, and whether any
    // fragment lies behind the box: from two renders of the share, the first from outside
    // every shell and the second from inside kDeep of them, which give the share's effect on
    // the inside count, n -> max(n - a, 0) + b (a back face outside every shell is ignored),
    // composed front to back over the boxes by MPI_Exscan.
    std::vector<int> transform(pixels * 2), has(pixels);
    error = attempt([&] {
      renderer = makeRenderer(Method::Octree, device);
      const RenderResult fresh = renderer->render(geometry, settings);
      FrameSettings deep = settings;
      auto seed = std::make_shared<std::vector<float> >(pixels * 2, 0.0f);
      for (size_t p = 0; p < pixels; ++p) (*seed)[p * 2] = float(kDeep);
      deep.translucency_seed = seed;
      const RenderResult inside = renderer->render(geometry, deep);
      render_ms += fresh.stats.frame_ms.median + inside.stats.frame_ms.median;
      for (size_t p = 0; p < pixels; ++p) {
        const int b = int(fresh.partial_state[p * 2]);
        const int end = int(inside.partial_state[p * 2]);
        transform[p * 2] = kDeep + b - end;  // a
        transform[p * 2 + 1] = b;
        has[p] = fresh.depth_complexity[p] > 0;
      }
    });
    if (auto e = firstFailure(error, mpi)) return fail(*e);
    std::vector<int> entry(pixels * 2, 0);
    MPI_Op compose;
    MPI_Op_create(&composeInside, 0, &compose);
    MPI_Iexscan(transform.data(), entry.data(), int(pixels), MPI_2INT, compose, ordered, &r);
    mpi.wait(r, "the shells entered in front of each box");
    MPI_Op_free(&compose);
    MPI_Iexscan(has.data(), later.data(), int(pixels), MPI_INT, MPI_MAX, reversed, &r);
    mpi.wait(r, "the fragments behind each box");
    if (position == 0) std::fill(entry.begin(), entry.end(), 0);  // Exscan leaves it undefined
    if (position == mpi.size - 1) std::fill(later.begin(), later.end(), 0);
    auto seed = std::make_shared<std::vector<float> >(pixels * 2, 0.0f);
    rays = std::make_unique<BoxRays>(settings, partition, mpi.rank);
    for (size_t p = 0; p < pixels; ++p) {
      (*seed)[p * 2] = float(entry[p * 2 + 1]);  // the prefix applied to "outside": its b
      (*seed)[p * 2 + 1] = rays->entry[p];
    }
    settings.translucency_seed = seed;
  }
  error = attempt([&] {
    if (mpi.rank == job.fail_rank)
      throw Error("failed on purpose (--fail-rank " + std::to_string(job.fail_rank) + ")");
    if (!renderer) renderer = makeRenderer(Method::Octree, device);
    result = renderer->render(geometry, settings);
  });
  if (auto e = firstFailure(error, mpi)) return fail(*e);
  if (translucent) {
    // Absorption from the share's last fragment to where the ray leaves its box, where the ray
    // is inside a shell there and a fragment lies further on (one process absorbs only between
    // fragments too).
    for (size_t p = 0; p < pixels; ++p) {
      const float inside = result.partial_state[p * 2], last = result.partial_state[p * 2 + 1];
      const float exit = rays->exit[p];
      if (inside > 0.0f && later[p] && std::isfinite(exit) && exit > last)
        result.partial[p * 4 + 3] *= std::exp(-settings.sigma * (exit - last) * rays->length[p]);
    }
  }
  if (mpi.rank == job.fail_rank_late)
    throw Error("failed on purpose (--fail-rank-late " + std::to_string(job.fail_rank_late) + ")");
  const FrameStats& st = result.stats;
  mine.render_ms = render_ms + st.frame_ms.median;
  mine.fragments = st.fragments;
  mine.peak_device_bytes = st.peak_device_bytes;
  mine.disk_read_bytes = st.disk_read_bytes;
  std::snprintf(mine.device, sizeof(mine.device), "%s", st.device.c_str());

  MPI_Datatype pixel_type;
  MPI_Type_contiguous(4, MPI_FLOAT, &pixel_type);
  MPI_Type_commit(&pixel_type);
  MPI_Op under;
  MPI_Op_create(&compositeUnder, 0, &under);

  // Reduce-scatter in visibility order (each rank ends with a stripe of the composited image),
  // then the stripes gathered to rank 0; once per frame, timed.
  const size_t stripe = (pixels + size_t(mpi.size) - 1) / size_t(mpi.size);
  std::vector<float> share(stripe * size_t(mpi.size) * 4, 0.0f);
  for (size_t i = 0; i < share.size(); i += 4) share[i + 3] = 1.0f;  // the padding: empty
  std::copy(result.partial.begin(), result.partial.end(), share.begin());
  std::vector<float> part(stripe * 4),
      image_rgbt(mpi.rank == 0 ? stripe * size_t(mpi.size) * 4 : 0);
  std::vector<double> composite_ms;
  for (int f = 0; f < std::max(1, settings.frames); ++f) {
    MPI_Ibarrier(ordered, &r);
    mpi.wait(r, "the start of a frame's composite");
    const double t0 = MPI_Wtime();
    MPI_Ireduce_scatter_block(share.data(), part.data(), int(stripe), pixel_type, under, ordered,
                              &r);
    mpi.wait(r, "a frame's composite");
    MPI_Igather(part.data(), int(stripe), pixel_type, image_rgbt.data(), int(stripe), pixel_type,
                root, ordered, &r);
    mpi.wait(r, "a frame's composited stripes");
    composite_ms.push_back((MPI_Wtime() - t0) * 1000.0);
  }
  std::sort(composite_ms.begin(), composite_ms.end());
  mine.composite_ms = composite_ms[composite_ms.size() / 2];
  // What this rank hands the collectives per frame: the image less its own stripe, and (but
  // rank 0) its stripe.
  mine.composite_bytes = (share.size() - part.size()) * 4 + (mpi.rank == 0 ? 0 : part.size() * 4);
  std::vector<uint32_t> depth(mpi.rank == 0 ? pixels : 0);
  MPI_Ireduce(result.depth_complexity.data(), depth.data(), int(pixels), MPI_UINT32_T, MPI_SUM,
              0, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the depth complexity");
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) == 0) mine.host_peak_rss = uint64_t(usage.ru_maxrss) * 1024;
  std::vector<RankFigures> all(size_t(mpi.size));
  MPI_Igather(&mine, int(sizeof(RankFigures)), MPI_BYTE, all.data(), int(sizeof(RankFigures)),
              MPI_BYTE, 0, MPI_COMM_WORLD, &r);
  mpi.wait(r, "the ranks' statistics");
  MPI_Op_free(&under);
  MPI_Type_free(&pixel_type);
  MPI_Comm_free(&ordered);
  MPI_Comm_free(&reversed);
  if (mpi.rank != 0) return 0;

  // Rank 0: the background under the composited image, the image and the statistics.
  const StViewConstants view = makeViewConstants(settings);
  Image image(settings.width, settings.height);
  for (int y = 0; y < settings.height; ++y)
    for (int x = 0; x < settings.width; ++x) {
      const size_t p = size_t(y) * size_t(settings.width) + size_t(x);
      uint8_t* out = image.pixel(x, y);
      for (int c = 0; c < 3; ++c)
        out[c] =
            uint8_t(st_to_unorm8(image_rgbt[p * 4 + size_t(c)] +
                                 image_rgbt[p * 4 + 3] * st_background_channel(&view, x, y, c)));
      out[3] = 255;
    }
  if (!job.output.empty()) writeImage(image, job.output);
  double render_max = 0.0, composite_max = 0.0;
  uint64_t fragments = 0;
  const uint64_t max_depth = depth.empty() ? 0 : *std::max_element(depth.begin(), depth.end());
  nlohmann::json ranks = nlohmann::json::array();
  for (int r = 0; r < mpi.size; ++r) {
    const RankFigures& f = all[size_t(r)];
    render_max = std::max(render_max, f.render_ms);
    composite_max = std::max(composite_max, f.composite_ms);
    fragments += f.fragments;
    ranks.push_back({{"rank", r},
                     {"visibility_position", f.position},
                     {"device", std::string(f.device)},
                     {"leaves", f.leaves},
                     {"triangle_refs", f.refs},
                     {"fragments", f.fragments},
                     {"render_ms", f.render_ms},
                     {"composite_ms", f.composite_ms},
                     {"composite_bytes", f.composite_bytes},
                     {"disk_read_bytes", f.disk_read_bytes},
                     {"peak_device_bytes", f.peak_device_bytes},
                     {"host_peak_rss", f.host_peak_rss}});
  }
  std::printf("%-8s %10s %10s %10s %12s %10s  %s\n", "method", "render_ms", "compos_ms", "frame_ms",
              "fragments", "max_depth", "output");
  std::printf("%-8s %10.2f %10.2f %10.2f %12llu %10llu  %s\n", "octree", render_max, composite_max,
              render_max + composite_max, (unsigned long long)fragments,
              (unsigned long long)max_depth, job.output.c_str());
  if (!job.stats.empty()) {
    nlohmann::json j;
    j["method"] = "octree";
    j["scene"] = job.scene;
    j["octree_scene"] = path;
    j["width"] = settings.width;
    j["height"] = settings.height;
    j["device"] = st.device;
    j["distributed"] = true;
    j["processes"] = mpi.size;
    j["triangles"] = file->triangles();
    j["fragments"] = fragments;
    j["max_depth_complexity"] = max_depth;
    j["frame_ms"] = render_max + composite_max;
    j["render_ms"] = render_max;
    j["composite_ms"] = composite_max;
    j["image_bytes"] = pixels * 16;
    j["ranks"] = ranks;
    writeTextFileAtomically(job.stats, j.dump(2) + "\n");
  }
  return 0;
}

}  // namespace

int runDistributedRender(const DistributedJob& job) {
  MpiSession mpi(job.rank_timeout_s);
  try {
    return renderShare(job, mpi);
  } catch (const std::exception& e) {
    // A step outside attempt() failed on this rank alone (memory for the image, say): the others
    // wait for it in a collective, and would for ever (it still answers the watch's pings).
    // The job ends here, this rank naming itself.
    const bool memory = dynamic_cast<const std::bad_alloc*>(&e) != nullptr;
    mpi.watch->failAlone("--distributed: rank " + std::to_string(mpi.rank) + ": " +
                         (memory ? std::string("out of memory") : printableMessage(e.what())));
  }
}

#endif

namespace {

// Runs a command (argv[0] looked up on PATH) and waits for it; its exit status.
int runCommand(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0)
    throw Error(args[0] + ": cannot be started (" + std::strerror(errno) + ")");
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw Error(args[0] + ": lost track of it (" + std::strerror(errno) + ")");
  return WIFEXITED(status) ? WEXITSTATUS(status)
                           : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

std::string selfPath() {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("strata") : self.string();
}

std::string fileNameOf(const std::string& scene) {
  std::string name = std::filesystem::path(scene).filename().string();
  for (char& c : name)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '.') c = '_';
  return name;
}

}  // namespace

int runDistributedBench(const DistributedBench& b) {
  namespace fs = std::filesystem;
  if (!distributedAvailable())
    throw Error(
        "bench --distributed: this strata was built without MPI (install "
        "libopenmpi-dev and openmpi-bin and build again)");
  if (b.processes.empty() || b.scenes.empty()) throw Error("bench --distributed: nothing to run");
  for (int p : b.processes)
    if (p < 1 || p > 1024) throw Error("--processes: each count must be between 1 and 1024");
  checkFrameCount(b.frames, "--frames");
  if (geteuid() == 0 && !std::getenv("OMPI_ALLOW_RUN_AS_ROOT"))
    throw Error(
        "bench --distributed runs mpirun, which as root needs Open MPI's own leave: set "
        "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1");
  const fs::path out(b.out_dir);
  std::error_code ec;
  fs::create_directories(out / "images", ec);
  if (ec) throw Error(b.out_dir + ": cannot create the output folder (" + ec.message() + ")");
  const std::string self = selfPath();
  const std::string size = std::to_string(b.width) + "x" + std::to_string(b.height);
  nlohmann::json runs = nlohmann::json::array();
  std::string md = "# Distributed rendering: scaling\n\n" + size + ", " + std::to_string(b.frames) +
                   " frames, transparency; the slowest rank's render and composite medians. "
                   "Bytes: what the ranks hand the collectives per frame, against the image "
                   "size x log2 P of a binary-tree composite. Error: against one process.\n\n"
                   "| scene | P | render ms | composite ms | frame ms | speedup | bytes/frame | "
                   "ideal bytes | peak device/rank MB | host RSS/rank MB | max error |\n"
                   "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const std::string& scene : b.scenes) {
    double frame_at_one = 0.0;
    Image single;
    for (int p : b.processes) {
      const std::string tag = fileNameOf(scene) + "-p" + std::to_string(p);
      const std::string stats = (out / (tag + ".json")).string();
      const std::string image = (out / "images" / (tag + ".png")).string();
      std::fprintf(stderr, "bench --distributed: %s with %d process%s\n", scene.c_str(), p,
                   p == 1 ? "" : "es");
      std::vector<std::string> cmd{"mpirun",    "--oversubscribe",
                                   "--bind-to", "none",
                                   "-np",       std::to_string(p),
                                   self,        "render",
                                   scene,       "--distributed",
                                   "-s",        size,
                                   "--frames",  std::to_string(b.frames),
                                   "--cache",   (out / "cache").string(),
                                   "-o",        image,
                                   "--stats",   stats};
      if (!b.device.empty()) cmd.insert(cmd.end(), {"--device", b.device});
      if (const int rc = runCommand(cmd); rc != 0)
        throw Error("bench --distributed: " + scene + " with " + std::to_string(p) +
                    " processes failed (exit " + std::to_string(rc) + ")");
      std::ifstream in(stats);
      nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
      if (j.is_discarded() || !j.contains("ranks"))
        throw Error(stats + ": the statistics of the run cannot be read");
      const Image img = readImage(image);
      if (single.rgba.empty()) single = img;
      const int max_error = compareImages(img, single).max_abs;
      double bytes = 0.0, device_max = 0.0, rss_max = 0.0;
      for (const auto& r : j["ranks"]) {
        bytes += r["composite_bytes"].get<double>();
        device_max = std::max(device_max, r["peak_device_bytes"].get<double>());
        rss_max = std::max(rss_max, r["host_peak_rss"].get<double>());
      }
      const double frame = j["frame_ms"].get<double>();
      if (frame_at_one == 0.0) frame_at_one = frame;
      const double ideal = double(j["image_bytes"].get<uint64_t>()) * std::log2(double(p));
      char row[512];
      std::snprintf(row, sizeof(row),
                    "| %s | %d | %.1f | %.2f | %.1f | %.2f | %.0f | %.0f | %.1f | %.1f | %d |\n",
                    scene.c_str(), p, j["render_ms"].get<double>(), j["composite_ms"].get<double>(),
                    frame, frame_at_one / frame, bytes, ideal, device_max / 1048576.0,
                    rss_max / 1048576.0, max_error);
      md += row;
      j["bench"] = {{"bytes_per_frame", bytes},
                    {"ideal_bytes", ideal},
                    {"max_error_vs_first", max_error},
                    {"speedup", frame_at_one / frame}};
      runs.push_back(j);
    }
  }
  writeTextFileAtomically((out / "results.json").string(), runs.dump(2) + "\n");
  writeTextFileAtomically((out / "results.md").string(), md);
  std::cout << md << "wrote " << b.out_dir << "/results.json, results.md and images/\n";
  return 0;
}

}  // namespace strata
