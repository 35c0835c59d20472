#include "preprocess/octree_scene.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include "preprocess/core/files.h"

namespace strata {

namespace {

constexpr char kMagic[16] = {'S', 'T', 'R', 'A', 'T', 'A', '-', 'O',
                             'C', 'T', 'S', 'C', 'E', 'N', 'E', '\0'};
constexpr uint32_t kVersion = 1;
constexpr uint64_t kFrontBytes = 24;
constexpr uint64_t kRefBytes = OctreeSceneFile::kBytesPerReference;

struct Front {
  char magic[16];
  uint32_t version, zero;
};
static_assert(sizeof(Front) == kFrontBytes);

struct LeafRecord {
  uint64_t first_ref, count, sum;
};

struct MaterialRecord {
  float color[4];
  float opacity;
  uint32_t shader_variant, pad[2];
};
static_assert(sizeof(MaterialRecord) == 32);

struct Tail {
  uint64_t triangles, skipped, refs, nodes, leaf_records, materials, leaves, empty_leaves,
      largest_leaf;
  uint32_t depth, leaf_triangles, max_level, projection;  // projection: 0 none, 1 persp, 2 ortho
  float bounds_min[3], bounds_max[3], sphere_center[3], sphere_radius;
  float view[4];  // azimuth, elevation, distance, ortho height; NaN: unset (all NaN: no view)
  double build_ms;
};
static_assert(sizeof(Tail) % 8 == 0);

// Reads exactly `bytes` at `offset`; false on a short read (the file shrank) or an error.
bool readAt(int fd, void* out, uint64_t bytes, uint64_t offset) {
  char* p = static_cast<char*>(out);
  while (bytes > 0) {
    const ssize_t got = ::pread(fd, p, size_t(std::min<uint64_t>(bytes, 1u << 30)), off_t(offset));
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) return false;
    p += got;
    bytes -= uint64_t(got);
    offset += uint64_t(got);
  }
  return true;
}

bool finite3(const float* v) {
  return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

class Hasher {
 public:
  Hasher() : state_(XXH3_createState()) {
    if (!state_) throw std::bad_alloc();
    XXH3_64bits_reset(state_);
  }
  ~Hasher() { XXH3_freeState(state_); }
  Hasher(const Hasher&) = delete;
  Hasher& operator=(const Hasher&) = delete;
  void add(const void* data, size_t bytes) { XXH3_64bits_update(state_, data, bytes); }
  uint64_t digest() const { return XXH3_64bits_digest(state_); }

 private:
  XXH3_state_t* state_;
};

// The leaves with references, in reference order.
std::vector<uint32_t> leavesByReference(const Octree& tree) {
  std::vector<uint32_t> leaves;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i)
    if (tree.nodes[i].leaf() && tree.nodes[i].ref_count) leaves.push_back(i);
  std::sort(leaves.begin(), leaves.end(), [&](uint32_t a, uint32_t b) {
    return tree.nodes[a].first_ref < tree.nodes[b].first_ref;
  });
  return leaves;
}

}  // namespace

OctreeSceneFile::~OctreeSceneFile() {
  if (fd_ >= 0) ::close(fd_);
}

bool isOctreeSceneFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[sizeof(kMagic)] = {};
  return in.read(magic, sizeof(magic)) && std::memcmp(magic, kMagic, sizeof(kMagic)) == 0;
}

std::shared_ptr<const OctreeSceneFile> OctreeSceneFile::open(const std::string& path) {
  std::shared_ptr<OctreeSceneFile> f(new OctreeSceneFile());
  f->path_ = path;
  const auto fail = [&](const std::string& why) -> void {
    throw Error(path + ": not a valid octree scene: " + why);
  };
  f->fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (f->fd_ < 0)
    throw Error(path + ": cannot open the octree scene (" + std::strerror(errno) + ")");
  struct stat st {};
  if (::fstat(f->fd_, &st) != 0 || !S_ISREG(st.st_mode)) throw Error(path + ": not a regular file");
  const uint64_t size = uint64_t(st.st_size);
  f->file_bytes_ = size;
  Front front{};
  Tail t{};
  uint64_t stored_sum = 0;
  if (size < kFrontBytes + sizeof(Tail) + 8) fail("too short");
  if (!readAt(f->fd_, &front, sizeof(front), 0)) fail("cannot read its head");
  if (std::memcmp(front.magic, kMagic, sizeof(kMagic)) != 0) {
    char octree_magic[12];
    std::memcpy(octree_magic, front.magic, sizeof(octree_magic));
    if (std::memcmp(octree_magic, "STRATAOCTREE", 12) == 0)
      fail(
          "an octree cache file, which holds no triangles (write an octree scene with "
          "strata prep SCENE --octree -o FILE.octree)");
    fail("not an octree scene file");
  }
  if (front.version != kVersion || front.zero != 0)
    fail("format version " + std::to_string(front.version) + " (this strata reads version " +
         std::to_string(kVersion) + ")");
  if (!readAt(f->fd_, &t, sizeof(t), size - 8 - sizeof(Tail)) ||
      !readAt(f->fd_, &stored_sum, 8, size - 8))
    fail("cannot read its tail");
  // Sizes first, each bounded by the file before any product is formed.
  const uint64_t room = size - kFrontBytes - sizeof(Tail) - 8;
  if (t.refs > room / kRefBytes || t.nodes > room / sizeof(OctreeNode) ||
      t.leaf_records > room / sizeof(LeafRecord) || t.materials > room / sizeof(MaterialRecord) ||
      t.nodes == 0 || t.materials == 0 || t.triangles > uint64_t(UINT32_MAX))
    fail("inconsistent sizes");
  const uint64_t index_bytes = t.nodes * sizeof(OctreeNode) + t.leaf_records * sizeof(LeafRecord) +
                               t.materials * sizeof(MaterialRecord);
  if (t.refs * kRefBytes + index_bytes != room) fail("inconsistent sizes");
  const uint64_t index_at = kFrontBytes + t.refs * kRefBytes;
  std::vector<char> index(index_bytes);
  if (!readAt(f->fd_, index.data(), index_bytes, index_at)) fail("cannot read its index");
  Hasher h;
  h.add(&front, sizeof(front));
  h.add(index.data(), index.size());
  h.add(&t, sizeof(t));
  if (h.digest() != stored_sum) fail("checksum mismatch");
  f->key_ = stored_sum;

  Octree& tree = f->tree_;
  tree.options.leaf_triangles = t.leaf_triangles;
  tree.options.max_level = t.max_level;
  tree.nodes.resize(t.nodes);
  std::memcpy(tree.nodes.data(), index.data(), t.nodes * sizeof(OctreeNode));
  std::vector<LeafRecord> records(t.leaf_records);
  std::memcpy(records.data(), index.data() + t.nodes * sizeof(OctreeNode),
              t.leaf_records * sizeof(LeafRecord));
  std::vector<MaterialRecord> materials(t.materials);
  std::memcpy(materials.data(),
              index.data() + t.nodes * sizeof(OctreeNode) + t.leaf_records * sizeof(LeafRecord),
              t.materials * sizeof(MaterialRecord));
  if (t.max_level > kMaxOctreeLevel || t.leaf_triangles == 0) fail("bad options");
  if (const std::string why = checkOctreeNodes(tree.nodes, t.refs, t.max_level); !why.empty())
    fail(why);
  // One record per leaf with references, covering the references in order: each leaf's bytes
  // are its own, and each has its checksum.
  f->leaf_sum_.assign(tree.nodes.size(), 0);
  const std::vector<uint32_t> leaves = leavesByReference(tree);
  if (leaves.size() != records.size()) fail("leaf records that do not match the leaves");
  uint64_t next = 0;
  for (size_t i = 0; i < leaves.size(); ++i) {
    const OctreeNode& n = tree.nodes[leaves[i]];
    if (records[i].first_ref != n.first_ref || records[i].count != n.ref_count ||
        n.first_ref != next)
      fail("leaf records that do not match the leaves");
    next += n.ref_count;
    f->leaf_sum_[leaves[i]] = records[i].sum;
  }
  if (next != t.refs) fail("references outside every leaf");
  for (const MaterialRecord& m : materials) {
    Material mat;
    mat.color = glm::vec4(m.color[0], m.color[1], m.color[2], m.color[3]);
    mat.opacity = m.opacity;
    mat.shader_variant = m.shader_variant;
    if (!std::isfinite(m.color[0] + m.color[1] + m.color[2] + m.color[3] + m.opacity))
      fail("a material that is not finite");
    f->materials_.push_back(mat);
  }
  if (!finite3(t.bounds_min) || !finite3(t.bounds_max) || !finite3(t.sphere_center) ||
      !(t.sphere_radius > 0.0f) || !std::isfinite(t.sphere_radius))
    fail("bad bounds");
  f->bounds_.min = glm::vec3(t.bounds_min[0], t.bounds_min[1], t.bounds_min[2]);
  f->bounds_.max = glm::vec3(t.bounds_max[0], t.bounds_max[1], t.bounds_max[2]);
  f->sphere_.center = glm::vec3(t.sphere_center[0], t.sphere_center[1], t.sphere_center[2]);
  f->sphere_.radius = t.sphere_radius;
  if (std::isfinite(t.view[0]) && std::isfinite(t.view[1])) {
    OrbitView v;
    v.azimuth_deg = t.view[0];
    v.elevation_deg = t.view[1];
    if (std::isfinite(t.view[2])) v.distance_radii = t.view[2];
    if (std::isfinite(t.view[3])) v.ortho_height = t.view[3];
    f->view_ = v;
  }
  if (t.projection == 1) f->projection_ = Projection::Perspective;
  if (t.projection == 2) f->projection_ = Projection::Orthographic;
  tree.stats.triangles = t.triangles;
  tree.stats.skipped = t.skipped;
  tree.stats.nodes = t.nodes;
  tree.stats.leaves = t.leaves;
  tree.stats.empty_leaves = t.empty_leaves;
  tree.stats.refs = t.refs;
  tree.stats.largest_leaf = t.largest_leaf;
  tree.stats.depth = t.depth;
  tree.stats.build_ms = t.build_ms;
  return f;
}

void OctreeSceneFile::readLeaf(uint32_t node, float* corners, uint32_t* materials,
                               uint32_t* ids) const {
  if (node >= tree_.nodes.size() || !tree_.nodes[node].leaf())
    throw Error(path_ + ": node " + std::to_string(node) + " is not a leaf");
  const OctreeNode& n = tree_.nodes[node];
  const uint64_t count = n.ref_count;
  if (count == 0) return;
  std::vector<uint32_t> own_ids;
  if (!ids) {
    own_ids.resize(count);
    ids = own_ids.data();
  }
  const uint64_t at = kFrontBytes + uint64_t(n.first_ref) * kRefBytes;
  if (!readAt(fd_, ids, count * 4, at) || !readAt(fd_, corners, count * 36, at + count * 4) ||
      !readAt(fd_, materials, count * 4, at + count * 40))
    throw Error(path_ + ": cannot read the triangles of leaf " + std::to_string(node) +
                " (the file was truncated or cannot be read)");
  Hasher h;
  h.add(ids, count * 4);
  h.add(corners, count * 36);
  h.add(materials, count * 4);
  if (h.digest() != leaf_sum_[node])
    throw Error(path_ + ": the triangles of leaf " + std::to_string(node) +
                " fail their checksum (the file is damaged)");
  for (uint64_t i = 0; i < count; ++i)
    if (materials[i] >= materials_.size() || ids[i] >= tree_.stats.triangles)
      throw Error(path_ + ": leaf " + std::to_string(node) +
                  " has a material or triangle id out of range");
}

void writeOctreeScene(const std::string& path, const Scene& scene, const WorldGeometry& geometry,
                      const Octree& tree, const std::function<void(double)>& progress) {
  if (geometry.textured())
    throw Error(path +
                ": textured scenes are not written as octree scenes (their texture "
                "coordinates and images stay in the scene file)");
  if (tree.empty() || tree.refs.size() != tree.stats.refs)
    throw Error(path + ": the octree of the scene is not complete in memory");
  const std::vector<uint32_t> leaves = leavesByReference(tree);
  std::vector<LeafRecord> records;
  uint64_t next = 0;
  for (uint32_t leaf : leaves) {
    const OctreeNode& n = tree.nodes[leaf];
    if (n.first_ref != next) throw Error(path + ": the octree's leaves overlap in its references");
    next += n.ref_count;
  }
  std::vector<MaterialRecord> materials;
  for (size_t i = 0; i < geometry.material_colors.size(); ++i) {
    const glm::vec4 c =
        i < scene.materials.size() ? scene.materials[i].color : glm::vec4(0.8f, 0.8f, 0.8f, 1.0f);
    MaterialRecord m{};
    for (int k = 0; k < 4; ++k) m.color[k] = c[k];
    m.opacity = geometry.material_colors[i].a;
    m.shader_variant = i < scene.materials.size() ? scene.materials[i].shader_variant : 0;
    materials.push_back(m);
  }

  writeFileAtomically(path, "octree scene", [&](const std::filesystem::path& temp) {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path + ": cannot write the octree scene (" + std::strerror(errno) + ")");
    Hasher index_sum;
    const auto put = [&](const void* data, size_t bytes, bool indexed) {
      out.write(static_cast<const char*>(data), std::streamsize(bytes));
      if (indexed) index_sum.add(data, bytes);
    };
    Front front{};
    std::memcpy(front.magic, kMagic, sizeof(kMagic));
    front.version = kVersion;
    put(&front, sizeof(front), true);
    std::vector<float> corners;
    std::vector<uint32_t> mats;
    for (size_t li = 0; li < leaves.size(); ++li) {
      const OctreeNode& n = tree.nodes[leaves[li]];
      const uint32_t* ids = tree.refs.data() + n.first_ref;
      corners.resize(size_t(n.ref_count) * 9);
      mats.resize(n.ref_count);
      for (uint32_t j = 0; j < n.ref_count; ++j) {
        const uint32_t t = ids[j];
        for (int c = 0; c < 3; ++c) {
          const glm::vec3& p = geometry.positions[geometry.indices[size_t(t) * 3 + c]];
          corners[size_t(j) * 9 + c * 3] = p.x;
          corners[size_t(j) * 9 + c * 3 + 1] = p.y;
          corners[size_t(j) * 9 + c * 3 + 2] = p.z;
        }
        mats[j] = geometry.triangle_material[t];
      }
      Hasher leaf_sum;
      leaf_sum.add(ids, size_t(n.ref_count) * 4);
      leaf_sum.add(corners.data(), corners.size() * 4);
      leaf_sum.add(mats.data(), mats.size() * 4);
      put(ids, size_t(n.ref_count) * 4, false);
      put(corners.data(), corners.size() * 4, false);
      put(mats.data(), mats.size() * 4, false);
      records.push_back({n.first_ref, n.ref_count, leaf_sum.digest()});
      if (!out) throw Error(path + ": writing the octree scene failed (disk full?)");
      if (progress) progress(double(li + 1) / double(leaves.size()));
    }
    put(tree.nodes.data(), tree.nodes.size() * sizeof(OctreeNode), true);
    put(records.data(), records.size() * sizeof(LeafRecord), true);
    put(materials.data(), materials.size() * sizeof(MaterialRecord), true);
    Tail t{};
    t.triangles = tree.stats.triangles;
    t.skipped = tree.stats.skipped;
    t.refs = tree.stats.refs;
    t.nodes = tree.nodes.size();
    t.leaf_records = records.size();
    t.materials = materials.size();
    t.leaves = tree.stats.leaves;
    t.empty_leaves = tree.stats.empty_leaves;
    t.largest_leaf = tree.stats.largest_leaf;
    t.depth = tree.stats.depth;
    t.leaf_triangles = tree.options.leaf_triangles;
    t.max_level = tree.options.max_level;
    const Bounds b = scene.worldBounds();
    const BoundingSphere s = scene.boundingSphere();
    for (int k = 0; k < 3; ++k) {
      t.bounds_min[k] = b.empty() ? 0.0f : b.min[k];
      t.bounds_max[k] = b.empty() ? 0.0f : b.max[k];
      t.sphere_center[k] = s.center[k];
    }
    t.sphere_radius = s.radius;
    for (float& v : t.view) v = NAN;
    if (scene.default_view) {
      t.view[0] = scene.default_view->azimuth_deg;
      t.view[1] = scene.default_view->elevation_deg;
      if (scene.default_view->distance_radii) t.view[2] = *scene.default_view->distance_radii;
      if (scene.default_view->ortho_height) t.view[3] = *scene.default_view->ortho_height;
    }
    t.projection = !scene.default_projection                              ? 0
                   : *scene.default_projection == Projection::Perspective ? 1
                                                                          : 2;
    t.build_ms = tree.stats.build_ms;
    put(&t, sizeof(t), true);
    const uint64_t sum = index_sum.digest();
    put(&sum, sizeof(sum), false);
    out.close();
    if (!out) throw Error(path + ": writing the octree scene failed (disk full?)");
  });
}

Scene loadOctreeScene(const std::string& path) {
  const std::shared_ptr<const OctreeSceneFile> file = OctreeSceneFile::open(path);
  Scene scene;
  scene.source = path;
  scene.materials = file->materials();
  scene.default_view = file->defaultView();
  scene.default_projection = file->defaultProjection();
  scene.report.triangles_loaded = file->triangles() - file->tree().stats.skipped;
  auto ooc = std::make_shared<OutOfCoreTriangles>();
  ooc->file = file;
  ooc->path = path;
  ooc->triangles = file->triangles();
  ooc->bounds = file->bounds();
  ooc->sphere = file->sphere();
  scene.out_of_core = std::move(ooc);
  return scene;
}

WorldGeometry materializeOctreeScene(const OctreeSceneFile& file,
                                     const std::vector<glm::vec4>& material_colors,
                                     const std::vector<uint64_t>& material_state) {
  const uint64_t triangles = file.triangles();
  std::vector<uint8_t> seen(triangles, 0);
  std::vector<glm::vec3> corners(triangles * 3);
  std::vector<uint32_t> material(triangles, 0);
  std::vector<float> leaf_corners;
  std::vector<uint32_t> leaf_materials, leaf_ids;
  const Octree& tree = file.tree();
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    const OctreeNode& n = tree.nodes[i];
    if (!n.leaf() || n.ref_count == 0) continue;
    leaf_corners.resize(size_t(n.ref_count) * 9);
    leaf_materials.resize(n.ref_count);
    leaf_ids.resize(n.ref_count);
    file.readLeaf(i, leaf_corners.data(), leaf_materials.data(), leaf_ids.data());
    for (uint32_t j = 0; j < n.ref_count; ++j) {
      const uint32_t t = leaf_ids[j];
      if (seen[t]) continue;
      seen[t] = 1;
      std::memcpy(&corners[size_t(t) * 3], &leaf_corners[size_t(j) * 9], 36);
      material[t] = leaf_materials[j];
    }
  }
  WorldGeometry g;
  g.material_colors = material_colors;
  g.material_state = material_state;
  for (uint64_t t = 0; t < triangles; ++t) {
    if (!seen[t]) continue;
    const uint32_t base = uint32_t(g.positions.size());
    for (int c = 0; c < 3; ++c) {
      g.positions.push_back(corners[t * 3 + c]);
      g.indices.push_back(base + uint32_t(c));
    }
    g.triangle_material.push_back(material[t] < material_colors.size() ? material[t] : 0);
    g.triangle_object.push_back(0);
  }
  return g;
}

WorldGeometry inCore(WorldGeometry geometry) {
  if (!geometry.out_of_core) return geometry;
  return materializeOctreeScene(*geometry.out_of_core->file, geometry.material_colors,
                                geometry.material_state);
}

}  // namespace strata
