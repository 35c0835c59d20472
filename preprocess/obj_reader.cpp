// The OBJ reader, with its MTL material libraries (loadObj).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>
#include <filesystem>
#include <map>
#include <unordered_map>

#include "preprocess/texture_loader.h"
#include "preprocess/loader_internal.h"

namespace strata::loader {

namespace fs = std::filesystem;

namespace {

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

}  // namespace

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

}  // namespace strata::loader
