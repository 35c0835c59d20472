// loadSceneFile: format dispatch, and what the readers share: polygon triangulation, the polygon
// soup a reader fills, and the text scanning of the ascii formats. The readers: obj_reader.cpp
// (OBJ + MTL), off_reader.cpp, stl_reader.cpp, ply_reader.cpp, gltf_loader.cpp, gltf1_loader.cpp.
//
// OpenMesh's readers were the first choice for OBJ/PLY/OFF/STL, but each one changes or loses
// geometry without a trace on inputs this loader must handle (non-finite coordinates, repeated
// corners, truncated files, corrupt counts); the reasons are given at each reader. These
// formats are simple enough to read directly, with every count checked against the data.
#include "preprocess/mesh_loader.h"

#include "preprocess/gltf1_loader.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <new>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "preprocess/loader_internal.h"
#include "preprocess/octree_scene.h"
#include "preprocess/texture_loader.h"
#include "preprocess/validate.h"

namespace strata {
namespace loader {

void fail(const std::string& path, const std::string& problem) {
  std::string line = path + ": " + problem;
  std::replace(line.begin(), line.end(), '\n', ' ');
  std::replace(line.begin(), line.end(), '\r', ' ');
  throw Error(line);
}

bool parseNumber(std::string_view word, double& value) {
  if (!word.empty() && word[0] == '+') word.remove_prefix(1);
  if (word.empty()) return false;
  const char* end = word.data() + word.size();
  const auto [stop, ec] = std::from_chars(word.data(), end, value);
  if (stop != end) return false;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves `value` alone here; the number is real, only too large or too small.
    const size_t e = word.find_first_of("eE");
    const bool tiny = e != std::string_view::npos && e + 1 < word.size() && word[e + 1] == '-';
    const double magnitude = tiny ? 0.0 : std::numeric_limits<double>::infinity();
    value = word[0] == '-' ? -magnitude : magnitude;
    return true;
  }
  return ec == std::errc();
}

std::string firstLine(const std::string& text) {
  size_t begin = text.find_first_not_of(" \t\r\n");
  if (begin == std::string::npos) return "unknown error";
  size_t end = text.find_first_of("\r\n", begin);
  std::string line = text.substr(begin, end == std::string::npos ? std::string::npos : end - begin);
  while (!line.empty() && std::isspace(static_cast<unsigned char>(line.back()))) line.pop_back();
  return line;
}

std::string fileStem(const std::string& path) {
  return std::filesystem::path(path).stem().string();
}

bool isAbsoluteReference(const std::string& uri) {
  if (uri.empty()) return false;
  if (uri[0] == '/' || uri[0] == '\\') return true;
  const size_t colon = uri.find(':');
  return colon != std::string::npos && colon < uri.find_first_of("/\\");
}

bool isInsideFolder(const std::filesystem::path& folder, const std::filesystem::path& target) {
  auto f = folder.begin(), t = target.begin();
  for (; f != folder.end(); ++f, ++t) {
    if (t == target.end() || *f != *t) return false;
  }
  return true;
}

Scene singleMeshScene(const std::string& path, Mesh mesh, LoadReport report) {
  Scene scene;
  scene.source = path;
  const std::string stem = fileStem(path);
  mesh.name = stem;
  mesh.material = 0;
  scene.meshes.push_back(std::move(mesh));
  Material material;
  material.name = "default";
  scene.materials.push_back(material);
  Instance instance;
  instance.mesh = 0;
  instance.object_id = 0;
  instance.name = stem;
  scene.instances.push_back(instance);
  scene.report = std::move(report);
  validateScene(scene);
  return scene;
}

// ---------------------------------------------------------------------------------------------
// Polygon triangulation

namespace {

// Polygons with more corners than this are fanned rather than ear clipped: ear clipping costs
// up to cubic time in the corner count, and large faces (caps of scanned or CAD data) are
// nearly always convex, where the fan is exact.
constexpr size_t kMaxEarClippingCorners = 256;

double cross2(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

void appendFan(const uint32_t* corners, size_t count, std::vector<uint32_t>& out) {
  for (size_t i = 1; i + 1 < count; ++i) {
    out.push_back(corners[0]);
    out.push_back(corners[i]);
    out.push_back(corners[i + 1]);
  }
}

// Ear clipping on the polygon projected to 2D. `orientation` is the sign of the projected
// polygon's area, so "convex corner" means a turn with that sign.
void appendEarClipped(const std::vector<glm::dvec2>& p, const uint32_t* corners, double orientation,
                      std::vector<uint32_t>& out) {
  std::vector<size_t> remaining(p.size());
  for (size_t i = 0; i < p.size(); ++i) remaining[i] = i;

  auto isEar = [&](size_t k) {
    const size_t n = remaining.size();
    const size_t ia = remaining[(k + n - 1) % n], ib = remaining[k], ic = remaining[(k + 1) % n];
    if (cross2(p[ia], p[ib], p[ic]) * orientation <= 0.0) return false;  // reflex or flat
    for (size_t j = 0; j < n; ++j) {
      const size_t q = remaining[j];
      if (q == ia || q == ib || q == ic) continue;
      // Corners at the ear's own positions are the two ends of a bridge edge, which polygons
      // with holes use (OBJ/concave_polygon.obj); they touch the ear without blocking it.
      if (p[q] == p[ia] || p[q] == p[ib] || p[q] == p[ic]) continue;
      // A remaining corner inside (or on the boundary of) the candidate ear blocks it.
      if (cross2(p[ia], p[ib], p[q]) * orientation >= 0.0 &&
          cross2(p[ib], p[ic], p[q]) * orientation >= 0.0 &&
          cross2(p[ic], p[ia], p[q]) * orientation >= 0.0)
        return false;
    }
    return true;
  };

  size_t start = 0;  // resume the search where the last ear was cut: ears tend to be adjacent
  while (remaining.size() > 3) {
    const size_t n = remaining.size();
    size_t ear = n;
    for (size_t step = 0; step < n; ++step) {
      const size_t k = (start + step) % n;
      if (isEar(k)) {
        ear = k;
        break;
      }
    }
    if (ear == n) break;  // self-intersecting or numerically flat: fan what is left
    out.push_back(corners[remaining[(ear + n - 1) % n]]);
    out.push_back(corners[remaining[ear]]);
    out.push_back(corners[remaining[(ear + 1) % n]]);
    remaining.erase(remaining.begin() + static_cast<std::ptrdiff_t>(ear));
    start = ear == 0 ? 0 : ear - 1;
  }
  for (size_t i = 1; i + 1 < remaining.size(); ++i) {
    out.push_back(corners[remaining[0]]);
    out.push_back(corners[remaining[i]]);
    out.push_back(corners[remaining[i + 1]]);
  }
}

}  // namespace

size_t triangulatePolygon(const std::vector<glm::vec3>& positions, const uint32_t* corners,
                          size_t count, std::vector<uint32_t>& out) {
  if (count < 3) return 0;
  if (count == 3) {
    out.insert(out.end(), corners, corners + 3);
    return 1;
  }
  const size_t triangles = count - 2;
  bool placeable = count <= kMaxEarClippingCorners;
  for (size_t i = 0; placeable && i < count; ++i) {
    placeable = corners[i] < positions.size() && std::isfinite(positions[corners[i]].x) &&
                std::isfinite(positions[corners[i]].y) && std::isfinite(positions[corners[i]].z);
  }
  if (!placeable) {
    appendFan(corners, count, out);
    return triangles;
  }

  // Newell's normal is robust for non-planar polygons; project along its largest axis.
  glm::dvec3 normal(0.0);
  for (size_t i = 0; i < count; ++i) {
    const glm::dvec3 a(positions[corners[i]]);
    const glm::dvec3 b(positions[corners[(i + 1) % count]]);
    normal +=
        glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }
  const glm::dvec3 mag = glm::abs(normal);
  const int drop = (mag.x >= mag.y && mag.x >= mag.z) ? 0 : (mag.y >= mag.z ? 1 : 2);
  const int u = (drop + 1) % 3, v = (drop + 2) % 3;
  std::vector<glm::dvec2> p(count);
  double area2 = 0.0;
  for (size_t i = 0; i < count; ++i) {
    const glm::dvec3 q(positions[corners[i]]);
    p[i] = glm::dvec2(q[u], q[v]);
  }
  for (size_t i = 0; i < count; ++i) {
    const glm::dvec2& a = p[i];
    const glm::dvec2& b = p[(i + 1) % count];
    area2 += a.x * b.y - a.y * b.x;
  }
  if (area2 == 0.0 || !std::isfinite(area2)) {
    appendFan(corners, count, out);  // zero-area polygon: validation will count its triangles
    return triangles;
  }
  const double orientation = area2 > 0.0 ? 1.0 : -1.0;

  bool convex = true;
  for (size_t i = 0; convex && i < count; ++i) {
    convex = cross2(p[(i + count - 1) % count], p[i], p[(i + 1) % count]) * orientation > 0.0;
  }
  if (convex) {
    appendFan(corners, count, out);
  } else {
    appendEarClipped(p, corners, orientation, out);
  }
  return triangles;
}

// ---------------------------------------------------------------------------------------------
// Polygon soup: what a reader found, before triangulation

namespace {

uint32_t toIndex(int64_t v) {
  // Out-of-range stays out of range: validation counts it instead of wrapping it into range.
  return v < 0 || v > static_cast<int64_t>(UINT32_MAX) ? UINT32_MAX : static_cast<uint32_t>(v);
}

// The mesh vertex of every face corner. With per-corner texture coordinates (OBJ), a position
// whose corners disagree on the UV (a seam) is split into one vertex per distinct UV, so that
// Mesh::texcoords can hold one UV per vertex; `mesh` grows accordingly. Otherwise corners map to
// positions one to one and per-vertex UVs (OFF) are taken as they are.
std::vector<uint32_t> cornerVertices(PolygonSoup& soup, Mesh& mesh) {
  std::vector<uint32_t> corner_vertex(soup.corners.size());
  if (soup.corner_texcoords.empty()) {
    for (size_t c = 0; c < soup.corners.size(); ++c) corner_vertex[c] = toIndex(soup.corners[c]);
    if (!soup.vertex_texcoords.empty()) {
      soup.vertex_texcoords.resize(mesh.positions.size());
      mesh.texcoords = std::move(soup.vertex_texcoords);
    }
    return corner_vertex;
  }

  struct Key {
    uint32_t vertex;
    float u, v;
    bool operator==(const Key& o) const { return vertex == o.vertex && u == o.u && v == o.v; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint32_t ub, vb;
      std::memcpy(&ub, &k.u, 4);
      std::memcpy(&vb, &k.v, 4);
      return std::hash<uint64_t>()((uint64_t(k.vertex) << 32) ^ (uint64_t(ub) * 0x9E3779B1u) ^ vb);
    }
  };
  std::unordered_map<Key, uint32_t, KeyHash> split;
  mesh.texcoords.assign(mesh.positions.size(), glm::vec2(0.0f));
  std::vector<bool> assigned(mesh.positions.size(), false);
  for (size_t f = 0; f < soup.faceCount(); ++f) {
    for (size_t c = soup.face_begin[f]; c < soup.face_begin[f + 1]; ++c) {
      const uint32_t vi = toIndex(soup.corners[c]);
      corner_vertex[c] = vi;
      if (vi >= assigned.size() || !soup.face_has_texcoords[f]) continue;
      const glm::vec2 uv = soup.corner_texcoords[c];
      if (!assigned[vi]) {
        assigned[vi] = true;
        mesh.texcoords[vi] = uv;
      } else if (mesh.texcoords[vi] != uv) {
        auto [it, inserted] =
            split.try_emplace(Key{vi, uv.x, uv.y}, static_cast<uint32_t>(mesh.positions.size()));
        if (inserted) {
          const glm::vec3 position = mesh.positions[vi];  // copy: push_back may reallocate
          mesh.positions.push_back(position);
          mesh.texcoords.push_back(uv);
        }
        corner_vertex[c] = it->second;
      }
    }
  }
  return corner_vertex;
}

// The shortest cycle (of at least three corners) that `corners` repeats whole, or `n` when it
// is not periodic. A face that lists the same loop several times (assimp's
// OBJ/box_longline.obj: a quad written out 234 times) would otherwise be triangulated into as
// many stacked copies, which a transparency renderer would draw as that many layers.
size_t repeatedCycleLength(const uint32_t* corners, size_t n) {
  for (size_t m = 3; m <= n / 2; ++m) {
    if (n % m != 0) continue;
    bool periodic = true;
    for (size_t i = m; periodic && i < n; ++i) periodic = corners[i] == corners[i - m];
    if (periodic) return m;
  }
  return n;
}

}  // namespace

Scene sceneFromSoup(const std::string& path, PolygonSoup& soup, LoadReport report,
                    std::vector<Material> materials) {
  Mesh mesh;
  mesh.positions = std::move(soup.positions);
  const std::vector<uint32_t> corner_vertex = cornerVertices(soup, mesh);
  const size_t groups = std::max<size_t>(1, materials.size());
  std::vector<std::vector<uint32_t>> group_indices(groups);
  std::vector<bool> group_has_texcoords(groups, false);
  if (groups == 1) group_indices[0].reserve(soup.corners.size() * 3 / 2);
  size_t repeated_loops = 0;
  for (size_t f = 0; f < soup.faceCount(); ++f) {
    const size_t g = soup.face_group.empty() ? 0 : std::min<size_t>(soup.face_group[f], groups - 1);
    const size_t begin = soup.face_begin[f];
    size_t n = soup.face_begin[f + 1] - begin;
    if (n < 3) {
      ++report.dropped_degenerate;  // a face with fewer than three corners has no area
      continue;
    }
    if (soup.face_has_texcoords[f]) group_has_texcoords[g] = true;
    if (n >= 6) {
      const size_t cycle = repeatedCycleLength(corner_vertex.data() + begin, n);
      if (cycle < n) {
        ++repeated_loops;
        n = cycle;
      }
    }
    if (n > 3) ++report.polygons_triangulated;
    triangulatePolygon(mesh.positions, corner_vertex.data() + begin, n, group_indices[g]);
  }
  if (repeated_loops > 0) {
    report.warnings.push_back(std::to_string(repeated_loops) +
                              " faces list the same corner loop several times; read once");
  }
  if (groups == 1) {
    mesh.indices = std::move(group_indices[0]);
    Scene scene = singleMeshScene(path, std::move(mesh), std::move(report));
    if (!materials.empty()) scene.materials[0] = std::move(materials[0]);
    return scene;
  }

  Scene scene;
  scene.source = path;
  const std::string stem = fileStem(path);
  std::vector<uint32_t> remap(mesh.positions.size(), UINT32_MAX);
  for (size_t g = 0; g < groups; ++g) {
    if (group_indices[g].empty()) continue;
    Mesh part;
    part.name = stem + "/" + materials[g].name;
    part.material = static_cast<uint32_t>(g);
    const bool uv = group_has_texcoords[g] && mesh.texcoords.size() == mesh.positions.size();
    part.indices.reserve(group_indices[g].size());
    for (uint32_t i : group_indices[g]) {
      if (i >= mesh.positions.size()) {
        part.indices.push_back(UINT32_MAX);  // stays out of range: validation counts it
        continue;
      }
      if (remap[i] == UINT32_MAX) {
        remap[i] = static_cast<uint32_t>(part.positions.size());
        part.positions.push_back(mesh.positions[i]);
        if (uv) part.texcoords.push_back(mesh.texcoords[i]);
      }
      part.indices.push_back(remap[i]);
    }
    for (uint32_t i : group_indices[g])
      if (i < remap.size()) remap[i] = UINT32_MAX;  // reset for the next group
    Instance instance;
    instance.mesh = static_cast<uint32_t>(scene.meshes.size());
    instance.object_id = 0;
    instance.name = stem;
    scene.instances.push_back(instance);
    scene.meshes.push_back(std::move(part));
  }
  scene.materials = std::move(materials);
  scene.report = std::move(report);
  validateScene(scene);
  return scene;
}

std::string readWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) fail(path, "cannot open file");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// What separates words; trimmed and nextWord agree on it, so a line that trims to nothing has no
// words (a line of vertical tabs is blank, not a line without a first word).
constexpr const char* kSpace = " \t\r\n\f\v";

std::string_view trimmed(std::string_view s) {
  const size_t b = s.find_first_not_of(kSpace);
  if (b == std::string_view::npos) return {};
  const size_t e = s.find_last_not_of(kSpace);
  return s.substr(b, e - b + 1);
}

// The line of `text` starting at `pos` (without its '\n'); moves `pos` past it.
std::string_view nextLine(const std::string& text, size_t& pos) {
  size_t end = text.find('\n', pos);
  if (end == std::string::npos) end = text.size();
  const std::string_view line = std::string_view(text).substr(pos, end - pos);
  pos = end + 1;
  return line;
}

// Splits off the next whitespace-separated word of `rest`.
std::string_view nextWord(std::string_view& rest) {
  const size_t b = rest.find_first_not_of(kSpace);
  if (b == std::string_view::npos) {
    rest = {};
    return {};
  }
  const size_t e = std::min(rest.find_first_of(kSpace, b), rest.size());
  const std::string_view word = rest.substr(b, e - b);
  rest = rest.substr(e);
  return word;
}

bool parseFloat(std::string_view word, float& value) {
  double d = 0.0;
  if (!parseNumber(word, d)) return false;
  value = toFloat(d);
  return true;
}

bool parseInteger(std::string_view word, int64_t& value) {
  if (!word.empty() && word[0] == '+') word.remove_prefix(1);
  const auto [end, ec] = std::from_chars(word.data(), word.data() + word.size(), value);
  return ec == std::errc() && end == word.data() + word.size() && !word.empty();
}

namespace {

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

}  // namespace
}  // namespace loader

Scene loadSceneFile(const std::string& path) {
  namespace fs = std::filesystem;
  using loader::fail;

  const std::string ext = loader::lowerExtension(path);
  static const char* const kSupported = ".obj, .ply, .off, .stl, .gltf, .glb, .octree";
  if (ext.empty()) fail(path, std::string("no file extension (supported: ") + kSupported + ")");
  if (ext != ".obj" && ext != ".ply" && ext != ".off" && ext != ".stl" && ext != ".gltf" &&
      ext != ".glb" && ext != ".octree") {
    fail(path, "unsupported file extension '" + ext + "' (supported: " + kSupported + ")");
  }

  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) fail(path, "no such file");
  if (!fs::is_regular_file(status)) fail(path, "not a regular file");
  const uintmax_t size = fs::file_size(path, ec);
  if (ec) fail(path, "cannot read file size: " + ec.message());
  if (size == 0) fail(path, "empty file");

  try {
    if (ext == ".gltf" || ext == ".glb") {
      // tinygltf reads glTF 2.0 only; 1.0 (assimp's glTF/ folder) has its own reader.
      if (loader::isGltf1File(path)) return loader::loadGltf1(path);
      return loader::loadGltf(path, ext == ".glb");
    }
    if (ext == ".octree") return loadOctreeScene(path);  // out of core: the triangles stay there
    if (ext == ".ply") return loader::loadPly(path);
    if (ext == ".obj") return loader::loadObj(path);
    if (ext == ".off") return loader::loadOff(path);
    return loader::loadStl(path, size);
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    fail(path, "out of memory while loading");
  } catch (const std::exception& e) {
    fail(path, std::string("unexpected failure while loading: ") + e.what());
  }
}

}  // namespace strata
