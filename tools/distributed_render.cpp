#include "tools/distributed_render.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <vector>

#include <sys/resource.h>
#include <nlohmann/json.hpp>

#include "engine/report/stats_json.h"
#include "engine/view_constants.h"
#include "kernels/strata_shared.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/core/hash.h"
#include "preprocess/image_io.h"
#include "preprocess/octree_partition.h"
#include "preprocess/octree_scene.h"

#ifdef STRATA_WITH_MPI
#include <mpi.h>
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

// MPI for the lifetime of one distributed render.
class MpiSession {
 public:
  MpiSession() {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) MPI_Init(nullptr, nullptr);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
  }
  ~MpiSession() {
    int finalized = 0;
    MPI_Finalized(&finalized);
    if (!finalized) MPI_Finalize();
  }
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank = 0, size = 1;
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
  MPI_Allreduce(&me, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == mpi.size) return std::nullopt;
  int length = mpi.rank == first ? int(std::min<size_t>(mine.size(), 4096)) : 0;
  MPI_Bcast(&length, 1, MPI_INT, first, MPI_COMM_WORLD);
  std::string message(size_t(length), ' ');
  if (mpi.rank == first) message = mine.substr(0, size_t(length));
  MPI_Bcast(message.data(), length, MPI_CHAR, first, MPI_COMM_WORLD);
  return "rank " + std::to_string(first) + ": " + message;
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
};

}  // namespace

int runDistributedRender(const DistributedJob& job) {
  MpiSession mpi;
  const auto fail = [&](const std::string& message) {
    if (mpi.rank == 0) std::cerr << "strata: error: " << message << "\n";
    return 1;
  };

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
  MPI_Bcast(&length, 1, MPI_INT, 0, MPI_COMM_WORLD);
  path.resize(size_t(length));
  MPI_Bcast(path.data(), length, MPI_CHAR, 0, MPI_COMM_WORLD);

  // Each rank's share: the leaves of its box.
  FrameSettings settings = job.settings;
  WorldGeometry geometry;
  OctreePartition partition;
  std::shared_ptr<const OctreeSceneFile> file;
  RankFigures mine;
  RenderResult result;
  error = attempt([&] {
    if (settings.effect != Effect::Transparency)
      throw Error("--distributed renders transparency (translucency across ranks is not built)");
    const Scene scene = loadScene(path);
    if (!scene.out_of_core) throw Error(path + ": not an octree scene");
    file = scene.out_of_core->file;
    settings.camera = job.camera(scene);
    geometry = WorldGeometry::fromScene(scene, job.alpha);
    partition = partitionOctree(file->tree(), uint32_t(mpi.size));
    auto leaves = std::make_shared<std::vector<uint32_t> >(partition.leaves[size_t(mpi.rank)]);
    mine.leaves = leaves->size();
    mine.refs = partition.refs[size_t(mpi.rank)];
    settings.octree_leaves = std::move(leaves);
    settings.partial = true;
    settings.capture_depth_complexity = true;  // summed over the ranks: the true deepest pixel
    if (mpi.rank == job.fail_rank)
      throw Error("failed on purpose (--fail-rank " + std::to_string(job.fail_rank) + ")");
    result = makeRenderer(Method::Octree, job.device)->render(geometry, settings);
  });
  if (auto e = firstFailure(error, mpi)) return fail(*e);
  const FrameStats& st = result.stats;
  mine.render_ms = st.frame_ms.median;
  mine.fragments = st.fragments;
  mine.peak_device_bytes = st.peak_device_bytes;
  mine.disk_read_bytes = st.disk_read_bytes;

  // Visibility order of the boxes for the view, as the ranks' order in a communicator.
  const std::vector<uint32_t> order =
      partsFrontToBack(partition, settings.camera.projection == Projection::Perspective,
                       settings.camera.eye, settings.camera.forward());
  int position = 0, root = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    if (int(order[i]) == mpi.rank) position = int(i);
    if (order[i] == 0) root = int(i);
  }
  mine.position = position;
  MPI_Comm ordered;
  MPI_Comm_split(MPI_COMM_WORLD, 0, position, &ordered);
  MPI_Datatype pixel_type;
  MPI_Type_contiguous(4, MPI_FLOAT, &pixel_type);
  MPI_Type_commit(&pixel_type);
  MPI_Op under;
  MPI_Op_create(&compositeUnder, 0, &under);

  // Reduce-scatter in visibility order (each rank ends with a stripe of the composited image),
  // then the stripes gathered to rank 0; once per frame, timed.
  const size_t pixels = size_t(settings.width) * size_t(settings.height);
  const size_t stripe = (pixels + size_t(mpi.size) - 1) / size_t(mpi.size);
  std::vector<float> share(stripe * size_t(mpi.size) * 4, 0.0f);
  for (size_t i = 0; i < share.size(); i += 4) share[i + 3] = 1.0f;  // the padding: empty
  std::copy(result.partial.begin(), result.partial.end(), share.begin());
  std::vector<float> part(stripe * 4),
      image_rgbt(mpi.rank == 0 ? stripe * size_t(mpi.size) * 4 : 0);
  std::vector<double> composite_ms;
  for (int f = 0; f < std::max(1, settings.frames); ++f) {
    MPI_Barrier(ordered);
    const double t0 = MPI_Wtime();
    MPI_Reduce_scatter_block(share.data(), part.data(), int(stripe), pixel_type, under, ordered);
    MPI_Gather(part.data(), int(stripe), pixel_type, image_rgbt.data(), int(stripe), pixel_type,
               root, ordered);
    composite_ms.push_back((MPI_Wtime() - t0) * 1000.0);
  }
  std::sort(composite_ms.begin(), composite_ms.end());
  mine.composite_ms = composite_ms[composite_ms.size() / 2];
  // What this rank hands the collectives per frame: the image less its own stripe, and (but
  // rank 0) its stripe.
  mine.composite_bytes = (share.size() - part.size()) * 4 + (mpi.rank == 0 ? 0 : part.size() * 4);
  std::vector<uint32_t> depth(mpi.rank == 0 ? pixels : 0);
  MPI_Reduce(result.depth_complexity.data(), depth.data(), int(pixels), MPI_UINT32_T, MPI_SUM, 0,
             MPI_COMM_WORLD);
  struct rusage usage {};
  if (getrusage(RUSAGE_SELF, &usage) == 0) mine.host_peak_rss = uint64_t(usage.ru_maxrss) * 1024;
  std::vector<RankFigures> all(size_t(mpi.size));
  MPI_Gather(&mine, int(sizeof(RankFigures)), MPI_BYTE, all.data(), int(sizeof(RankFigures)),
             MPI_BYTE, 0, MPI_COMM_WORLD);
  MPI_Op_free(&under);
  MPI_Type_free(&pixel_type);
  MPI_Comm_free(&ordered);
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

#endif

}  // namespace strata
