// The out-of-core octree scene: a self-contained file holding a scene's octree and, leaf by
// leaf in the order the octree file numbers its references, each leaf's triangles (three
// world-space corners and a material per reference), with the scene's materials, bounds and
// natural view. The octree method renders it by reading only the leaves of the batch it is
// about to draw (pread into its staging buffers), so the scene's triangles never have to fit
// in host memory; every other consumer reads it whole (materializeOctreeScene). No OpenCL here.
//
// Layout (host byte order):
//   front:  "STRATA-OCTSCENE\0", u32 version, u32 zero;
//   leaves: per leaf with references, n = its reference count: u32 triangle ids[n], float
//           corners[9 n], u32 materials[n] (44 n bytes, at front + 44 * first_ref);
//   index:  the nodes (32-byte OctreeNode records, the root last), one LeafRecord per leaf with
//           references (in reference order), the materials (MaterialRecord);
//   tail:   Tail (counts, offsets, bounds, view, statistics), then u64 XXH3-64 of the front,
//           the index and the tail.
// Opening reads and checks the front, index and tail only (checksum, sizes, a tree whose
// leaves lie in the file); each leaf's bytes carry their own XXH3-64, checked on every read,
// with every material index, so a damaged or forged leaf is an error naming the file, never a
// wrong image or an out-of-range read.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "preprocess/octree.h"
#include "preprocess/scene/scene.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

class OctreeSceneFile {
 public:
  // Bytes of a leaf's reference in the file: its triangle id, three corners and a material.
  static constexpr uint64_t kBytesPerReference = 4 + 36 + 4;

  ~OctreeSceneFile();
  OctreeSceneFile(const OctreeSceneFile&) = delete;
  OctreeSceneFile& operator=(const OctreeSceneFile&) = delete;

  // Opens and checks `path`; throws Error naming the file and the problem.
  static std::shared_ptr<const OctreeSceneFile> open(const std::string& path);

  const std::string& path() const { return path_; }
  // The tree: nodes and statistics (refs stays empty: the references live in the leaves).
  const Octree& tree() const { return tree_; }
  const std::vector<Material>& materials() const { return materials_; }
  const Bounds& bounds() const { return bounds_; }
  const BoundingSphere& sphere() const { return sphere_; }
  const std::optional<OrbitView>& defaultView() const { return view_; }
  const std::optional<Projection>& defaultProjection() const { return projection_; }
  uint64_t triangles() const { return tree_.stats.triangles; }  // of the source scene
  uint64_t fileBytes() const { return file_bytes_; }
  uint64_t key() const { return key_; }  // the index's checksum: identifies the content

  // Reads leaf `node`'s triangles: 9 floats of corners per reference into `corners` and a
  // material per reference into `materials` (and the triangle ids into `ids` when given).
  // Thread-safe. Throws Error naming the file when the leaf fails its checksum or a material
  // is out of range.
  void readLeaf(uint32_t node, float* corners, uint32_t* materials, uint32_t* ids = nullptr) const;

 private:
  OctreeSceneFile() = default;
  std::string path_;
  int fd_ = -1;
  uint64_t file_bytes_ = 0, key_ = 0;
  Octree tree_;
  std::vector<uint64_t> leaf_sum_;  // per node (leaves with references)
  std::vector<Material> materials_;
  Bounds bounds_;
  BoundingSphere sphere_;
  std::optional<OrbitView> view_;
  std::optional<Projection> projection_;
};

// Whether `path` starts like an octree scene file.
bool isOctreeSceneFile(const std::string& path);

// Writes the octree scene of `scene` (flattened into `geometry`, untextured) to `path` through
// a temporary name; `tree` is its octree (from loadOrBuildOctree). `progress(fraction)` may be
// empty. Throws Error naming the file (a textured scene, a full disk); no partial file is left.
void writeOctreeScene(const std::string& path, const Scene& scene, const WorldGeometry& geometry,
                      const Octree& tree, const std::function<void(double)>& progress = {});

// A Scene standing for the file: its materials, bounds and view, no meshes, octree_file set.
Scene loadOctreeScene(const std::string& path);

// The file's triangles read whole into host memory: each triangle of the source scene once, in
// its original order (the ones the build left out are missing), three unshared corners each.
WorldGeometry materializeOctreeScene(const OctreeSceneFile& file,
                                     const std::vector<glm::vec4>& material_colors,
                                     const std::vector<uint64_t>& material_state);
// `geometry` with the triangles of its out-of-core file (if it has one) read into host memory.
WorldGeometry inCore(WorldGeometry geometry);

}  // namespace strata
