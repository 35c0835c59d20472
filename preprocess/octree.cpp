#include "preprocess/octree.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <optional>

#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/core/hash.h"
#include "strata/error.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

constexpr uint32_t kOctreeVersion = 2;
constexpr char kMagic[12] = {'S', 'T', 'R', 'A', 'T', 'A', 'O', 'C', 'T', 'R', 'E', 'E'};
constexpr size_t kMaxOctreeFileBytes = size_t(1) << 36;

// The children's cubes are closed and widened by this share of their side, so a triangle that
// touches a cube within rounding is referenced by it: a missing reference would lose fragments,
// an extra one only costs a duplicate that the per-pixel leaf intervals discard.
constexpr float kBoxSlack = 1e-4f;
// ... and by at least this share of the root's side: a fragment's point on its pixel ray lies
// within the raster's rounding of its triangle (half a 1/256-pixel snap, about 3e-6 of the view
// distance at 512x512), and small leaves would otherwise widen by less than that.
constexpr float kRootSlack = 1.0f / 65536.0f;

bool finite(const glm::vec3& p) {
  return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
}

// Projections of the triangle's corners onto `axis` against the box's half extent `h`.
bool separatedOn(const glm::vec3& axis, const glm::vec3& v0, const glm::vec3& v1,
                 const glm::vec3& v2, const glm::vec3& h) {
  const float p0 = glm::dot(axis, v0), p1 = glm::dot(axis, v1), p2 = glm::dot(axis, v2);
  const float r = h.x * std::abs(axis.x) + h.y * std::abs(axis.y) + h.z * std::abs(axis.z);
  return std::min(p0, std::min(p1, p2)) > r || std::max(p0, std::max(p1, p2)) < -r;
}

class Builder {
 public:
  Builder(const MeshView& mesh, const OctreeOptions& options, OctreeSink& sink,
          const std::function<void(double)>& progress)
      : mesh_(mesh),
        options_(options),
        sink_(sink),
        progress_(progress),
        pending_(options.max_level + 2),
        lists_(options.max_level + 2) {}

  // A split whose children would reference more than this many times the node's triangles only
  // copies references (coincident, overlapping or large triangles that cover most children: one
  // face listed 10,000 times, say), and copies them again at every level below: the node stays
  // a leaf over the face limit instead. Spread-out triangles of any size split at about 1x to
  // 2x (a triangle in more than one child only where it crosses a split plane).
  static constexpr double kMaxSplitGrowth = 3.0;
  // ... and when one child would keep at least this share of them: the split separates
  // (nearly) nothing. Small leaf limits, where a node's triangles are large for its cube, still
  // split while they separate something.
  static constexpr double kUnseparated = 0.9;
  // The most references a build makes: this many per triangle, plus an allowance.
  static constexpr uint64_t kMaxRefsPerTriangle = 32;
  static constexpr uint64_t kRefsAllowance = uint64_t(1) << 20;

  OctreeStats run() {
    const auto t0 = std::chrono::steady_clock::now();
    stats_.triangles = mesh_.triangle_count;
    // The root cube: the bounds of every usable triangle, made a cube around their centre.
    std::vector<uint32_t>& all = lists_[0][0];
    glm::vec3 lo(1e30f), hi(-1e30f);
    for (uint32_t t = 0; t < mesh_.triangle_count; ++t) {
      glm::vec3 p[3];
      if (!corners(t, p)) {
        ++stats_.skipped;
        continue;
      }
      all.push_back(t);
      for (const glm::vec3& q : p) {
        lo = glm::min(lo, q);
        hi = glm::max(hi, q);
      }
    }
    if (all.empty()) lo = hi = glm::vec3(0.0f);
    const glm::vec3 extent = hi - lo;
    const float side = std::max(std::max(extent.x, extent.y), std::max(extent.z, 1e-20f)) *
                       (1.0f + 2.0f * kBoxSlack);
    const glm::vec3 root_lo = 0.5f * (lo + hi) - glm::vec3(0.5f * side);
    root_slack_ = kRootSlack * side;
    child_ = 0;
    OctreeNode root = build(root_lo, side, 0, 1.0);
    sink_.nodes(&root, 1);
    ++stats_.nodes;
    stats_.build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return stats_;
  }

 private:
  // The corners of triangle t; false when an index is out of range or a corner is not finite.
  bool corners(uint32_t t, glm::vec3 p[3]) const {
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh_.indices[size_t(t) * 3 + k];
      if (v >= mesh_.vertex_count) return false;
      p[k] = mesh_.positions[v];
      if (!finite(p[k])) return false;
    }
    return true;
  }

  // Builds the node with cube (lo, size) at `level` over lists_[level][child_]; returns its record,
  // which the caller emits with its siblings.
  OctreeNode build(const glm::vec3& lo, float size, uint32_t level, double share) {
    OctreeNode node;
    node.lo = lo;
    node.size = size;
    node.level = level;
    stats_.depth = std::max(stats_.depth, level);
    std::vector<uint32_t>& tris = lists_[level][child_];
    bool leaf = tris.size() <= options_.leaf_triangles || level >= options_.max_level;
    const float half = 0.5f * size;
    auto childLo = [&](uint32_t i) {
      return lo + glm::vec3((i & 1) ? half : 0.0f, (i & 2) ? half : 0.0f, (i & 4) ? half : 0.0f);
    };
    std::array<std::vector<uint32_t>, 8>& kids = lists_[level + 1];
    if (!leaf) {
      size_t referenced = 0, largest = 0;
      for (uint32_t i = 0; i < 8; ++i) {
        filterInto(tris, childLo(i), half, kids[i]);
        referenced += kids[i].size();
        largest = std::max(largest, kids[i].size());
      }
      if (double(referenced) > kMaxSplitGrowth * double(tris.size()) &&
          double(largest) >= kUnseparated * double(tris.size())) {
        leaf = true;
        ++stats_.unsplit_leaves;
        for (std::vector<uint32_t>& k : kids) std::vector<uint32_t>().swap(k);
      }
    }
    if (leaf) {
      // What a build may write is bounded by its input: the refs of a degenerate mesh must not
      // fill the disk (or the memory) before anyone sees why.
      const uint64_t max_refs = std::min<uint64_t>(
          kMaxRefsPerTriangle * lists_[0][0].size() + kRefsAllowance, UINT32_MAX);
      if (stats_.refs + tris.size() > max_refs)
        throw OctreeRefused(
            "the octree of " + std::to_string(lists_[0][0].size()) +
            " triangles would hold more than " + std::to_string(max_refs) +
            " triangle references (faces that overlap throughout the scene?); not built");
      node.first_ref = uint32_t(stats_.refs);
      node.ref_count = uint32_t(tris.size());
      if (!tris.empty()) sink_.leafRefs(tris.data(), tris.size());
      stats_.refs += tris.size();
      ++stats_.leaves;
      if (tris.empty()) ++stats_.empty_leaves;
      stats_.largest_leaf = std::max<uint64_t>(stats_.largest_leaf, tris.size());
      done_ += share;
      if (progress_) progress_(std::min(1.0, done_));
      return node;
    }
    std::array<OctreeNode, 8>& children = pending_[level + 1];
    for (uint32_t i = 0; i < 8; ++i) {
      child_ = i;
      children[i] = build(childLo(i), half, level + 1, share / 8.0);
      std::vector<uint32_t>().swap(kids[i]);  // its subtree is done
    }
    STRATA_CHECK(stats_.nodes + 8 < kNoChildren);
    node.first_child = uint32_t(stats_.nodes);
    sink_.nodes(children.data(), 8);
    stats_.nodes += 8;
    return node;
  }

  // The triangles of `tris` that meet the widened closed cube (lo, size).
  void filterInto(const std::vector<uint32_t>& tris, const glm::vec3& lo, float size,
                  std::vector<uint32_t>& out) const {
    out.clear();
    const float slack = std::max(kBoxSlack * size, root_slack_);
    const glm::vec3 box_lo = lo - glm::vec3(slack), box_hi = lo + glm::vec3(size + slack);
    for (uint32_t t : tris) {
      glm::vec3 p[3];
      corners(t, p);
      const glm::vec3 tlo = glm::min(p[0], glm::min(p[1], p[2]));
      const glm::vec3 thi = glm::max(p[0], glm::max(p[1], p[2]));
      if (glm::any(glm::lessThan(thi, box_lo)) || glm::any(glm::greaterThan(tlo, box_hi))) continue;
      // Inside the box along every axis: no other axis can separate them.
      const bool inside =
          glm::all(glm::greaterThanEqual(tlo, box_lo)) && glm::all(glm::lessThanEqual(thi, box_hi));
      if (inside || triangleOverlapsBox(p[0], p[1], p[2], box_lo, box_hi)) out.push_back(t);
    }
  }

  float root_slack_ = 0.0f;
  const MeshView& mesh_;
  const OctreeOptions options_;
  OctreeSink& sink_;
  const std::function<void(double)>& progress_;
  std::vector<std::array<OctreeNode, 8>> pending_;  // per level: the children being built
  // Per level: the triangles of the eight children of the node on the path at the level above
  // (filtered together, to see what a split would copy); lists_[0][0] holds the root's, and
  // child_ is the one being built.
  std::vector<std::array<std::vector<uint32_t>, 8>> lists_;
  uint32_t child_ = 0;
  OctreeStats stats_;
  double done_ = 0.0;
};

class MemorySink : public OctreeSink {
 public:
  explicit MemorySink(Octree& tree) : tree_(tree) {}
  void leafRefs(const uint32_t* refs, size_t count) override {
    tree_.refs.insert(tree_.refs.end(), refs, refs + count);
  }
  void nodes(const OctreeNode* nodes, size_t count) override {
    tree_.nodes.insert(tree_.nodes.end(), nodes, nodes + count);
  }

 private:
  Octree& tree_;
};

void checkOptions(const OctreeOptions& options) {
  if (options.leaf_triangles == 0)
    throw Error("the octree's leaf face limit (--leaf-tris) must be at least 1");
  if (options.max_level > kMaxOctreeLevel)
    throw Error("the octree's deepest level must be at most " + std::to_string(kMaxOctreeLevel));
}

uint64_t cacheKey(const MeshView& mesh, const OctreeOptions& options) {
  const uint32_t opts[2] = {options.leaf_triangles, options.max_level};
  return meshCacheKey("strata-octree", kOctreeVersion, mesh, opts);
}

// The fixed head of the file: everything known before the build starts.
std::string fileHead(const MeshView& mesh, const OctreeOptions& options) {
  std::string head(kMagic, sizeof(kMagic));
  auto put = [&](const auto& v) { head.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  put(kOctreeVersion);
  put(cacheKey(mesh, options));
  put(options.leaf_triangles);
  put(options.max_level);
  put(uint64_t(mesh.triangle_count));
  put(uint64_t(mesh.vertex_count));
  return head;
}

// The trailer: the stats and the counts (the build's results).
struct Trailer {
  uint64_t triangles, skipped, nodes, leaves, empty_leaves, refs, largest_leaf;
  uint32_t depth, pad;
  double build_ms;
  uint64_t ref_count, node_count;
};
static_assert(sizeof(Trailer) == 88, "Trailer is a file record");

// Writes the refs into the temporary file as leaves finish and the nodes into a second one,
// appended when the build is done; hashes every byte in file order.
class FileSink : public OctreeSink {
 public:
  FileSink(const fs::path& main, const fs::path& side, const std::string& target, Octree* keep)
      : target_(target),
        keep_(keep),
        main_(main, std::ios::binary | std::ios::trunc),
        side_(side, std::ios::binary | std::ios::trunc) {
    if (!main_ || !side_)
      throw Error(target + ": cannot write the octree (" + std::strerror(errno) + ")");
  }
  void write(const void* data, size_t size) {
    main_.write(static_cast<const char*>(data), std::streamsize(size));
    hash_ = fnv1a64(data, size, hash_);
  }
  void leafRefs(const uint32_t* refs, size_t count) override {
    write(refs, count * sizeof(uint32_t));
    if (keep_) keep_->refs.insert(keep_->refs.end(), refs, refs + count);
  }
  void nodes(const OctreeNode* nodes, size_t count) override {
    if (keep_) keep_->nodes.insert(keep_->nodes.end(), nodes, nodes + count);
    side_.write(reinterpret_cast<const char*>(nodes), std::streamsize(count * sizeof(OctreeNode)));
  }
  // Appends the nodes and the trailer, then the checksum.
  void finish(const fs::path& side, const OctreeStats& s) {
    side_.close();
    if (!side_) throw Error(target_ + ": writing the octree failed (disk full?)");
    std::ifstream in(side, std::ios::binary);
    std::vector<char> buffer(size_t(1) << 20);
    while (in) {
      in.read(buffer.data(), std::streamsize(buffer.size()));
      if (in.gcount() > 0) write(buffer.data(), size_t(in.gcount()));
    }
    Trailer t{s.triangles,    s.skipped, s.nodes, s.leaves,   s.empty_leaves, s.refs,
              s.largest_leaf, s.depth,   0,       s.build_ms, s.refs,         s.nodes};
    write(&t, sizeof(t));
    const uint64_t sum = hash_;
    main_.write(reinterpret_cast<const char*>(&sum), sizeof(sum));
    main_.close();
    if (!main_) throw Error(target_ + ": writing the octree failed (disk full?)");
  }

 private:
  std::string target_;
  Octree* keep_;  // also kept in memory, when given
  std::ofstream main_, side_;
  uint64_t hash_ = kFnvOffsetBasis;
};

// Parses and checks a file's bytes; the reason it is not a valid octree, or empty.
std::string parseOctree(std::string_view bytes, const MeshView& mesh, const OctreeOptions& options,
                        Octree* out) {
  const std::string head = fileHead(mesh, options);
  if (bytes.size() < head.size() + sizeof(Trailer) + 8) return "too short";
  if (bytes.compare(0, sizeof(kMagic), std::string_view(kMagic, sizeof(kMagic))) != 0)
    return "not an octree file";
  uint64_t stored_sum;
  std::memcpy(&stored_sum, bytes.data() + bytes.size() - 8, 8);
  if (fnv1a64(bytes.data(), bytes.size() - 8) != stored_sum) return "checksum mismatch";
  uint32_t version;
  std::memcpy(&version, bytes.data() + sizeof(kMagic), 4);
  if (version != kOctreeVersion) return "format version " + std::to_string(version);
  if (bytes.compare(0, head.size(), head) != 0) return "made for another mesh or other options";
  Trailer t;
  std::memcpy(&t, bytes.data() + bytes.size() - 8 - sizeof(Trailer), sizeof(Trailer));
  const uint64_t body = bytes.size() - 8 - sizeof(Trailer) - head.size();
  if (t.ref_count > body / 4 || t.node_count > body / sizeof(OctreeNode) ||
      t.ref_count * 4 + t.node_count * sizeof(OctreeNode) != body || t.node_count == 0)
    return "inconsistent sizes";
  Octree tree;
  tree.options = options;
  tree.refs.resize(size_t(t.ref_count));
  tree.nodes.resize(size_t(t.node_count));
  const char* p = bytes.data() + head.size();
  if (t.ref_count) std::memcpy(tree.refs.data(), p, size_t(t.ref_count) * 4);
  std::memcpy(tree.nodes.data(), p + t.ref_count * 4, size_t(t.node_count) * sizeof(OctreeNode));
  for (uint32_t r : tree.refs)
    if (r >= mesh.triangle_count) return "a reference past the triangles";
  if (std::string why = checkOctreeNodes(tree.nodes, t.ref_count, options.max_level); !why.empty())
    return why;
  tree.stats = {t.triangles, t.skipped,      t.nodes, t.leaves,  t.empty_leaves,
                t.refs,      t.largest_leaf, t.depth, t.build_ms};
  if (tree.stats.triangles != mesh.triangle_count || tree.stats.nodes != t.node_count ||
      tree.stats.refs != t.ref_count)
    return "inconsistent stats";
  *out = std::move(tree);
  return {};
}

}  // namespace

std::string parseOctreeFile(std::string_view bytes, const MeshView& mesh,
                            const OctreeOptions& options, Octree* out) {
  return parseOctree(bytes, mesh, options, out);
}

std::string checkOctreeNodes(const std::vector<OctreeNode>& nodes, uint64_t ref_count,
                             uint32_t max_level) {
  if (nodes.empty()) return "no nodes";
  // A tree: every node but the root (the last) is the child of exactly one node, so walking it
  // visits each node once.
  std::vector<uint8_t> parents(nodes.size(), 0);
  for (const OctreeNode& n : nodes)
    if (!n.leaf() && uint64_t(n.first_child) + 8 <= nodes.size())
      for (uint32_t c = 0; c < 8; ++c)
        if (++parents[n.first_child + c] > 1) return "a node with two parents";
  for (size_t i = 0; i + 1 < parents.size(); ++i)
    if (parents[i] != 1) return "a node outside the tree";
  if (parents.back() != 0) return "a root with a parent";
  for (size_t i = 0; i < nodes.size(); ++i) {
    const OctreeNode& n = nodes[i];
    if (!finite(n.lo) || !(n.size > 0.0f) || !std::isfinite(n.size) || n.level > max_level)
      return "a bad node";
    if (n.leaf()) {
      if (uint64_t(n.first_ref) + n.ref_count > ref_count) return "a leaf past the references";
    } else if (uint64_t(n.first_child) + 8 > i) {
      return "a node whose children do not precede it";
    }
  }
  return {};
}

bool triangleOverlapsBox(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                         const glm::vec3& lo, const glm::vec3& hi) {
  const glm::vec3 center = 0.5f * (lo + hi), h = 0.5f * (hi - lo);
  const glm::vec3 v0 = a - center, v1 = b - center, v2 = c - center;
  // The box's faces.
  for (int k = 0; k < 3; ++k) {
    const float mn = std::min(v0[k], std::min(v1[k], v2[k]));
    const float mx = std::max(v0[k], std::max(v1[k], v2[k]));
    if (mn > h[k] || mx < -h[k]) return false;
  }
  // The triangle's plane, then the nine edge-by-axis cross products.
  const glm::vec3 e[3] = {v1 - v0, v2 - v1, v0 - v2};
  const glm::vec3 normal = glm::cross(e[0], e[1]);
  if (separatedOn(normal, v0, v1, v2, h)) return false;
  for (const glm::vec3& edge : e)
    for (int k = 0; k < 3; ++k) {
      glm::vec3 unit(0.0f);
      unit[k] = 1.0f;
      const glm::vec3 axis = glm::cross(unit, edge);
      if (axis == glm::vec3(0.0f)) continue;
      if (separatedOn(axis, v0, v1, v2, h)) return false;
    }
  return true;
}

OctreeStats buildOctree(const MeshView& mesh, const OctreeOptions& options, OctreeSink& sink,
                        const std::function<void(double)>& progress) {
  checkOptions(options);
  return Builder(mesh, options, sink, progress).run();
}

Octree buildOctree(const MeshView& mesh, const OctreeOptions& options,
                   const std::function<void(double)>& progress) {
  Octree tree;
  tree.options = options;
  MemorySink sink(tree);
  tree.stats = buildOctree(mesh, options, sink, progress);
  return tree;
}

void frontToBackLeaves(const Octree& tree, bool perspective, const glm::vec3& eye,
                       const glm::vec3& forward, std::vector<uint32_t>& leaves) {
  leaves.clear();
  if (tree.empty()) return;
  // Children in Morton order; the viewer's octant o first, then the three children sharing a
  // face with it (one bit flipped), the three sharing an edge (two bits), the opposite one. A
  // child can only hide a child whose differing bits include all of its own, so this order
  // lists every child before those it can hide.
  static constexpr uint32_t kFlip[8] = {0, 1, 2, 4, 3, 5, 6, 7};
  std::vector<uint32_t> stack{tree.root()};
  while (!stack.empty()) {
    const uint32_t n = stack.back();
    stack.pop_back();
    const OctreeNode& node = tree.nodes[n];
    if (node.leaf()) {
      if (node.ref_count) leaves.push_back(n);
      continue;
    }
    const glm::vec3 c = node.center();
    uint32_t o = 0;
    for (int k = 0; k < 3; ++k) {
      // Orthographic: the viewer is at infinity against the view direction.
      const bool upper = perspective ? eye[k] > c[k] : forward[k] < 0.0f;
      if (upper) o |= 1u << k;
    }
    for (int i = 7; i >= 0; --i) stack.push_back(node.first_child + (o ^ kFlip[i]));
  }
}

std::string defaultOctreeCacheDir() { return userCacheDir("octree").string(); }

std::string octreeCachePath(const MeshView& mesh, const OctreeOptions& options,
                            const std::string& cache_dir) {
  char name[32];
  std::snprintf(name, sizeof(name), "%016llx.octree", (unsigned long long)cacheKey(mesh, options));
  const std::string dir = cache_dir.empty() ? defaultOctreeCacheDir() : cache_dir;
  return (fs::path(dir) / name).string();
}

Octree readOctreeFile(const std::string& path, const MeshView& mesh, const OctreeOptions& options) {
  checkOptions(options);
  const std::optional<std::string> bytes = readCacheFile(path, kMaxOctreeFileBytes);
  if (!bytes)
    throw Error(path + ": cannot read the octree file (missing, unreadable or not a regular file)");
  Octree tree;
  const std::string why = parseOctree(*bytes, mesh, options, &tree);
  if (!why.empty()) throw Error(path + ": not a valid octree of this mesh: " + why);
  return tree;
}

OctreeStats writeOctreeFile(const std::string& path, const MeshView& mesh,
                            const OctreeOptions& options,
                            const std::function<void(double)>& progress, Octree* keep) {
  checkOptions(options);
  OctreeStats stats;
  writeCacheFileAtomically(path, "octree", [&](const fs::path& temp) {
    // The nodes wait in a side file until the refs are written; registered like the main
    // temporary file, so an interrupted build leaves neither.
    const ScopedTemporaryFile side(temp.string() + ".nodes");
    if (keep) *keep = Octree{};
    FileSink sink(temp, side.path(), path, keep);
    const std::string head = fileHead(mesh, options);
    sink.write(head.data(), head.size());
    stats = buildOctree(mesh, options, sink, progress);
    sink.finish(side.path(), stats);
  });
  return stats;
}

Octree loadOrBuildOctree(const MeshView& mesh, const OctreeOptions& options,
                         const std::string& cache_dir, bool* from_cache,
                         const std::function<void(double)>& progress) {
  checkOptions(options);
  const std::string path = octreeCachePath(mesh, options, cache_dir);
  removeStaleTemporaries(fs::path(path).parent_path());
  if (const std::optional<std::string> bytes = readCacheFile(path, kMaxOctreeFileBytes)) {
    Octree tree;
    if (parseOctree(*bytes, mesh, options, &tree).empty()) {
      if (from_cache) *from_cache = true;
      return tree;
    }
  }
  if (from_cache) *from_cache = false;
  try {
    std::error_code ec;
    fs::create_directories(fs::path(path).parent_path(), ec);
    Octree tree;
    tree.stats = writeOctreeFile(path, mesh, options, progress, &tree);
    tree.options = options;
    return tree;
  } catch (const OctreeRefused&) {
    throw;  // it would be refused in memory too
  } catch (const Error& e) {
    std::cerr << "strata: warning: " << printableMessage(e.what())
              << " (building the octree in memory)\n";
  }
  return buildOctree(mesh, options, progress);
}

}  // namespace strata
