// glTF 1.0 loading: the JSON read with nlohmann::json, the scene built the way gltf_loader.cpp
// builds a glTF 2.0 one (node hierarchy to instances, primitives to meshes, one object id per
// node), materials' diffuse colour or texture decoded through texture_loader.h. Every accessor
// is bounds checked before it is read, and external files may only come from the asset's own
// folder.
#include "preprocess/gltf1_loader.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <string_view>

#include <nlohmann/json.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>

#include "preprocess/core/json_nesting.h"
#include "preprocess/loader_internal.h"
#include "preprocess/texture_loader.h"
#include "preprocess/validate.h"

namespace strata::loader {

namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// Bounds on element counts taken from the file before memory is allocated for them (they are
// also checked against the data backing them).
constexpr uint64_t kMaxAccessorElements = uint64_t(1) << 28;
// Dozens of similar warnings would bury the useful ones; keep the first.
constexpr size_t kMaxWarnings = 50;

// GL enums of glTF 1.0 (the same values as 2.0); component types and primitive modes are
// loader_internal.h's gl:: ones, which the accessor reading and triangle assembly shared with
// the 2.0 reader use.
using gl::kFloat, gl::kUnsignedByte, gl::kUnsignedShort, gl::kUnsignedInt;
constexpr int kNearest = 9728, kNearestMipmapLinear = 9986, kLinearMipmapLinear = 9987;
constexpr int kRepeat = 10497, kMirroredRepeat = 33648, kClampToEdge = 33071;

// Binary glTF 1.0 (KHR_binary_glTF): a 20-byte header, the JSON content, then the binary body,
// which the buffer with this id stands for.
constexpr size_t kGlbHeaderSize = 20;
constexpr const char* kBinaryBufferId = "binary_glTF";

// Problems with the file's structure are thrown as FormatProblem (problem(), loader_internal.h)
// and turned into Error("<file>: <problem>") by loadGltf1.

std::string quoteId(const std::string& id) { return "'" + id + "'"; }

uint32_t readU32(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

// ---------------------------------------------------------------------------------------------
// URIs

// Which URIs may be read is decided by uriRefusal (loader_internal.h), shared with the 2.0
// reader: no scheme or absolute path, before or after decoding, no NUL, and nothing that leaves
// the asset's folder, symbolic links followed. Both readers decode URIs with percentDecode
// (loader_internal.h).

bool readFile(const fs::path& path, std::vector<unsigned char>& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  out.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return !in.bad();
}

// ---------------------------------------------------------------------------------------------
// JSON access with messages that say what is wrong where

const json* member(const json& object, const char* key) {
  if (!object.is_object()) return nullptr;
  const auto it = object.find(key);
  return it == object.end() ? nullptr : &*it;
}

std::string getId(const json& object, const char* key, const std::string& what) {
  const json* v = member(object, key);
  if (!v) problem(what + ": no '" + key + "'");
  if (!v->is_string()) problem(what + ": '" + key + "' must be an id string");
  return v->get<std::string>();
}

std::optional<std::string> optionalId(const json& object, const char* key,
                                      const std::string& what) {
  if (!member(object, key)) return std::nullopt;
  return getId(object, key, what);
}

// A non-negative integer (an integral double such as 4.0 is accepted), at most 2^53.
uint64_t getUint(const json& object, const char* key, const std::string& what,
                 std::optional<uint64_t> fallback = std::nullopt) {
  const json* v = member(object, key);
  if (!v) {
    if (fallback) return *fallback;
    problem(what + ": no '" + key + "'");
  }
  if (v->is_number_unsigned() || (v->is_number_integer() && v->get<int64_t>() >= 0)) {
    const uint64_t n = v->get<uint64_t>();
    if (n <= (uint64_t(1) << 53)) return n;
  } else if (v->is_number_float()) {
    const double d = v->get<double>();
    if (d >= 0.0 && d <= 9007199254740992.0 && d == std::floor(d)) return static_cast<uint64_t>(d);
  }
  problem(what + ": '" + key + "' must be a non-negative integer");
}

// A GL enum; absent: `fallback`, or an error when there is none.
int getEnum(const json& object, const char* key, const std::string& what,
            std::optional<int> fallback = std::nullopt) {
  std::optional<uint64_t> def;
  if (fallback) def = uint64_t(*fallback);
  const uint64_t v = getUint(object, key, what, def);
  if (v > 0xFFFFFF)
    problem(what + ": '" + key + "' value " + std::to_string(v) + " is not a GL enum");
  return static_cast<int>(v);
}

// `count` numbers from an array member (absent: nullopt).
std::optional<std::vector<double>> getNumbers(const json& object, const char* key, size_t count,
                                              const std::string& what) {
  const json* v = member(object, key);
  if (!v) return std::nullopt;
  if (!v->is_array() || v->size() != count)
    problem(what + ": '" + key + "' must be an array of " + std::to_string(count) + " numbers");
  std::vector<double> out;
  for (const json& e : *v) {
    if (!e.is_number())
      problem(what + ": '" + key + "' must be an array of " + std::to_string(count) + " numbers");
    out.push_back(e.get<double>());
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Accessors

size_t componentCount(const std::string& type) {
  if (type == "SCALAR") return 1;
  if (type == "VEC2") return 2;
  if (type == "VEC3") return 3;
  if (type == "VEC4" || type == "MAT2") return 4;
  if (type == "MAT3") return 9;
  if (type == "MAT4") return 16;
  return 0;
}

// A byte window of a buffer view: pointer and size, checked against its buffer.
struct ViewBytes {
  const unsigned char* data = nullptr;
  size_t size = 0;
};

// ---------------------------------------------------------------------------------------------
// Scene assembly

class Gltf1SceneBuilder {
 public:
  Gltf1SceneBuilder(const std::string& path, const json& doc,
                    const std::vector<unsigned char>* glb_body, Scene& scene)
      : doc_(doc), glb_body_(glb_body), scene_(scene) {
    std::error_code ec;
    const fs::path file = fs::absolute(path, ec).lexically_normal();
    folder_ = file.parent_path();
    canonical_folder_ = confinementFolder(folder_);
  }

  void build() {
    checkVersion();
    for (const char* name : {"accessors", "bufferViews", "buffers", "images", "materials", "meshes",
                             "nodes", "samplers", "scenes", "textures", "techniques"})
      collection(name);  // a 2.0-style array (or anything but a dictionary) is refused up front
    if (const json* used = member(doc_, "extensionsUsed")) {
      if (!used->is_array()) problem("'extensionsUsed' must be an array");
      for (const json& e : *used) {
        if (!e.is_string()) problem("'extensionsUsed' must hold extension names");
        const std::string ext = e.get<std::string>();
        if (ext != "KHR_binary_glTF" && ext != "KHR_materials_common")
          warn("extension " + ext + " is not supported; ignored");
      }
    }
    for (const std::string& root : rootNodes()) walk(root);
  }

 private:
  void warn(const std::string& message) {
    auto& w = scene_.report.warnings;
    if (warnings_ == kMaxWarnings) w.push_back("(further glTF 1.0 warnings omitted)");
    if (warnings_++ < kMaxWarnings) w.push_back(message);
  }

  void checkVersion() const {
    const json* asset = member(doc_, "asset");
    if (!asset) return;  // required by the spec, but the content tells the version well enough
    const json* version = member(*asset, "version");
    if (!version) return;
    if (version->is_string()) {
      const std::string v = version->get<std::string>();
      if (v.empty() || v[0] != '1' || (v.size() > 1 && v[1] != '.'))
        problem("asset.version '" + v + "' is not glTF 1.0");
    } else if (version->is_number()) {
      const double v = version->get<double>();
      if (!(v >= 1.0 && v < 2.0)) problem("asset.version " + version->dump() + " is not glTF 1.0");
    } else {
      problem("asset.version must be a string");
    }
  }

  // A top-level dictionary (empty when absent).
  const json& collection(const char* name) const {
    static const json kEmpty = json::object();
    const json* c = member(doc_, name);
    if (!c) return kEmpty;
    if (!c->is_object())
      problem(std::string("'") + name + "' must be a dictionary keyed by id (glTF 1.0)" +
              (c->is_array() ? "; an array is glTF 2.0" : ""));
    return *c;
  }

  // Item `id` of top-level dictionary `name`; `kind` names it in messages ("accessor").
  const json& item(const char* name, const char* kind, const std::string& id,
                   const std::string& what) const {
    const json& c = collection(name);
    const auto it = c.find(id);
    if (it == c.end()) problem(what + ": " + kind + " " + quoteId(id) + " does not exist");
    if (!it->is_object()) problem(std::string(kind) + " " + quoteId(id) + " must be an object");
    return *it;
  }

  // ----- files and buffers

  // The path of a relative URI inside the asset's folder; refuses anything else. The path is
  // lexically normalised before it is checked, and that same path is opened.
  fs::path resolveUri(const std::string& uri, const std::string& what) const {
    if (uri.empty()) problem(what + ": empty URI");
    const std::string decoded = percentDecode(uri);
    const fs::path target = (folder_ / decoded).lexically_normal();
    const std::string refusal = uriRefusal(uri, decoded, target, canonical_folder_);
    if (!refusal.empty()) problem(what + ": " + refusal);
    return target;
  }

  const std::vector<unsigned char>& buffer(const std::string& id, const std::string& what) {
    const auto cached = buffers_.find(id);
    if (cached != buffers_.end()) return cached->second;
    const json& b = item("buffers", "buffer", id, what);
    const std::string where = "buffer " + quoteId(id);
    std::vector<unsigned char> bytes;
    if (glb_body_ && id == kBinaryBufferId) {
      bytes = *glb_body_;
    } else {
      const std::string uri = getId(b, "uri", where);
      if (isDataUri(uri)) {
        bytes = decodeDataUri(uri, where);
      } else {
        const fs::path file = resolveUri(uri, where);
        std::error_code ec;
        if (!fs::is_regular_file(file, ec)) problem(where + ": file '" + uri + "' not found");
        if (!readFile(file, bytes)) problem(where + ": cannot read '" + uri + "'");
      }
    }
    if (member(b, "byteLength")) {
      const uint64_t length = getUint(b, "byteLength", where);
      if (length > bytes.size())
        problem(where + ": byteLength " + std::to_string(length) + " but only " +
                std::to_string(bytes.size()) + " bytes of data (truncated?)");
      bytes.resize(static_cast<size_t>(length));
    }
    return buffers_.emplace(id, std::move(bytes)).first->second;
  }

  ViewBytes bufferView(const std::string& id, const std::string& what) {
    const json& v = item("bufferViews", "bufferView", id, what);
    const std::string where = what + ": bufferView " + quoteId(id);
    const std::vector<unsigned char>& bytes = buffer(getId(v, "buffer", where), where);
    const uint64_t offset = getUint(v, "byteOffset", where, 0);
    if (offset > bytes.size())
      problem(where + ": byteOffset " + std::to_string(offset) + " is past its buffer's " +
              std::to_string(bytes.size()) + " bytes");
    const uint64_t length = getUint(v, "byteLength", where, bytes.size() - offset);
    if (length > bytes.size() - offset)
      problem(where + " (offset " + std::to_string(offset) + ", length " + std::to_string(length) +
              ") extends past its buffer's " + std::to_string(bytes.size()) + " bytes");
    return {bytes.data() + offset, static_cast<size_t>(length)};
  }

  // Reads accessor `id` as rows of `components` doubles (integers normalised when asked).
  std::vector<double> readAccessor(const std::string& id, size_t components,
                                   const std::vector<int>& allowed, bool normalized,
                                   const std::string& what) {
    const json& a = item("accessors", "accessor", id, what);
    const std::string name = what + " (accessor " + quoteId(id) + ")";
    if (const json* ext = member(a, "extensions");
        ext && member(*ext, "WEB3D_quantized_attributes"))
      problem(name + ": quantized (WEB3D_quantized_attributes), which is not supported");
    const json* type = member(a, "type");
    if (!type || !type->is_string()) problem(name + ": no 'type'");
    const std::string type_name = type->get<std::string>();
    if (componentCount(type_name) != components)
      problem(name + ": type " + type_name + " where a " + std::to_string(components) +
              "-component type is required");
    const int component_type = getEnum(a, "componentType", name);
    if (std::find(allowed.begin(), allowed.end(), component_type) == allowed.end())
      problem(name + ": unsupported componentType " + std::to_string(component_type));
    const uint64_t count = getUint(a, "count", name);
    if (count > kMaxAccessorElements)
      problem(name + ": count " + std::to_string(count) + " is implausibly large");
    const uint64_t offset = getUint(a, "byteOffset", name, 0);
    const size_t element = components * gltfComponentSize(component_type);
    const uint64_t byte_stride = getUint(a, "byteStride", name, 0);
    if (byte_stride != 0 && (byte_stride < element || byte_stride > 255))
      problem(name + ": byteStride " + std::to_string(byte_stride) + " is outside [element size " +
              std::to_string(element) + ", 255]");
    const size_t stride = byte_stride ? static_cast<size_t>(byte_stride) : element;
    const ViewBytes view = bufferView(getId(a, "bufferView", name), name);

    std::vector<double> out;
    if (count == 0) return out;
    if (!elementsFit(offset, count, element, stride, view.size))
      problem(name + ": " + describeElements(count, element, stride, offset) +
              " do not fit in its bufferView of " + std::to_string(view.size) + " bytes");
    const unsigned char* base = view.data + offset;
    const size_t csize = gltfComponentSize(component_type);
    out.resize(static_cast<size_t>(count) * components);
    for (size_t i = 0; i < count; ++i)
      for (size_t c = 0; c < components; ++c)
        out[i * components + c] =
            readGltfComponent(base + i * stride + c * csize, component_type, normalized);
    return out;
  }

  // ----- hierarchy

  std::vector<std::string> idList(const json& object, const char* key,
                                  const std::string& what) const {
    std::vector<std::string> ids;
    const json* list = member(object, key);
    if (!list) return ids;
    if (!list->is_array()) problem(what + ": '" + key + "' must be an array of ids");
    for (const json& e : *list) {
      if (!e.is_string()) problem(what + ": '" + key + "' must be an array of ids");
      ids.push_back(e.get<std::string>());
    }
    return ids;
  }

  std::vector<std::string> rootNodes() const {
    const json& scenes = collection("scenes");
    if (const json* s = member(doc_, "scene")) {
      if (!s->is_string()) problem("'scene' must be an id string");
      const std::string id = s->get<std::string>();
      return idList(item("scenes", "scene", id, "default scene"), "nodes", "scene " + quoteId(id));
    }
    if (!scenes.empty()) {
      // No default scene: the first one (by id) is the conventional choice.
      const auto first = scenes.begin();
      if (!first->is_object()) problem("scene " + quoteId(first.key()) + " must be an object");
      return idList(*first, "nodes", "scene " + quoteId(first.key()));
    }
    // No scenes: every node that is nobody's child is a root.
    const json& nodes = collection("nodes");
    std::map<std::string, bool> is_child;
    for (auto it = nodes.begin(); it != nodes.end(); ++it)
      for (const std::string& c : idList(*it, "children", "node " + quoteId(it.key())))
        is_child[c] = true;
    std::vector<std::string> roots;
    for (auto it = nodes.begin(); it != nodes.end(); ++it)
      if (!is_child.count(it.key())) roots.push_back(it.key());
    return roots;
  }

  // Depth-first without recursion, so deep or hostile hierarchies cannot exhaust the stack. The
  // node graph must be a forest: a node met again while on the current path is a cycle (an
  // error); met again after its subtree is done, it has two parents and is drawn once.
  void walk(const std::string& root) {
    enum : uint8_t { kOnPath = 1, kDone = 2 };
    struct Step {
      std::string node;
      glm::dmat4 parent;
      bool exit;
      std::string from;  // who names the node, for messages
    };
    std::vector<Step> stack{{root, glm::dmat4(1.0), false, "scene"}};
    while (!stack.empty()) {
      Step step = std::move(stack.back());
      stack.pop_back();
      uint8_t& state = node_state_[step.node];
      if (step.exit) {
        state = kDone;
        continue;
      }
      const json& node = item("nodes", "node", step.node, step.from);
      const std::string what = "node " + quoteId(step.node);
      if (state == kOnPath)
        problem("node hierarchy has a cycle through node " + quoteId(step.node));
      if (state == kDone) {
        warn(what + " has more than one parent; drawn once");
        continue;
      }
      state = kOnPath;
      const glm::dmat4 world = step.parent * localTransform(node, what);
      const std::vector<std::string> meshes = idList(node, "meshes", what);
      if (!meshes.empty()) {
        if (member(node, "skin") || member(node, "skeletons"))
          warn(what + ": skinning ignored; drawn in its bind pose");
        addInstances(node, step.node, meshes, world);
      }
      const std::vector<std::string> children = idList(node, "children", what);
      stack.push_back({step.node, glm::dmat4(1.0), true, {}});
      for (auto it = children.rbegin(); it != children.rend(); ++it)
        stack.push_back({*it, world, false, what + " children"});
    }
  }

  static glm::dmat4 localTransform(const json& node, const std::string& what) {
    glm::dmat4 m(1.0);
    if (const auto matrix = getNumbers(node, "matrix", 16, what)) {
      for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
          m[c][r] = (*matrix)[size_t(4 * c + r)];  // column-major, like glm
    } else {
      glm::dmat4 t(1.0), r(1.0), s(1.0);
      if (const auto v = getNumbers(node, "translation", 3, what))
        t = glm::translate(glm::dmat4(1.0), glm::dvec3((*v)[0], (*v)[1], (*v)[2]));
      if (const auto q = getNumbers(node, "rotation", 4, what)) {
        // x, y, z, w, as in 2.0
        const glm::dquat quat((*q)[3], (*q)[0], (*q)[1], (*q)[2]);
        if (!(glm::length(quat) > 0.0)) problem(what + ": rotation is not a unit quaternion");
        r = glm::mat4_cast(glm::normalize(quat));
      }
      if (const auto v = getNumbers(node, "scale", 3, what))
        s = glm::scale(glm::dmat4(1.0), glm::dvec3((*v)[0], (*v)[1], (*v)[2]));
      m = t * r * s;
    }
    return finiteTransform(m, what);
  }

  void addInstances(const json& node, const std::string& id, const std::vector<std::string>& meshes,
                    const glm::dmat4& world) {
    const std::string what = "node " + quoteId(id);
    glm::mat4 transform(1.0f);
    if (!toFloatTransform(world, transform))
      problem(what + ": world transform exceeds float range");
    std::string name = id;
    if (const json* n = member(node, "name"); n && n->is_string() && !n->get<std::string>().empty())
      name = n->get<std::string>();
    const uint32_t object_id = next_object_id_++;
    for (const std::string& gltf_mesh : meshes)
      addNodeInstances(scene_, meshesOf(gltf_mesh, what), transform, object_id, name);
  }

  // ----- meshes

  // The strata meshes (one per triangle primitive) of glTF mesh `id`, built on first use and
  // shared by every node that draws it.
  const std::vector<uint32_t>& meshesOf(const std::string& id, const std::string& what) {
    const auto cached = mesh_cache_.find(id);
    if (cached != mesh_cache_.end()) return cached->second;
    const json& gm = item("meshes", "mesh", id, what);
    std::vector<uint32_t> built;
    const std::string where = "mesh " + quoteId(id);
    const json* primitives = member(gm, "primitives");
    if (primitives && !primitives->is_array()) problem(where + ": 'primitives' must be an array");
    if (!primitives || primitives->empty()) warn(where + " has no primitives");
    std::string base_name = id;
    if (const json* n = member(gm, "name"); n && n->is_string() && !n->get<std::string>().empty())
      base_name = n->get<std::string>();
    for (size_t p = 0; primitives && p < primitives->size(); ++p) {
      const json& prim = (*primitives)[p];
      const std::string pwhat = where + " primitive " + std::to_string(p);
      if (!prim.is_object()) problem(pwhat + " must be an object");
      Mesh mesh;
      if (!buildPrimitive(prim, pwhat, mesh)) continue;
      mesh.name = base_name + "#" + std::to_string(p);
      mesh.material = materialFor(optionalId(prim, "material", pwhat), pwhat);
      built.push_back(static_cast<uint32_t>(scene_.meshes.size()));
      scene_.meshes.push_back(std::move(mesh));
    }
    return mesh_cache_.emplace(id, std::move(built)).first->second;
  }

  bool buildPrimitive(const json& prim, const std::string& what, Mesh& mesh) {
    const int mode = getEnum(prim, "mode", what, gl::kTriangles);
    if (mode != gl::kTriangles && mode != gl::kTriangleStrip && mode != gl::kTriangleFan) {
      warn(what + ": mode " + std::to_string(mode) + " (points or lines) skipped");
      return false;
    }
    const json* attributes = member(prim, "attributes");
    if (attributes && !attributes->is_object()) problem(what + ": 'attributes' must be an object");
    if (!attributes || !member(*attributes, "POSITION")) {
      warn(what + ": no POSITION attribute; skipped");
      return false;
    }
    // Read in the order POSITION, TEXCOORD_0, indices (the order their errors are reported).
    PrimitiveRows rows;
    rows.positions =
        readAccessor(getId(*attributes, "POSITION", what), 3, {kFloat}, false, what + " POSITION");
    if (member(*attributes, "TEXCOORD_0"))
      rows.texcoords =
          readAccessor(getId(*attributes, "TEXCOORD_0", what), 2,
                       {kFloat, kUnsignedByte, kUnsignedShort}, true, what + " TEXCOORD_0");
    if (member(prim, "indices"))
      rows.indices =
          readAccessor(getId(prim, "indices", what), 1,
                       {kUnsignedByte, kUnsignedShort, kUnsignedInt}, false, what + " indices");
    // Assembled as in 2.0, by the same code (odd strip triangles swap their last two corners).
    buildTriangleMesh(
        mode, rows, what, [this](const std::string& w) { warn(w); }, mesh);
    return true;
  }

  // ----- materials and textures

  uint32_t materialFor(const std::optional<std::string>& id, const std::string& what) {
    const std::string key = id.value_or("");
    const auto cached = material_cache_.find(key);
    if (cached != material_cache_.end()) return cached->second;
    Material material;
    if (!id) {
      material.name = "default";
    } else {
      const json& gm = item("materials", "material", *id, what);
      const std::string where = "material " + quoteId(*id);
      material.name = *id;
      if (const json* n = member(gm, "name"); n && n->is_string() && !n->get<std::string>().empty())
        material.name = n->get<std::string>();
      if (const json* diffuse = diffuseOf(gm, where)) applyDiffuse(*diffuse, where, material);
    }
    const uint32_t index = static_cast<uint32_t>(scene_.materials.size());
    scene_.materials.push_back(std::move(material));
    material_cache_.emplace(key, index);
    return index;
  }

  // The material's diffuse value: KHR_materials_common's (diffuse, or emission for its CONSTANT
  // technique), else the material's own values, else the default value of its technique's
  // "diffuse" parameter. nullptr when there is none.
  const json* diffuseOf(const json& gm, const std::string& where) const {
    if (const json* ext = member(gm, "extensions")) {
      if (const json* common = member(*ext, "KHR_materials_common")) {
        if (const json* values = member(*common, "values")) {
          if (const json* d = member(*values, "diffuse")) return d;
          if (const json* e = member(*values, "emission")) return e;
        }
      }
    }
    if (const json* values = member(gm, "values"))
      if (const json* d = member(*values, "diffuse")) return d;
    if (const json* t = member(gm, "technique"); t && t->is_string()) {
      const json& techniques = collection("techniques");
      const auto it = techniques.find(t->get<std::string>());
      if (it != techniques.end())
        if (const json* params = member(*it, "parameters"))
          if (const json* d = member(*params, "diffuse"))
            if (const json* v = member(*d, "value")) return v;
    }
    return nullptr;
  }

  void applyDiffuse(const json& diffuse, const std::string& where, Material& material) {
    // A texture may be given as an id or as a one-element array holding the id.
    const json* texture = diffuse.is_string() ? &diffuse : nullptr;
    if (diffuse.is_array() && diffuse.size() == 1 && diffuse[0].is_string()) texture = &diffuse[0];
    if (texture) {
      material.color = glm::vec4(1.0f);  // the texel is the colour
      bindTexture(texture->get<std::string>(), where, material);
      return;
    }
    if (diffuse.is_array() && (diffuse.size() == 3 || diffuse.size() == 4) &&
        std::all_of(diffuse.begin(), diffuse.end(), [](const json& e) { return e.is_number(); })) {
      for (size_t c = 0; c < diffuse.size(); ++c) {
        // Colours are bounded to [0, 1]; clamping keeps a bad file's colour meaningful.
        const double f = diffuse[c].get<double>();
        material.color[int(c)] =
            std::isfinite(f) ? static_cast<float>(std::clamp(f, 0.0, 1.0)) : 1.0f;
      }
      return;
    }
    warn(where + ": diffuse is neither a colour nor a texture id; default colour used");
  }

  void bindTexture(const std::string& id, const std::string& where, Material& material) {
    const json& t = item("textures", "texture", id, where);
    const std::string what = "texture " + quoteId(id);
    const int target = getEnum(t, "target", what, 3553);
    if (target != 3553) {
      warn(what + ": target " + std::to_string(target) + " is not TEXTURE_2D; ignored");
      return;
    }
    const std::string source = getId(t, "source", what);
    material.texture = textureFor(source, what);
    material.base_color_texture = scene_.textures[size_t(material.texture)].name;
    if (const auto sampler = optionalId(t, "sampler", what))
      material.sampler =
          samplerFor(item("samplers", "sampler", *sampler, what), "sampler " + quoteId(*sampler));
    else
      material.sampler = samplerFor(json::object(), what);
  }

  Sampler samplerFor(const json& s, const std::string& what) {
    Sampler sampler;
    // glTF 1.0's defaults: LINEAR magnification, NEAREST_MIPMAP_LINEAR minification, REPEAT.
    const int mag = getEnum(s, "magFilter", what, 9729);
    const int min = getEnum(s, "minFilter", what, kNearestMipmapLinear);
    if (mag == kNearest)
      sampler.filter = Filter::Nearest;
    else if (min == kLinearMipmapLinear || min == kNearestMipmapLinear)
      sampler.filter = Filter::Trilinear;
    else
      sampler.filter = Filter::Bilinear;
    sampler.wrap_s = wrapOf(getEnum(s, "wrapS", what, kRepeat), what + " wrapS");
    sampler.wrap_t = wrapOf(getEnum(s, "wrapT", what, kRepeat), what + " wrapT");
    return sampler;
  }

  Wrap wrapOf(int mode, const std::string& what) {
    switch (mode) {
      case kRepeat:
        return Wrap::Repeat;
      case kMirroredRepeat:
        return Wrap::MirroredRepeat;
      case kClampToEdge:
        return Wrap::Clamp;
      default:
        warn(what + ": unknown wrap mode " + std::to_string(mode) + "; REPEAT used");
        return Wrap::Repeat;
    }
  }

  // Scene::textures index of image `id`, decoded on first use.
  int32_t textureFor(const std::string& id, const std::string& what) {
    const auto cached = texture_cache_.find(id);
    if (cached != texture_cache_.end()) return cached->second;
    const json& image = item("images", "image", id, what);
    const std::string where = "image " + quoteId(id);
    SceneTexture texture;
    try {
      const json* binary = nullptr;
      if (const json* ext = member(image, "extensions")) binary = member(*ext, "KHR_binary_glTF");
      if (binary) {
        const ViewBytes bytes =
            bufferView(getId(*binary, "bufferView", where + " KHR_binary_glTF"), where);
        texture.name = "embedded:" + id;
        texture.image = loadTextureMemory(bytes.data, bytes.size, texture.name);
      } else {
        const std::string uri = getId(image, "uri", where);
        if (isDataUri(uri)) {
          const std::vector<unsigned char> bytes = decodeDataUri(uri, where);
          texture.name = "embedded:" + id;
          texture.image = loadTextureMemory(bytes.data(), bytes.size(), texture.name);
        } else {
          const fs::path file = resolveUri(uri, where);
          texture.name = uri;
          texture.image = loadTextureFile(file.string());
        }
      }
    } catch (const Error& e) {
      problem(where + ": " + e.what());
    }
    if (!texture.image) problem(where + ": the image could not be decoded");
    const int32_t index = static_cast<int32_t>(scene_.textures.size());
    scene_.textures.push_back(std::move(texture));
    texture_cache_.emplace(id, index);
    return index;
  }

  const json& doc_;
  const std::vector<unsigned char>* glb_body_;
  Scene& scene_;
  fs::path folder_, canonical_folder_;
  std::map<std::string, std::vector<unsigned char>> buffers_;
  std::map<std::string, uint8_t> node_state_;
  std::map<std::string, std::vector<uint32_t>> mesh_cache_;
  std::map<std::string, uint32_t> material_cache_;
  std::map<std::string, int32_t> texture_cache_;
  uint32_t next_object_id_ = 0;
  size_t warnings_ = 0;
};

// "parse error at line 3, column 1: ..." without nlohmann's "[json.exception.parse_error.101] ".
std::string jsonMessage(const std::exception& e) {
  std::string m = e.what();
  if (m.compare(0, 16, "[json.exception.") == 0) {
    const size_t close = m.find("] ");
    if (close != std::string::npos) m = m.substr(close + 2);
  }
  return firstLine(m);
}

}  // namespace

Scene loadGltf1(const std::string& path) {
  std::vector<unsigned char> bytes;
  {
    std::error_code ec;
    if (!fs::exists(path, ec)) fail(path, "no such file");
    if (!fs::is_regular_file(path, ec)) fail(path, "not a regular file");
    if (!readFile(path, bytes)) fail(path, "cannot read file");
  }
  if (bytes.empty()) fail(path, "empty file");

  // Binary glTF 1.0: header (magic, version 1, total length, content length, content format 0
  // = JSON), the JSON content, then the binary body.
  std::vector<unsigned char> body;
  const bool binary = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (binary) {
    if (bytes.size() < kGlbHeaderSize)
      fail(path, "binary glTF header truncated (" + std::to_string(bytes.size()) + " of 20 bytes)");
    const uint32_t version = readU32(&bytes[4]), length = readU32(&bytes[8]),
                   content_length = readU32(&bytes[12]), content_format = readU32(&bytes[16]);
    if (version != 1)
      fail(path, "binary glTF version " + std::to_string(version) + " is not glTF 1.0");
    if (length != bytes.size())
      fail(path, "binary glTF header declares " + std::to_string(length) +
                     " bytes but the file has " + std::to_string(bytes.size()) +
                     " (truncated or altered)");
    if (content_length > length - kGlbHeaderSize)
      fail(path, "binary glTF content of " + std::to_string(content_length) +
                     " bytes extends past the end of the file");
    if (content_format != 0)
      fail(path,
           "binary glTF content format " + std::to_string(content_format) + " is not JSON (0)");
    text = text.substr(kGlbHeaderSize, content_length);
    body.assign(bytes.begin() + static_cast<std::ptrdiff_t>(kGlbHeaderSize + content_length),
                bytes.end());
  }

  if (jsonNestingDepth(text) > kMaxJsonNesting)
    fail(path, "the JSON nests arrays and objects more than " + std::to_string(kMaxJsonNesting) +
                   " deep");
  json doc;
  try {
    doc = json::parse(text.begin(), text.end());
  } catch (const json::exception& e) {
    fail(path, "cannot parse JSON: " + jsonMessage(e));
  }
  if (!doc.is_object()) fail(path, "the glTF JSON is not an object");

  Scene scene;
  scene.source = path;
  try {
    Gltf1SceneBuilder(path, doc, binary ? &body : nullptr, scene).build();
  } catch (const FormatProblem& p) {
    fail(path, p.message);
  } catch (const json::exception& e) {
    fail(path, "malformed glTF 1.0: " + jsonMessage(e));
  }
  validateScene(scene);
  compactObjectIds(scene);  // validation may have removed instances
  return scene;
}

}  // namespace strata::loader
