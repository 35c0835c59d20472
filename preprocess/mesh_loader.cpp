// loadSceneFile: format dispatch, polygon triangulation and the OBJ (+ MTL), OFF and STL readers.
// PLY lives in ply_reader.cpp, glTF in gltf_loader.cpp.
//
// OpenMesh's readers were the first choice for OBJ/PLY/OFF/STL, but each one changes or loses
// geometry without a trace on inputs this loader must handle (non-finite coordinates, repeated
// corners, truncated files, corrupt counts); the reasons are given at each reader below. These
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

namespace fs = std::filesystem;

// Faces as read, corner indices as the file gave them (0-based, possibly out of range or
// negative), and optional texture coordinates per corner (OBJ) or per vertex (OFF).
struct PolygonSoup {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> vertex_texcoords;  // empty, or sized with positions
  std::vector<int64_t> corners;             // all faces' corners, flattened
  std::vector<size_t> face_begin{0};        // face f spans corners[face_begin[f], face_begin[f+1])
  std::vector<glm::vec2> corner_texcoords;  // empty, or parallel to corners
  std::vector<bool> face_has_texcoords;
  std::vector<uint32_t> face_group;  // empty, or every face's material group (OBJ usemtl)

  size_t faceCount() const { return face_begin.size() - 1; }

  void addFace(const int64_t* first, size_t n) {
    corners.insert(corners.end(), first, first + n);
    face_begin.push_back(corners.size());
    face_has_texcoords.push_back(false);
    if (!corner_texcoords.empty()) corner_texcoords.resize(corners.size());
  }
};

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

// Triangulates the soup into the scene's meshes and validates them. With at most one material
// (every format but OBJ, and OBJ files without usemtl or with one material) the scene is one mesh
// drawn once, as singleMeshScene makes it. With several (OBJ's usemtl), face group g becomes a
// mesh of material g holding only the vertices its triangles use (texture coordinates only when
// one of its faces had them), each mesh drawn by one instance of the same object (object id 0,
// named after the file), so every mesh keeps one material.
Scene sceneFromSoup(const std::string& path, PolygonSoup& soup, LoadReport report,
                    std::vector<Material> materials = {}) {
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

// ---------------------------------------------------------------------------------------------
// OBJ

// ---------------------------------------------------------------------------------------------
// MTL material libraries (OBJ's mtllib / usemtl)
//
// Read per `newmtl NAME` (the rest of the line, trimmed: names may contain spaces):
//   - `Kd r [g b]`: the base colour (one number: grey), clamped to [0, 1];
//   - `d a` (dissolve, opacity; `-halo` skipped) or `Tr t` (transparency, a = 1 - t; `d` wins when
//     both are given): stored in the colour's alpha, clamped to [0, 1]. Material::opacity keeps
//     the scene default kDefaultOpacity, as for every format but glTF's BLEND: real MTL files say
//     `d 1` for surfaces strata exists to show transparent, so `d` cannot replace --alpha's
//     default; an alpha below 1 in the colour is still there for a material system to use;
//   - `map_Kd [options] FILE`: the base colour texture (the texel multiplies Kd, as MTL says).
//     Options: `-clamp on` -> Wrap::Clamp on both axes (`off`: Repeat); `-o`, `-s`, `-t` with one
//     to three numbers, `-mm` with two, `-blendu`, `-blendv`, `-bm`, `-boost`, `-cc`, `-imfchan`,
//     `-texres`, `-type` with one argument are skipped (a warning when -o / -s / -t would move
//     the texture). FILE is the rest of the line (it may contain spaces).
// Other statements (Ka, Ks, Ns, illum, other maps) do not change what strata draws. Keywords are
// matched without regard to case (exporters write both map_Kd and map_kd).
//
// Files: `mtllib` names are relative to the OBJ's folder, map_Kd names to the MTL file's folder;
// backslashes are read as folder separators (Windows exporters write `.\tex.jpg`). A name that is
// absolute or resolves outside the OBJ's folder is refused (Error), as glTF URIs are. `mtllib`
// may list several files; a name with spaces is taken whole when such a file exists, else split.
//
// Missing pieces: a material library that does not exist is a warning (its materials get the
// default colour; assimp's test files have such references). A usemtl name that no library
// defines is a warning and the default colour. A map_Kd image that is missing, corrupt,
// truncated or of absurd size fails the load with an Error naming the OBJ, the material and the
// image: a renderer must not drop a texture silently, and the glTF loader does the same.
// Textures are decoded only for materials that faces use, once per image file.

struct MtlMaterial {
  glm::vec3 kd{0.8f, 0.8f, 0.8f};
  bool has_d = false, has_tr = false;
  float d = 1.0f, tr = 0.0f;
  std::string map_kd;   // as written (folder separators normalised), empty if none
  std::string library;  // the MTL file, for messages
  fs::path library_folder;
  Wrap wrap = Wrap::Repeat;
};

std::string lowerCase(std::string_view word) {
  std::string out(word);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string withForwardSlashes(std::string name) {
  std::replace(name.begin(), name.end(), '\\', '/');
  return name;
}

// Parses the options and file name of a map_Kd line (after the keyword).
void parseMapKd(std::string_view rest, MtlMaterial& m, const std::string& where,
                std::vector<std::string>& warnings) {
  for (;;) {
    std::string_view probe = rest;
    const std::string_view word = nextWord(probe);
    if (word.size() < 2 || word[0] != '-') break;
    double number = 0.0;
    if (parseNumber(word, number)) break;  // "-1.png" is a file name, not an option
    const std::string option = lowerCase(word.substr(1));
    rest = probe;
    if (option == "o" || option == "s" || option == "t") {
      const double neutral = option == "s" ? 1.0 : 0.0;
      bool moves = false;
      for (int k = 0; k < 3; ++k) {
        std::string_view next = rest;
        const std::string_view arg = nextWord(next);
        if (!parseNumber(arg, number)) break;
        moves |= number != neutral;
        rest = next;
      }
      if (moves)
        warnings.push_back(where + ": map_Kd option -" + option + " is not supported; ignored");
    } else if (option == "mm") {
      nextWord(rest);
      nextWord(rest);
    } else if (option == "clamp") {
      const std::string value = lowerCase(nextWord(rest));
      m.wrap = value == "on" ? Wrap::Clamp : Wrap::Repeat;
    } else if (option == "blendu" || option == "blendv" || option == "bm" || option == "boost" ||
               option == "cc" || option == "imfchan" || option == "texres" || option == "type") {
      nextWord(rest);
    } else {
      warnings.push_back(where + ": unknown map_Kd option -" + option + " skipped");
    }
  }
  m.map_kd = withForwardSlashes(std::string(trimmed(rest)));
}

// Reads one MTL file into `library` (first definition of a name wins).
void readMtl(const fs::path& file, const std::string& label,
             std::map<std::string, MtlMaterial>& library, std::vector<std::string>& warnings) {
  const std::string text = readWholeFile(file.string());
  MtlMaterial* current = nullptr;
  MtlMaterial ignored;  // a repeated name's statements land here
  std::string current_name;
  size_t pos = 0;
  while (pos < text.size()) {
    std::string_view rest = nextLine(text, pos);
    const std::string keyword = lowerCase(nextWord(rest));
    if (keyword.empty() || keyword[0] == '#') continue;
    if (keyword == "newmtl") {
      current_name = std::string(trimmed(rest));
      auto [it, inserted] = library.try_emplace(current_name);
      current = inserted ? &it->second : &ignored;
      if (inserted) {
        current->library = label;
        current->library_folder = file.parent_path();
      }
      continue;
    }
    if (current == nullptr) continue;  // statements before the first newmtl
    const std::string where = label + " material '" + current_name + "'";
    if (keyword == "kd") {
      float c[3];
      int read = 0;
      for (; read < 3; ++read) {
        std::string_view next = rest;
        if (!parseFloat(nextWord(next), c[read])) break;
        rest = next;
      }
      if (read == 1) c[1] = c[2] = c[0];
      if ((read == 1 || read == 3) && std::isfinite(c[0]) && std::isfinite(c[1]) &&
          std::isfinite(c[2])) {
        current->kd = glm::clamp(glm::vec3(c[0], c[1], c[2]), glm::vec3(0.0f), glm::vec3(1.0f));
      } else {
        warnings.push_back(where + ": Kd without a readable RGB colour ignored");
      }
    } else if (keyword == "d" || keyword == "tr") {
      std::string_view word = nextWord(rest);
      if (word == "-halo") word = nextWord(rest);
      float value = 0.0f;
      if (!parseFloat(word, value) || !std::isfinite(value)) {
        warnings.push_back(where + ": " + keyword + " without a readable number ignored");
      } else if (keyword == "d") {
        current->has_d = true;
        current->d = std::clamp(value, 0.0f, 1.0f);
      } else {
        current->has_tr = true;
        current->tr = std::clamp(value, 0.0f, 1.0f);
      }
    } else if (keyword == "map_kd") {
      parseMapKd(rest, *current, where, warnings);
    }
  }
}

// The file `name` (relative to `base`) if it may be read: Error when it is absolute or outside
// the model's folder. Does not check that it exists.
fs::path confinedPath(const std::string& obj_path, const fs::path& model_folder,
                      const fs::path& base, const std::string& name, const std::string& what) {
  if (isAbsoluteReference(name))
    fail(obj_path,
         what + " '" + name + "' is absolute; only files in the model's folder may be read");
  std::error_code ec;
  const fs::path target = fs::weakly_canonical(base / name, ec);
  if (ec || !isInsideFolder(model_folder, target))
    fail(obj_path, what + " '" + name + "' resolves outside the model's folder; refused");
  return target;
}

// What loadObj needs from the material libraries for the usemtl names faces use.
struct ObjMaterialSet {
  std::vector<Material> materials;  // one per face group
  std::vector<SceneTexture> textures;
};

ObjMaterialSet resolveObjMaterials(const std::string& obj_path,
                                   const std::vector<std::string>& libraries,
                                   const std::vector<std::string>& group_names,
                                   const std::vector<bool>& group_named,
                                   std::vector<std::string>& warnings) {
  std::error_code ec;
  const fs::path obj_file = fs::absolute(obj_path, ec);
  const fs::path model_folder = fs::weakly_canonical(obj_file.parent_path(), ec);

  std::map<std::string, MtlMaterial> library;
  std::vector<fs::path> read_files;
  for (const std::string& statement : libraries) {
    // The whole statement when it names an existing file (names with spaces), else its words.
    std::vector<std::string> names{withForwardSlashes(statement)};
    if (!fs::is_regular_file(model_folder / names[0], ec) &&
        statement.find_first_of(" \t") != std::string::npos) {
      names.clear();
      std::string_view rest(statement);
      for (std::string_view w = nextWord(rest); !w.empty(); w = nextWord(rest))
        names.push_back(withForwardSlashes(std::string(w)));
    }
    for (const std::string& name : names) {
      const fs::path file =
          confinedPath(obj_path, model_folder, model_folder, name, "material library");
      if (std::find(read_files.begin(), read_files.end(), file) != read_files.end()) continue;
      read_files.push_back(file);
      if (!fs::is_regular_file(file, ec)) {
        warnings.push_back("material library '" + name +
                           "' not found; its materials get the default colour");
        continue;
      }
      readMtl(file, name, library, warnings);
    }
  }

  ObjMaterialSet set;
  std::map<fs::path, int32_t> decoded;  // image file -> Scene::textures index
  size_t undefined = 0;
  for (size_t g = 0; g < group_names.size(); ++g) {
    Material material;
    material.name = group_named[g] ? group_names[g] : "default";
    const auto it = group_named[g] ? library.find(group_names[g]) : library.end();
    if (group_named[g] && it == library.end()) {
      if (++undefined <= 20)
        warnings.push_back("usemtl '" + group_names[g] + "': " +
                           (libraries.empty() ? std::string("the file names no material library")
                                              : std::string("no material library defines it")) +
                           "; default colour used");
    }
    if (it != library.end()) {
      const MtlMaterial& m = it->second;
      const float alpha = m.has_d ? m.d : m.has_tr ? 1.0f - m.tr : 1.0f;
      material.color = glm::vec4(m.kd, alpha);
      if (!m.map_kd.empty()) {
        const std::string what = "material '" + group_names[g] + "' (" + m.library + ") map_Kd";
        const fs::path file =
            confinedPath(obj_path, model_folder, m.library_folder, m.map_kd, what);
        material.base_color_texture = m.map_kd;
        material.sampler.wrap_s = material.sampler.wrap_t = m.wrap;
        auto [slot, inserted] = decoded.try_emplace(file, -1);
        if (inserted) {
          try {
            SceneTexture texture{m.map_kd, loadTextureFile(file.string())};
            slot->second = static_cast<int32_t>(set.textures.size());
            set.textures.push_back(std::move(texture));
          } catch (const Error& e) {
            fail(obj_path, what + ": " + e.what());
          }
        }
        material.texture = slot->second;
      }
    }
    set.materials.push_back(std::move(material));
  }
  if (undefined > 20)
    warnings.push_back(std::to_string(undefined - 20) + " more usemtl names are not defined");
  return set;
}

// ---------------------------------------------------------------------------------------------
// OBJ

// OBJ is read here rather than by OpenMesh's reader, which changes geometry silently: it parses
// coordinates with iostreams, so a `v nan 0 0` line is skipped and every later vertex shifts
// down by one; it removes repeated corners from a face, which breaks polygons with holes joined
// by a bridge edge (assimp's OBJ/concave_polygon.obj); and it discards faces left with fewer
// than three corners without a trace.
//
// Read: `v` (x y z; w and colours ignored), `vt` (u [v]; stored as (u, 1 - v), since OBJ's v
// axis points up and strata's texture coordinate (0, 0) is the image's top-left corner) and `f`
// with corners `v`, `v/vt`, `v/vt/vn` or `v//vn`, indices 1-based or negative (relative to the
// elements read so far); `mtllib` and `usemtl` (names are the rest of the line, trimmed) with the
// MTL rules above: faces of each usemtl material (faces before any usemtl: "default") become one
// mesh of that material. Points (`p`) and lines (`l`) are counted in a warning; other statements
// (groups, smoothing, normals) do not affect the geometry.
Scene loadObj(const std::string& path) {
  const std::string text = readWholeFile(path);
  PolygonSoup soup;
  LoadReport report;
  std::vector<glm::vec2> vt;
  std::vector<int64_t> face;
  std::vector<int64_t> face_vt;    // 0-based texcoord index per corner, -1 when absent
  std::vector<int64_t> corner_vt;  // the same for all faces, resolved once vt is complete
  size_t unreadable_vertices = 0, malformed_corners = 0, points_and_lines = 0;
  // Material groups in order of first use by a face; group g's usemtl name (group_named[g]
  // false: the faces before any usemtl).
  std::vector<std::string> libraries, group_names;
  std::vector<bool> group_named;
  std::map<std::string, uint32_t> named_group;
  int64_t default_group = -1;
  bool in_named = false;  // a usemtl has been seen
  std::string current_name;
  int64_t current_group = -1;  // resolved lazily when the next face comes

  size_t pos = 0;
  while (pos < text.size()) {
    std::string_view rest = nextLine(text, pos);
    const std::string_view keyword = nextWord(rest);
    if (keyword == "v") {
      glm::vec3 p;
      bool readable = true;
      for (int c = 0; c < 3; ++c) readable = parseFloat(nextWord(rest), p[c]) && readable;
      if (!readable) {
        // Keep the slot so that later vertices keep their numbers; validation drops the
        // triangles that use it.
        ++unreadable_vertices;
        p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
      }
      soup.positions.push_back(p);
    } else if (keyword == "vt") {
      glm::vec2 t(0.0f);
      if (!parseFloat(nextWord(rest), t.x)) t.x = std::numeric_limits<float>::quiet_NaN();
      const std::string_view second = nextWord(rest);
      if (!second.empty() && !parseFloat(second, t.y))
        t.y = std::numeric_limits<float>::quiet_NaN();
      t.y = 1.0f - t.y;  // OBJ's v points up; strata's from the image's top row down
      vt.push_back(t);
    } else if (keyword == "f" || keyword == "fo") {
      face.clear();
      face_vt.clear();
      for (std::string_view word = nextWord(rest); !word.empty(); word = nextWord(rest)) {
        const size_t slash = word.find('/');
        int64_t v = 0, t = 0;
        const bool has_t =
            slash != std::string_view::npos && slash + 1 < word.size() && word[slash + 1] != '/';
        if (!parseInteger(word.substr(0, slash), v) || v == 0) {
          ++malformed_corners;
          face.push_back(-1);  // unresolvable: the triangles using it are counted out of range
        } else {
          face.push_back(v > 0 ? v - 1 : static_cast<int64_t>(soup.positions.size()) + v);
        }
        if (has_t) {
          const std::string_view tw = word.substr(slash + 1, word.find('/', slash + 1) - slash - 1);
          if (parseInteger(tw, t) && t != 0)
            face_vt.push_back(t > 0 ? t - 1 : static_cast<int64_t>(vt.size()) + t);
          else
            face_vt.push_back(-1);
        } else {
          face_vt.push_back(-1);
        }
      }
      if (current_group < 0) {
        if (!in_named) {
          if (default_group < 0) {
            default_group = static_cast<int64_t>(group_names.size());
            group_names.emplace_back();
            group_named.push_back(false);
          }
          current_group = default_group;
        } else {
          auto [it, inserted] =
              named_group.try_emplace(current_name, static_cast<uint32_t>(group_names.size()));
          if (inserted) {
            group_names.push_back(current_name);
            group_named.push_back(true);
          }
          current_group = it->second;
        }
      }
      soup.addFace(face.data(), face.size());
      soup.face_group.push_back(static_cast<uint32_t>(current_group));
      corner_vt.insert(corner_vt.end(), face_vt.begin(), face_vt.end());
    } else if (keyword == "p" || keyword == "l") {
      ++points_and_lines;
    } else if (keyword == "usemtl") {
      in_named = true;
      current_name = std::string(trimmed(rest));
      current_group = -1;
    } else if (keyword == "mtllib") {
      const std::string_view name = trimmed(rest);
      if (!name.empty()) libraries.emplace_back(name);
    }
  }

  // Texture coordinates, now that every `vt` is known: a face gets them when all its corners
  // name a valid one.
  if (!vt.empty()) {
    std::vector<glm::vec2> uv;
    for (size_t f = 0; f < soup.faceCount(); ++f) {
      const size_t begin = soup.face_begin[f], end = soup.face_begin[f + 1];
      uv.clear();
      for (size_t c = begin; c < end; ++c) {
        const int64_t t = corner_vt[c];
        if (t < 0 || static_cast<uint64_t>(t) >= vt.size()) break;
        uv.push_back(vt[static_cast<size_t>(t)]);
      }
      if (uv.size() == end - begin && !uv.empty()) {
        soup.corner_texcoords.resize(soup.corners.size());
        std::copy(uv.begin(), uv.end(),
                  soup.corner_texcoords.begin() + static_cast<std::ptrdiff_t>(begin));
        soup.face_has_texcoords[f] = true;
      }
    }
  }

  if (unreadable_vertices > 0)
    report.warnings.push_back(std::to_string(unreadable_vertices) +
                              " vertex lines without three readable numbers (kept as non-finite "
                              "so that later vertices keep their numbers)");
  if (malformed_corners > 0)
    report.warnings.push_back(std::to_string(malformed_corners) +
                              " face corners without a readable vertex index");
  if (points_and_lines > 0)
    report.warnings.push_back(std::to_string(points_and_lines) +
                              " point and line statements skipped (only faces are drawn)");
  if (!in_named) return sceneFromSoup(path, soup, std::move(report));  // no usemtl: as ever

  ObjMaterialSet set =
      resolveObjMaterials(path, libraries, group_names, group_named, report.warnings);
  Scene scene = sceneFromSoup(path, soup, std::move(report), std::move(set.materials));
  scene.textures = std::move(set.textures);
  // A textured material whose faces have no texture coordinates would show one texel all over.
  for (const Mesh& mesh : scene.meshes) {
    Material& material = scene.materials[mesh.material];
    if (material.texture >= 0 && mesh.texcoords.empty()) {
      material.texture = -1;
      material.sampler = Sampler();
      scene.report.warnings.push_back("material '" + material.name +
                                      "': map_Kd, but its faces have no texture coordinates "
                                      "(vt); drawn untextured");
    }
  }
  return scene;
}

// ---------------------------------------------------------------------------------------------
// OFF

// Geomview OFF, ascii: an optional [ST][C][N][4]OFF keyword, counts "vertices faces [edges]"
// (on the keyword's line or the next), one vertex per line (x y z [w], then optional normal,
// colour and, for ST, the texture coordinate last) and one face per line (corner count, corner
// indices, optional colour). `#` starts a comment. Binary and n-dimensional OFF are refused.
//
// OpenMesh's OFF reader is not used: it reads coordinates with iostreams (a "nan" stops the
// stream and every later vertex and face is garbage), still yields the declared number of faces
// when the file is cut short (repeating the last one read), and trusts corner counts, so one
// corrupt count makes it read billions of indices from a failed stream.
Scene loadOff(const std::string& path) {
  const std::string text = readWholeFile(path);
  std::vector<std::string_view> lines;
  size_t pos = 0;
  while (pos < text.size()) {
    std::string_view line = nextLine(text, pos);
    line = trimmed(line.substr(0, line.find('#')));
    if (!line.empty()) lines.push_back(line);
  }
  if (lines.empty()) fail(path, "cannot parse as OFF: no header");

  std::vector<std::string_view> words;
  auto split = [&words](std::string_view line) {
    words.clear();
    for (std::string_view w = nextWord(line); !w.empty(); w = nextWord(line)) words.push_back(w);
  };
  split(lines[0]);
  const std::string keyword(words.empty() ? std::string_view() : words[0]);
  if (keyword.size() < 3 || keyword.compare(keyword.size() - 3, 3, "OFF") != 0)
    fail(path, "cannot parse as OFF: first line is not an OFF header");
  const std::string prefix = keyword.substr(0, keyword.size() - 3);
  if (std::find(words.begin(), words.end(), "BINARY") != words.end())
    fail(path, "binary OFF is not supported");
  if (prefix.find('n') != std::string::npos)
    fail(path, "n-dimensional OFF (" + keyword + ") is not supported");
  const bool homogeneous = prefix.find('4') != std::string::npos;
  const bool has_texcoords = prefix.find("ST") != std::string::npos;

  // Counts follow the keyword on its own line, or (rarely) on the same line.
  size_t body = 1;
  if (words.size() < 3) {
    if (lines.size() < 2) fail(path, "cannot parse as OFF: no element counts");
    split(lines[1]);
    body = 2;
  } else {
    words.erase(words.begin());
  }
  int64_t vertices = -1, faces = -1;
  if (words.size() < 2 || !parseInteger(words[0], vertices) || !parseInteger(words[1], faces) ||
      vertices < 0 || faces < 0)
    fail(path, "cannot parse as OFF: malformed element counts");
  const uint64_t needed = static_cast<uint64_t>(vertices) + static_cast<uint64_t>(faces);
  if (lines.size() - body < needed) {
    fail(path, "truncated OFF: header declares " + std::to_string(vertices) + " vertices and " +
                   std::to_string(faces) + " faces, the file has " +
                   std::to_string(lines.size() - body) + " element lines");
  }

  PolygonSoup soup;
  LoadReport report;
  soup.positions.reserve(static_cast<size_t>(vertices));
  if (has_texcoords) soup.vertex_texcoords.reserve(static_cast<size_t>(vertices));
  const size_t coordinates = homogeneous ? 4 : 3;
  size_t unreadable_vertices = 0;
  for (size_t v = 0; v < static_cast<size_t>(vertices); ++v) {
    split(lines[body + v]);
    float c[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    bool readable = words.size() >= coordinates;
    for (size_t k = 0; readable && k < coordinates; ++k) readable = parseFloat(words[k], c[k]);
    glm::vec3 p(c[0], c[1], c[2]);
    if (homogeneous) p /= c[3];
    if (!readable) {
      ++unreadable_vertices;
      p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
    }
    soup.positions.push_back(p);
    if (has_texcoords) {
      glm::vec2 st(0.0f);
      if (words.size() < coordinates + 2 || !parseFloat(words[words.size() - 2], st.x) ||
          !parseFloat(words.back(), st.y))
        st = glm::vec2(0.0f);
      soup.vertex_texcoords.push_back(st);
    }
  }

  std::vector<int64_t> face;
  size_t malformed_corners = 0;
  for (size_t f = 0; f < static_cast<size_t>(faces); ++f) {
    split(lines[body + static_cast<size_t>(vertices) + f]);
    int64_t corners = -1;
    // A line of separators only (vertical tabs, form feeds) has no words.
    if (words.empty() || !parseInteger(words[0], corners) || corners < 0 ||
        static_cast<uint64_t>(corners) > words.size() - 1) {
      // The problem first, then the line, quoted short: a long line must not push it out of
      // the one-line message.
      const std::string_view line = lines[body + static_cast<size_t>(vertices) + f];
      fail(path, "cannot parse as OFF: face " + std::to_string(f) +
                     " does not list the corners it declares (line '" +
                     std::string(line.substr(0, 60)) + (line.size() > 60 ? "...'" : "'") + ")");
    }
    face.clear();
    for (size_t k = 1; k <= static_cast<size_t>(corners); ++k) {
      int64_t index = -1;
      if (!parseInteger(words[k], index)) ++malformed_corners;
      face.push_back(index);  // -1 when unreadable: validation counts it out of range
    }
    soup.addFace(face.data(), face.size());
  }

  if (unreadable_vertices > 0)
    report.warnings.push_back(std::to_string(unreadable_vertices) +
                              " vertex lines without readable coordinates (kept as non-finite)");
  if (malformed_corners > 0)
    report.warnings.push_back(std::to_string(malformed_corners) +
                              " face corners without a readable vertex index");
  return sceneFromSoup(path, soup, std::move(report));
}

// ---------------------------------------------------------------------------------------------
// STL

// STL stores each facet's three corners by value. Corners with identical coordinates are
// merged into one vertex so the mesh has its connectivity; a corner with a non-finite
// coordinate is never merged, so its facet is dropped and counted by validation rather than
// attached to some other vertex.
class VertexWelder {
 public:
  explicit VertexWelder(std::vector<glm::vec3>& positions) : positions_(positions) {}

  int64_t index(glm::vec3 p) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      positions_.push_back(p);
      return static_cast<int64_t>(positions_.size() - 1);
    }
    Key key;
    for (int c = 0; c < 3; ++c) {
      const float v = p[c] == 0.0f ? 0.0f : p[c];  // -0 and +0 are the same point
      std::memcpy(&key.bits[c], &v, 4);
    }
    auto [it, inserted] = map_.try_emplace(key, static_cast<int64_t>(positions_.size()));
    if (inserted) positions_.push_back(p);
    return it->second;
  }

 private:
  struct Key {
    uint32_t bits[3];
    bool operator==(const Key& o) const {
      return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
    }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint64_t h = k.bits[0];
      h = h * 0x9E3779B97F4A7C15ull ^ k.bits[1];
      h = h * 0x9E3779B97F4A7C15ull ^ k.bits[2];
      return std::hash<uint64_t>()(h);
    }
  };
  std::vector<glm::vec3>& positions_;
  std::unordered_map<Key, int64_t, KeyHash> map_;
};

uint32_t littleEndian32(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

float littleEndianFloat(const unsigned char* p) {
  const uint32_t bits = littleEndian32(p);
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

// Binary STL: an 80-byte header, a facet count, then 50 bytes per facet (normal, three corners,
// attribute word). Ascii STL: "solid", then facets "facet normal .. outer loop vertex x y z (x3)
// endloop endfacet", then "endsolid". A file is binary exactly when its size matches the count
// (ascii files can start with anything, binary headers often with "solid"). OpenMesh's STL reader
// is not used: it merges a NaN corner with whatever vertex the comparison lands on, and skips
// facets with coincident corners without a trace.
Scene loadStl(const std::string& path, uintmax_t file_size) {
  const std::string text = readWholeFile(path);
  const auto* bytes = reinterpret_cast<const unsigned char*>(text.data());
  PolygonSoup soup;
  LoadReport report;
  VertexWelder welder(soup.positions);

  const uint32_t declared = text.size() >= 84 ? littleEndian32(bytes + 80) : 0;
  if (text.size() >= 84 && text.size() == 84 + uint64_t(50) * declared) {
    for (uint32_t f = 0; f < declared; ++f) {
      const unsigned char* facet = bytes + 84 + size_t(50) * f + 12;  // skip the normal
      int64_t corners[3];
      for (int k = 0; k < 3; ++k) {
        const unsigned char* c = facet + 12 * k;
        corners[k] = welder.index(
            glm::vec3(littleEndianFloat(c), littleEndianFloat(c + 4), littleEndianFloat(c + 8)));
      }
      soup.addFace(corners, 3);
    }
    return sceneFromSoup(path, soup, std::move(report));
  }

  std::string_view rest(text);
  if (trimmed(rest.substr(0, std::min<size_t>(rest.size(), 80))).substr(0, 5) != "solid") {
    if (text.size() < 84)
      fail(path, "truncated binary STL: " + std::to_string(file_size) +
                     " bytes, shorter than the 84-byte header");
    fail(path, "truncated or corrupt binary STL: header declares " + std::to_string(declared) +
                   " facets (" + std::to_string(84 + uint64_t(50) * declared) +
                   " bytes), file has " + std::to_string(file_size) + " bytes");
  }

  std::vector<int64_t> loop;
  size_t unterminated = 0, stray = 0, unreadable = 0;
  bool open = false, ended = false;  // open: inside a 'facet' not yet ended
  for (std::string_view word = nextWord(rest); !word.empty(); word = nextWord(rest)) {
    if (word == "facet") {
      if (open) ++unterminated;  // its corners are dropped
      open = true;
      loop.clear();
    } else if (word == "vertex") {
      glm::vec3 p;
      bool readable = true;
      for (int k = 0; k < 3; ++k) readable = parseFloat(nextWord(rest), p[k]) && readable;
      if (!readable) {
        ++unreadable;
        p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
      }
      loop.push_back(welder.index(p));
    } else if (word == "endfacet") {
      // A facet is meant to have three corners; whatever it has is kept as a polygon (fewer
      // than three count as degenerate). Corners after an 'endfacet' without its 'facet' are
      // kept too.
      if (!open) ++stray;
      if (open || !loop.empty()) soup.addFace(loop.data(), loop.size());
      loop.clear();
      open = false;
    } else if (word == "endsolid") {
      ended = true;
    }
  }
  if (open) ++unterminated;
  if (unterminated > 0) {
    report.warnings.push_back(std::to_string(unterminated) +
                              " facets without 'endfacet' (file cut short?) dropped");
    report.dropped_degenerate += unterminated;
  }
  if (stray > 0)
    report.warnings.push_back(std::to_string(stray) + " 'endfacet' without its 'facet'");
  if (!ended) report.warnings.push_back("ascii STL without 'endsolid': the file may be truncated");
  if (unreadable > 0)
    report.warnings.push_back(std::to_string(unreadable) +
                              " vertices without readable coordinates (kept as non-finite)");
  return sceneFromSoup(path, soup, std::move(report));
}

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
