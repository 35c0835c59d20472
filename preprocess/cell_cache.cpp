// The cache file of the convex-cell preprocessing (decomposition + grid + pairs).
//
// Layout (host byte order, no padding):
//   "STRATACELLS" (11 bytes), u32 format version, u64 key,
//   u32 mode, u32 max_cell_triangles, u64 triangle count, u64 vertex count,
//   u64 n, u32 cell_begin[n], u64 m, u32 triangle_order[m], u64 l, u32 cell_leader[l],
//   i32 dims[3], f32 origin[3], f32 cell_size[3], u32 unpaired,
//   u64 p, p x { u32 a, u32 b, u32 separable, f32 n[3], f32 d },
//   f64 decompose_seconds, f64 pairs_seconds,
//   u64 checksum (FNV-1a 64 of every byte before it).
// The key is FNV-1a 64 of the format version, the mesh's position and index bytes, the mode and
// max_cell_triangles. A file that fails any check is rebuilt and replaced, never trusted.
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string_view>

#include "preprocess/convex_cells.h"
#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/core/hash.h"
#include "strata/error.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

// 2: convex meshes stay one cell; 3: tolerance; 4: coincident triangles grouped (cell_leader);
// 5: the pair bound (unpaired)
constexpr uint32_t kCellCacheVersion = 5;
constexpr size_t kMaxCellCacheBytes = size_t(1) << 32;
constexpr char kMagic[11] = {'S', 'T', 'R', 'A', 'T', 'A', 'C', 'E', 'L', 'L', 'S'};
uint64_t cacheKey(const MeshView& mesh, const DecomposeOptions& options) {
  const uint32_t opts[2] = {uint32_t(options.mode), options.max_cell_triangles};
  return meshCacheKey("strata-cells", kCellCacheVersion, mesh, opts);
}

class Writer {
 public:
  template <class T>
  void put(const T& v) {
    const size_t n = buf_.size();
    buf_.resize(n + sizeof(T));
    std::memcpy(buf_.data() + n, &v, sizeof(T));
  }
  template <class T>
  void array(const std::vector<T>& v) {
    put(uint64_t(v.size()));
    const size_t n = buf_.size();
    buf_.resize(n + v.size() * sizeof(T));
    if (!v.empty()) std::memcpy(buf_.data() + n, v.data(), v.size() * sizeof(T));
  }
  void raw(const void* p, size_t size) {
    const size_t n = buf_.size();
    buf_.resize(n + size);
    std::memcpy(buf_.data() + n, p, size);
  }
  std::vector<char>& bytes() { return buf_; }

 private:
  std::vector<char> buf_;
};

class Reader {
 public:
  Reader(const char* p, size_t size) : p_(p), size_(size) {}
  template <class T>
  bool get(T* v) {
    if (size_ - pos_ < sizeof(T)) return false;
    std::memcpy(v, p_ + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  template <class T>
  bool array(std::vector<T>* v, uint64_t max_count) {
    uint64_t n;
    if (!get(&n) || n > max_count || n > (size_ - pos_) / sizeof(T)) return false;
    v->resize(size_t(n));
    if (n) std::memcpy(v->data(), p_ + pos_, size_t(n) * sizeof(T));
    pos_ += size_t(n) * sizeof(T);
    return true;
  }
  size_t pos() const { return pos_; }

 private:
  const char* p_;
  size_t size_, pos_ = 0;
};

std::vector<char> serialize(const CellPreprocess& r, uint64_t key, const MeshView& mesh,
                            const DecomposeOptions& options) {
  Writer w;
  w.raw(kMagic, sizeof(kMagic));
  w.put(kCellCacheVersion);
  w.put(key);
  w.put(uint32_t(options.mode));
  w.put(options.max_cell_triangles);
  w.put(uint64_t(mesh.triangle_count));
  w.put(uint64_t(mesh.vertex_count));
  w.array(r.cells.cell_begin);
  w.array(r.cells.triangle_order);
  w.array(r.cells.cell_leader);
  for (int k = 0; k < 3; ++k) w.put(int32_t(r.grid.dims[k]));
  for (int k = 0; k < 3; ++k) w.put(r.grid.origin[k]);
  for (int k = 0; k < 3; ++k) w.put(r.grid.cell_size[k]);
  w.put(uint32_t(r.unpaired ? 1 : 0));
  w.put(uint64_t(r.pairs.size()));
  for (const CellPair& p : r.pairs) {
    w.put(p.a);
    w.put(p.b);
    w.put(uint32_t(p.separable ? 1 : 0));
    for (int k = 0; k < 3; ++k) w.put(p.plane.n[k]);
    w.put(p.plane.d);
  }
  w.put(r.decompose_seconds);
  w.put(r.pairs_seconds);
  const uint64_t sum = fnv1a64(w.bytes().data(), w.bytes().size());
  w.put(sum);
  return std::move(w.bytes());
}

// Parses and validates a cache file's bytes; false on any mismatch or inconsistency.
bool deserialize(std::string_view bytes, uint64_t key, const MeshView& mesh,
                 const DecomposeOptions& options, CellPreprocess* out) {
  if (bytes.size() < sizeof(kMagic) + 8) return false;
  uint64_t stored_sum;
  std::memcpy(&stored_sum, bytes.data() + bytes.size() - 8, 8);
  if (fnv1a64(bytes.data(), bytes.size() - 8) != stored_sum) return false;
  if (std::memcmp(bytes.data(), kMagic, sizeof(kMagic)) != 0) return false;
  Reader r(bytes.data() + sizeof(kMagic), bytes.size() - sizeof(kMagic) - 8);
  uint32_t version, mode, max_tris;
  uint64_t file_key, tris, verts;
  if (!r.get(&version) || version != kCellCacheVersion) return false;
  if (!r.get(&file_key) || file_key != key) return false;
  if (!r.get(&mode) || mode != uint32_t(options.mode)) return false;
  if (!r.get(&max_tris) || max_tris != options.max_cell_triangles) return false;
  if (!r.get(&tris) || tris != mesh.triangle_count) return false;
  if (!r.get(&verts) || verts != mesh.vertex_count) return false;
  CellPreprocess res;
  res.cells.mode = options.mode;
  if (!r.array(&res.cells.cell_begin, tris + 1)) return false;
  if (!r.array(&res.cells.triangle_order, tris) || res.cells.triangle_order.size() != tris)
    return false;
  // Offsets: 0 .. tris, strictly increasing (no empty cells).
  const std::vector<uint32_t>& cb = res.cells.cell_begin;
  if (cb.empty() || cb.front() != 0 || cb.back() != tris) return false;
  for (size_t c = 0; c + 1 < cb.size(); ++c)
    if (cb[c] >= cb[c + 1]) return false;
  // Leaders: none, or every cell's; a class is its first cell and the one-triangle cells right
  // after it.
  if (!r.array(&res.cells.cell_leader, cb.size() - 1)) return false;
  const std::vector<uint32_t>& lead = res.cells.cell_leader;
  if (!lead.empty() && lead.size() != cb.size() - 1) return false;
  for (size_t c = 0; c < lead.size(); ++c) {
    if (lead[c] == c) continue;
    if (lead[c] > c || lead[lead[c]] != lead[c] || cb[c + 1] - cb[c] != 1 ||
        cb[lead[c] + 1] - cb[lead[c]] != 1 || (c - 1 != lead[c] && lead[c - 1] != lead[c]))
      return false;
  }
  // The order: a permutation.
  std::vector<uint8_t> seen(size_t(tris), 0);
  for (uint32_t t : res.cells.triangle_order) {
    if (t >= tris || seen[t]) return false;
    seen[t] = 1;
  }
  int32_t dims[3];
  for (int k = 0; k < 3; ++k)
    if (!r.get(&dims[k]) || dims[k] < 0 || dims[k] > 4096) return false;
  for (int k = 0; k < 3; ++k) res.grid.dims[k] = dims[k];
  for (int k = 0; k < 3; ++k)
    if (!r.get(&res.grid.origin[k]) || !std::isfinite(res.grid.origin[k])) return false;
  for (int k = 0; k < 3; ++k)
    if (!r.get(&res.grid.cell_size[k]) || !std::isfinite(res.grid.cell_size[k])) return false;
  uint32_t unpaired;
  if (!r.get(&unpaired) || unpaired > 1) return false;
  res.unpaired = unpaired == 1;
  uint64_t n_pairs;
  const uint64_t cells = res.cells.cellCount();
  if (!r.get(&n_pairs) || n_pairs > bytes.size() / 28 ||
      n_pairs > cellPairBound(uint32_t(cells)) || (res.unpaired && n_pairs > 0))
    return false;
  res.pairs.resize(size_t(n_pairs));
  uint64_t prev = 0;
  for (size_t i = 0; i < n_pairs; ++i) {
    CellPair& p = res.pairs[i];
    uint32_t sep;
    if (!r.get(&p.a) || !r.get(&p.b) || !r.get(&sep) || sep > 1) return false;
    for (int k = 0; k < 3; ++k)
      if (!r.get(&p.plane.n[k]) || !std::isfinite(p.plane.n[k])) return false;
    if (!r.get(&p.plane.d) || !std::isfinite(p.plane.d)) return false;
    p.separable = sep == 1;
    if (p.a >= p.b || p.b >= cells || res.cells.isCopy(p.a) || res.cells.isCopy(p.b))
      return false;
    const uint64_t k = (uint64_t(p.a) << 32) | p.b;
    if (i > 0 && k <= prev) return false;
    prev = k;
  }
  if (!r.get(&res.decompose_seconds) || !r.get(&res.pairs_seconds)) return false;
  if (r.pos() != bytes.size() - sizeof(kMagic) - 8) return false;
  *out = std::move(res);
  return true;
}

}  // namespace

std::vector<char> serializeCellCache(const CellPreprocess& result, const MeshView& mesh,
                                     const DecomposeOptions& options) {
  return serialize(result, cacheKey(mesh, options), mesh, options);
}

bool parseCellCache(std::string_view bytes, const MeshView& mesh, const DecomposeOptions& options,
                    CellPreprocess* out) {
  return deserialize(bytes, cacheKey(mesh, options), mesh, options, out);
}

std::string defaultCellCacheDir() { return userCacheDir("cells").string(); }

std::string cellCachePath(const MeshView& mesh, const DecomposeOptions& options,
                          const std::string& cache_dir) {
  char name[32];
  std::snprintf(name, sizeof(name), "%016llx.cells", (unsigned long long)cacheKey(mesh, options));
  const std::string dir = cache_dir.empty() ? defaultCellCacheDir() : cache_dir;
  return (fs::path(dir) / name).string();
}

CellPreprocess loadOrBuildCells(const MeshView& mesh, const DecomposeOptions& options,
                                const std::string& cache_dir, bool* from_cache) {
  const uint64_t key = cacheKey(mesh, options);
  const std::string path = cellCachePath(mesh, options, cache_dir);
  removeStaleTemporaries(std::filesystem::path(path).parent_path());
  CellPreprocess result;
  const std::optional<std::string> bytes = readCacheFile(path, kMaxCellCacheBytes);
  if (bytes && deserialize(*bytes, key, mesh, options, &result)) {
    if (from_cache) *from_cache = true;
    return result;
  }
  if (from_cache) *from_cache = false;
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  result.cells = decomposeConvexCells(mesh, options);
  const auto t1 = Clock::now();
  result.unpaired = !findCellPairs(mesh, result.cells, &result.grid, &result.pairs);
  const auto t2 = Clock::now();
  result.decompose_seconds = std::chrono::duration<double>(t1 - t0).count();
  result.pairs_seconds = std::chrono::duration<double>(t2 - t1).count();
  try {
    std::error_code ec;
    fs::create_directories(fs::path(path).parent_path(), ec);
    const std::vector<char> file = serialize(result, key, mesh, options);
    writeCacheFileAtomically(path, "cell cache", std::string_view(file.data(), file.size()));
  } catch (const Error& e) {
    std::cerr << "strata: warning: " << printableMessage(e.what()) << "\n";
  }
  return result;
}

}  // namespace strata
