// glTF 2.0 / GLB loading through tinygltf: node hierarchy to instances, primitives to meshes,
// metallic-roughness base colour (factor, and its texture decoded with texture_loader.h) to
// materials. Every accessor is bounds checked before it is read, and external files may only
// come from the asset's own folder.
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <nlohmann/json.hpp>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "preprocess/core/json_nesting.h"
#include "preprocess/gltf_asset_guard.h"
#include "preprocess/loader_internal.h"
#include "preprocess/texture_loader.h"
#include "preprocess/validate.h"

namespace strata::loader {

namespace {

namespace fs = std::filesystem;

// A library that reports dozens of similar problems would bury the useful ones; keep the first.
constexpr size_t kMaxLibraryWarnings = 20;

// Bounds on element counts taken from the file before memory is allocated for them. Counts
// backed by buffer data are also checked against the data's size.
constexpr size_t kMaxAccessorElements = size_t(1) << 28;
constexpr size_t kMaxUnbackedSparseElements = size_t(1) << 24;

// tinygltf hands every image's encoded bytes to this callback while parsing. Images are decoded
// later, and only those a material's base colour uses (GltfSceneBuilder::sceneTexture), so the
// callback keeps the bytes of URI images (a file read through the folder guard, or a data: URI)
// and leaves bufferView images in their buffer: tinygltf passes a pointer into the buffer without
// checking the view against the buffer's size, so those bytes are read later through the
// bounds-checked viewRange instead.
bool keepImageBytes(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                    const unsigned char* bytes, int size, void*) {
  if (image->bufferView < 0 && bytes != nullptr && size > 0)
    image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Accessors

// Components are sized and read by gltfComponentSize and readGltfComponent (loader_internal.h),
// shared with the glTF 1.0 reader: the GL enums are the same numbers in both versions.
static_assert(TINYGLTF_COMPONENT_TYPE_BYTE == gl::kByte &&
              TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE == gl::kUnsignedByte &&
              TINYGLTF_COMPONENT_TYPE_SHORT == gl::kShort &&
              TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT == gl::kUnsignedShort &&
              TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT == gl::kUnsignedInt &&
              TINYGLTF_COMPONENT_TYPE_FLOAT == gl::kFloat);
static_assert(TINYGLTF_MODE_TRIANGLES == gl::kTriangles &&
              TINYGLTF_MODE_TRIANGLE_STRIP == gl::kTriangleStrip &&
              TINYGLTF_MODE_TRIANGLE_FAN == gl::kTriangleFan);

size_t componentCount(int type) {
  switch (type) {
    case TINYGLTF_TYPE_SCALAR:
      return 1;
    case TINYGLTF_TYPE_VEC2:
      return 2;
    case TINYGLTF_TYPE_VEC3:
      return 3;
    case TINYGLTF_TYPE_VEC4:
    case TINYGLTF_TYPE_MAT2:
      return 4;
    case TINYGLTF_TYPE_MAT3:
      return 9;
    case TINYGLTF_TYPE_MAT4:
      return 16;
    default:
      return 0;
  }
}

// Problems with the file's structure are thrown as FormatProblem (problem(), loader_internal.h)
// and turned into Error("<file>: <context>: ...") by loadGltf.

// A validated window onto `count` elements of `element_size` bytes spaced `stride` apart.
struct ByteRange {
  const unsigned char* data = nullptr;
  size_t count = 0;
  size_t stride = 0;
};

// Checks that `count` elements at `offset` inside buffer view `view_index` stay inside both the
// view and its buffer, without overflowing size_t on hostile counts.
ByteRange viewRange(const tinygltf::Model& model, int view_index, size_t offset, size_t count,
                    size_t element_size, size_t stride_override, const std::string& what) {
  if (view_index < 0 || static_cast<size_t>(view_index) >= model.bufferViews.size())
    problem(what + ": bufferView " + std::to_string(view_index) + " does not exist");
  const tinygltf::BufferView& view = model.bufferViews[static_cast<size_t>(view_index)];
  if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model.buffers.size())
    problem(what + ": bufferView " + std::to_string(view_index) + " names buffer " +
            std::to_string(view.buffer) + ", which does not exist");
  const std::vector<unsigned char>& bytes = model.buffers[static_cast<size_t>(view.buffer)].data;
  if (view.byteOffset > bytes.size() || view.byteLength > bytes.size() - view.byteOffset)
    problem(what + ": bufferView " + std::to_string(view_index) + " (offset " +
            std::to_string(view.byteOffset) + ", length " + std::to_string(view.byteLength) +
            ") extends past its buffer's " + std::to_string(bytes.size()) + " bytes");
  size_t stride = stride_override ? stride_override : element_size;
  if (stride_override == 0 && view.byteStride != 0) {
    if (view.byteStride < element_size || view.byteStride > 252)
      problem(what + ": byteStride " + std::to_string(view.byteStride) +
              " is outside [element size " + std::to_string(element_size) + ", 252]");
    stride = view.byteStride;
  }
  ByteRange range;
  range.count = count;
  range.stride = stride;
  if (count == 0) return range;
  const size_t limit = view.byteLength;
  if (!elementsFit(offset, count, element_size, stride, limit))
    problem(what + ": " + describeElements(count, element_size, stride, offset) +
            " do not fit in bufferView " + std::to_string(view_index) + " of " +
            std::to_string(limit) + " bytes");
  range.data = bytes.data() + view.byteOffset + offset;
  return range;
}

const tinygltf::Accessor& accessorAt(const tinygltf::Model& model, int index,
                                     const std::string& what) {
  if (index < 0 || static_cast<size_t>(index) >= model.accessors.size())
    problem(what + ": accessor " + std::to_string(index) + " does not exist");
  return model.accessors[static_cast<size_t>(index)];
}

// Reads accessor `index` as `components`-wide rows of doubles (normalised integers mapped to
// [0,1] / [-1,1]), applying sparse substitution. `allowed` filters component types.
std::vector<double> readAccessor(const tinygltf::Model& model, int index, int expected_type,
                                 const std::vector<int>& allowed, const std::string& what) {
  const std::string name = what + " (accessor " + std::to_string(index) + ")";
  const tinygltf::Accessor& a = accessorAt(model, index, what);
  if (a.type != expected_type)
    problem(name + ": type " + std::to_string(a.type) + " where " + std::to_string(expected_type) +
            " is required");
  if (std::find(allowed.begin(), allowed.end(), a.componentType) == allowed.end())
    problem(name + ": unsupported componentType " + std::to_string(a.componentType));
  const size_t components = componentCount(a.type);
  const size_t csize = gltfComponentSize(a.componentType);
  if (a.count > kMaxAccessorElements)
    problem(name + ": count " + std::to_string(a.count) + " is implausibly large");

  std::vector<double> out;
  if (a.bufferView >= 0) {
    const ByteRange r =
        viewRange(model, a.bufferView, a.byteOffset, a.count, components * csize, 0, name);
    out.resize(a.count * components);
    for (size_t i = 0; i < a.count; ++i)
      for (size_t c = 0; c < components; ++c)
        out[i * components + c] =
            readGltfComponent(r.data + i * r.stride + c * csize, a.componentType, a.normalized);
  } else if (a.sparse.isSparse) {
    // Sparse without a base view starts from zeros; its count is backed by no data, so bound
    // it before allocating.
    if (a.count > kMaxUnbackedSparseElements)
      problem(name + ": sparse accessor of " + std::to_string(a.count) +
              " elements without a bufferView is implausibly large");
    out.assign(a.count * components, 0.0);
  } else {
    problem(name + ": no bufferView (and not sparse)");
  }

  if (a.sparse.isSparse && a.sparse.count > 0) {
    const size_t n = static_cast<size_t>(a.sparse.count);
    if (a.sparse.count < 0 || n > a.count)
      problem(name + ": sparse count " + std::to_string(a.sparse.count) + " exceeds count " +
              std::to_string(a.count));
    const int itype = a.sparse.indices.componentType;
    if (itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        itype != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
      problem(name + ": unsupported sparse index componentType " + std::to_string(itype));
    if (a.sparse.indices.byteOffset < 0 || a.sparse.values.byteOffset < 0)
      problem(name + ": negative sparse byteOffset");
    const size_t isize = gltfComponentSize(itype);
    const ByteRange ir = viewRange(model, a.sparse.indices.bufferView,
                                   static_cast<size_t>(a.sparse.indices.byteOffset), n, isize,
                                   isize, name + " sparse indices");
    const ByteRange vr = viewRange(model, a.sparse.values.bufferView,
                                   static_cast<size_t>(a.sparse.values.byteOffset), n,
                                   components * csize, components * csize, name + " sparse values");
    for (size_t i = 0; i < n; ++i) {
      const double target = readGltfComponent(ir.data + i * ir.stride, itype, false);
      if (target >= static_cast<double>(a.count))
        problem(name + ": sparse index " + std::to_string(static_cast<uint64_t>(target)) +
                " is past count " + std::to_string(a.count));
      const size_t row = static_cast<size_t>(target);
      for (size_t c = 0; c < components; ++c)
        out[row * components + c] =
            readGltfComponent(vr.data + i * vr.stride + c * csize, a.componentType, a.normalized);
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Scene assembly

// Extensions that change where geometry lives; without them the accessors would read as
// garbage or zeros, so such files are refused with a clear message.
const char* const kUnsupportedGeometryExtensions[] = {
    "KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization"};

class GltfSceneBuilder {
 public:
  GltfSceneBuilder(const tinygltf::Model& model, Scene& scene) : model_(model), scene_(scene) {}

  void build() {
    for (const std::string& ext : model_.extensionsRequired) {
      for (const char* unsupported : kUnsupportedGeometryExtensions)
        if (ext == unsupported) problem("requires unsupported extension " + ext);
    }
    for (int root : rootNodes()) walk(root);
  }

 private:
  std::vector<int> rootNodes() const {
    if (!model_.scenes.empty()) {
      int s = model_.defaultScene;
      if (s < 0) s = 0;  // no default scene: the first one is the conventional choice
      if (static_cast<size_t>(s) >= model_.scenes.size())
        problem("default scene " + std::to_string(s) + " does not exist");
      return model_.scenes[static_cast<size_t>(s)].nodes;
    }
    // No scenes: every node that is nobody's child is a root.
    std::vector<bool> is_child(model_.nodes.size(), false);
    for (const tinygltf::Node& node : model_.nodes)
      for (int c : node.children)
        if (c >= 0 && static_cast<size_t>(c) < is_child.size())
          is_child[static_cast<size_t>(c)] = true;
    std::vector<int> roots;
    for (size_t i = 0; i < model_.nodes.size(); ++i)
      if (!is_child[i]) roots.push_back(static_cast<int>(i));
    return roots;
  }

  // Depth-first, without recursion, so deep or hostile hierarchies cannot exhaust the stack. The
  // glTF node graph must be a forest: a node met again while it is on the current path is a
  // cycle (an error); met again after its subtree is done, it has two parents and is cut.
  void walk(int root) {
    enum : uint8_t { kUnvisited, kOnPath, kDone };
    state_.resize(model_.nodes.size(), kUnvisited);
    struct Step {
      int node;
      glm::dmat4 parent;
      bool exit;
    };
    std::vector<Step> stack{{root, glm::dmat4(1.0), false}};
    while (!stack.empty()) {
      const Step step = stack.back();
      stack.pop_back();
      if (step.node < 0 || static_cast<size_t>(step.node) >= model_.nodes.size())
        problem("node " + std::to_string(step.node) + " does not exist");
      const size_t n = static_cast<size_t>(step.node);
      if (step.exit) {
        state_[n] = kDone;
        continue;
      }
      if (state_[n] == kOnPath)
        problem("node hierarchy has a cycle through node " + std::to_string(n));
      if (state_[n] == kDone) {
        scene_.report.warnings.push_back("node " + std::to_string(n) +
                                         " has more than one parent; drawn once");
        continue;
      }
      state_[n] = kOnPath;
      const tinygltf::Node& node = model_.nodes[n];
      const glm::dmat4 world = step.parent * localTransform(node, n);
      if (node.mesh >= 0) addInstances(node, n, world);
      stack.push_back({step.node, glm::dmat4(1.0), true});
      for (auto it = node.children.rbegin(); it != node.children.rend(); ++it)
        stack.push_back({*it, world, false});
    }
  }

  static glm::dmat4 localTransform(const tinygltf::Node& node, size_t index) {
    const std::string what = "node " + std::to_string(index);
    glm::dmat4 m(1.0);
    if (!node.matrix.empty()) {
      if (node.matrix.size() != 16) problem(what + ": matrix needs 16 numbers");
      m = glm::make_mat4(node.matrix.data());  // glTF matrices are column-major, like glm
    } else {
      glm::dmat4 t(1.0), r(1.0), s(1.0);
      if (!node.translation.empty()) {
        if (node.translation.size() != 3) problem(what + ": translation needs 3 numbers");
        t = glm::translate(glm::dmat4(1.0), glm::make_vec3(node.translation.data()));
      }
      if (!node.rotation.empty()) {
        if (node.rotation.size() != 4) problem(what + ": rotation needs 4 numbers");
        const auto& q = node.rotation;  // glTF order x, y, z, w
        r = glm::mat4_cast(glm::normalize(glm::dquat(q[3], q[0], q[1], q[2])));
      }
      if (!node.scale.empty()) {
        if (node.scale.size() != 3) problem(what + ": scale needs 3 numbers");
        s = glm::scale(glm::dmat4(1.0), glm::make_vec3(node.scale.data()));
      }
      m = t * r * s;
    }
    return finiteTransform(m, what);
  }

  void addInstances(const tinygltf::Node& node, size_t index, const glm::dmat4& world) {
    if (static_cast<size_t>(node.mesh) >= model_.meshes.size())
      problem("node " + std::to_string(index) + ": mesh " + std::to_string(node.mesh) +
              " does not exist");
    const std::vector<uint32_t>& meshes = meshesOf(node.mesh);
    if (meshes.empty()) return;
    const uint32_t object_id = next_object_id_++;
    const std::string name = node.name.empty() ? "node" + std::to_string(index) : node.name;
    glm::mat4 transform(1.0f);
    if (!toFloatTransform(world, transform))
      problem("node " + std::to_string(index) + ": world transform exceeds float range");
    addNodeInstances(scene_, meshes, transform, object_id, name);
  }

  // The strata meshes (one per triangle primitive) of glTF mesh `gltf_mesh`, built on first use
  // and shared by every node that references it.
  const std::vector<uint32_t>& meshesOf(int gltf_mesh) {
    auto [it, inserted] = mesh_cache_.try_emplace(gltf_mesh);
    if (!inserted) return it->second;
    const tinygltf::Mesh& gm = model_.meshes[static_cast<size_t>(gltf_mesh)];
    if (gm.primitives.empty())
      scene_.report.warnings.push_back("mesh " + std::to_string(gltf_mesh) +
                                       " has no (readable) primitives");
    for (size_t p = 0; p < gm.primitives.size(); ++p) {
      const std::string what =
          "mesh " + std::to_string(gltf_mesh) + " primitive " + std::to_string(p);
      Mesh mesh;
      if (!buildPrimitive(gm.primitives[p], what, mesh)) continue;
      mesh.name = (gm.name.empty() ? "mesh" + std::to_string(gltf_mesh) : gm.name) + "#" +
                  std::to_string(p);
      mesh.material = materialFor(gm.primitives[p].material, !mesh.texcoords.empty(), what);
      it->second.push_back(static_cast<uint32_t>(scene_.meshes.size()));
      scene_.meshes.push_back(std::move(mesh));
    }
    return it->second;
  }

  bool buildPrimitive(const tinygltf::Primitive& prim, const std::string& what, Mesh& mesh) {
    const int mode = prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN) {
      scene_.report.warnings.push_back(what + ": mode " + std::to_string(mode) +
                                       " (points or lines) skipped");
      return false;
    }
    if (prim.extensions.count("KHR_draco_mesh_compression")) {
      scene_.report.warnings.push_back(what + ": Draco-compressed primitive skipped");
      return false;
    }
    const auto position = prim.attributes.find("POSITION");
    if (position == prim.attributes.end()) {
      scene_.report.warnings.push_back(what + ": no POSITION attribute; skipped");
      return false;
    }
    // Read in the order POSITION, TEXCOORD_0, indices (the order their errors are reported).
    PrimitiveRows rows;
    rows.positions = readAccessor(model_, position->second, TINYGLTF_TYPE_VEC3,
                                  {TINYGLTF_COMPONENT_TYPE_FLOAT}, what + " POSITION");
    const auto texcoord = prim.attributes.find("TEXCOORD_0");
    if (texcoord != prim.attributes.end())
      rows.texcoords =
          readAccessor(model_, texcoord->second, TINYGLTF_TYPE_VEC2,
                       {TINYGLTF_COMPONENT_TYPE_FLOAT, TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE,
                        TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT},
                       what + " TEXCOORD_0");
    if (prim.indices >= 0)
      rows.indices = readAccessor(
          model_, prim.indices, TINYGLTF_TYPE_SCALAR,
          {TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE, TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT,
           TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT},
          what + " indices");
    buildTriangleMesh(
        mode, rows, what, [this](const std::string& w) { scene_.report.warnings.push_back(w); },
        mesh);
    return true;
  }

  // The strata material of glTF material `gltf_material` for a primitive with (has_uv) or
  // without TEXCOORD_0. A textured material used by a primitive without texture coordinates is
  // drawn untextured there (a second strata material, with a warning) instead of sampling one
  // texel everywhere; glTF requires TEXCOORD_0 in that case, so this only meets broken files.
  uint32_t materialFor(int gltf_material, bool has_uv, const std::string& primitive) {
    bool textured = false;
    if (gltf_material >= 0 && static_cast<size_t>(gltf_material) < model_.materials.size())
      textured = model_.materials[static_cast<size_t>(gltf_material)]
                     .pbrMetallicRoughness.baseColorTexture.index >= 0;
    const bool variant_uv = textured ? has_uv : true;
    auto [it, inserted] = material_cache_.try_emplace({gltf_material, variant_uv}, 0u);
    if (!inserted) return it->second;
    Material material;
    if (gltf_material < 0) {
      material.name = "default";
    } else {
      if (static_cast<size_t>(gltf_material) >= model_.materials.size())
        problem("material " + std::to_string(gltf_material) + " does not exist");
      const tinygltf::Material& gm = model_.materials[static_cast<size_t>(gltf_material)];
      material.name = gm.name.empty() ? "material" + std::to_string(gltf_material) : gm.name;
      const auto& pbr = gm.pbrMetallicRoughness;
      if (pbr.baseColorFactor.size() == 4) {
        // The spec bounds each factor to [0, 1]; clamping keeps a bad file's colour meaningful.
        for (int c = 0; c < 4; ++c) {
          const double f = pbr.baseColorFactor[static_cast<size_t>(c)];
          material.color[c] = std::isfinite(f) ? static_cast<float>(std::clamp(f, 0.0, 1.0)) : 1.0f;
        }
      }
      if (gm.alphaMode == "BLEND") material.opacity = material.color.a;
      material.base_color_texture = textureName(pbr.baseColorTexture.index);
      applyBaseColorTexture(pbr.baseColorTexture, gltf_material, material);
      if (material.texture >= 0 && !variant_uv) {
        material.texture = -1;
        material.sampler = Sampler();
        scene_.report.warnings.push_back(primitive + ": material '" + material.name +
                                         "' has a base colour texture but the primitive has no "
                                         "TEXCOORD_0; drawn untextured");
      }
    }
    it->second = static_cast<uint32_t>(scene_.materials.size());
    scene_.materials.push_back(std::move(material));
    return it->second;
  }

  std::string textureName(int texture) {
    if (texture < 0) return {};
    if (static_cast<size_t>(texture) >= model_.textures.size())
      problem("texture " + std::to_string(texture) + " does not exist");
    const int source = model_.textures[static_cast<size_t>(texture)].source;
    if (source < 0 || static_cast<size_t>(source) >= model_.images.size()) {
      scene_.report.warnings.push_back("texture " + std::to_string(texture) +
                                       " has no usable image source; ignored");
      return {};
    }
    const tinygltf::Image& image = model_.images[static_cast<size_t>(source)];
    if (image.uri.empty() || image.uri.rfind("data:", 0) == 0)
      return "embedded:" + std::to_string(source);
    return image.uri;
  }

  // Sets material.texture (the decoded image) and material.sampler from the base colour's
  // texture info. Only TEXCOORD_0 is read: another set leaves the material untextured, with a
  // warning. KHR_texture_transform is not applied (warning); the texture is used untransformed.
  void applyBaseColorTexture(const tinygltf::TextureInfo& info, int gltf_material,
                             Material& material) {
    if (info.index < 0) return;
    const std::string what =
        "material '" + material.name + "' (" + std::to_string(gltf_material) + ")";
    const tinygltf::Texture& texture = model_.textures[static_cast<size_t>(info.index)];
    if (texture.source < 0 || static_cast<size_t>(texture.source) >= model_.images.size())
      return;  // textureName warned
    if (info.texCoord != 0) {
      scene_.report.warnings.push_back(what + ": baseColorTexture uses TEXCOORD_" +
                                       std::to_string(info.texCoord) +
                                       "; only TEXCOORD_0 is read, so it is drawn untextured");
      return;
    }
    if (info.extensions.count("KHR_texture_transform"))
      scene_.report.warnings.push_back(what +
                                       ": KHR_texture_transform is not supported; the "
                                       "base colour texture is used untransformed");
    if (texture.sampler >= 0) {
      if (static_cast<size_t>(texture.sampler) >= model_.samplers.size())
        problem("texture " + std::to_string(info.index) + ": sampler " +
                std::to_string(texture.sampler) + " does not exist");
      material.sampler = samplerFrom(model_.samplers[static_cast<size_t>(texture.sampler)],
                                     "sampler " + std::to_string(texture.sampler));
    }
    material.texture = sceneTexture(texture.source);
  }

  // glTF sampler -> Sampler. Wrap: 10497 REPEAT, 33648 MIRRORED_REPEAT, 33071 CLAMP_TO_EDGE
  // (unset: REPEAT, the glTF default; another value: REPEAT with a warning). Filter (one filter
  // for magnification and minification, as the atlas sampler has): magFilter NEAREST (9728) ->
  // Nearest; else minFilter NEAREST_MIPMAP_LINEAR (9986) or LINEAR_MIPMAP_LINEAR (9987) ->
  // Trilinear; everything else (LINEAR, the *_MIPMAP_NEAREST ones, unset) -> Bilinear.
  Sampler samplerFrom(const tinygltf::Sampler& gs, const std::string& what) {
    auto wrap = [&](int mode, const char* axis) {
      switch (mode) {
        case TINYGLTF_TEXTURE_WRAP_REPEAT:
          return Wrap::Repeat;
        case TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT:
          return Wrap::MirroredRepeat;
        case TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE:
          return Wrap::Clamp;
        default:
          scene_.report.warnings.push_back(what + ": unknown " + axis + " " + std::to_string(mode) +
                                           "; REPEAT used");
          return Wrap::Repeat;
      }
    };
    Sampler s;
    s.wrap_s = wrap(gs.wrapS, "wrapS");
    s.wrap_t = wrap(gs.wrapT, "wrapT");
    if (gs.magFilter == TINYGLTF_TEXTURE_FILTER_NEAREST)
      s.filter = Filter::Nearest;
    else if (gs.minFilter == TINYGLTF_TEXTURE_FILTER_NEAREST_MIPMAP_LINEAR ||
             gs.minFilter == TINYGLTF_TEXTURE_FILTER_LINEAR_MIPMAP_LINEAR)
      s.filter = Filter::Trilinear;
    else
      s.filter = Filter::Bilinear;
    return s;
  }

  // The Scene::textures index of glTF image `index`, decoded on first use: every texture and
  // material that shows the same image shares one decoded copy. An image that cannot be decoded
  // (missing file, corrupt or truncated data, absurd size) fails the load with a message naming
  // the image, like any other bad data in the asset: a renderer must not drop a texture silently.
  int32_t sceneTexture(int index) {
    auto [it, inserted] = texture_cache_.try_emplace(index, -1);
    if (!inserted) return it->second;
    const tinygltf::Image& image = model_.images[static_cast<size_t>(index)];
    // tinygltf keeps the URI of external files only: an image with neither a URI nor a
    // bufferView came from a data: URI.
    const bool data_uri =
        image.uri.rfind("data:", 0) == 0 || (image.uri.empty() && image.bufferView < 0);
    std::string label = "image " + std::to_string(index);
    std::string name;
    if (image.bufferView >= 0) {
      label += " (bufferView " + std::to_string(image.bufferView) + ")";
    } else if (data_uri) {
      label += " (data: URI)";
    } else {
      label += " '" + image.uri + "'";
      name = image.uri;
    }
    if (name.empty()) name = image.name.empty() ? "image " + std::to_string(index) : image.name;

    std::shared_ptr<const TextureImage> decoded;
    try {
      if (image.bufferView >= 0) {
        const size_t length =
            static_cast<size_t>(image.bufferView) < model_.bufferViews.size()
                ? model_.bufferViews[static_cast<size_t>(image.bufferView)].byteLength
                : 0;
        const ByteRange bytes = viewRange(model_, image.bufferView, 0, length, 1, 1, label);
        decoded = loadTextureMemory(bytes.data, bytes.count, label);
      } else if (!image.image.empty()) {
        decoded = loadTextureMemory(image.image.data(), image.image.size(), label);
      } else if (data_uri) {
        problem(label + ": the data: URI holds no bytes");
      } else {
        problem(label + ": no such file in the asset's folder (or it cannot be read)");
      }
    } catch (const Error& e) {
      problem(e.what());  // names the image already
    }
    it->second = static_cast<int32_t>(scene_.textures.size());
    scene_.textures.push_back(SceneTexture{name, std::move(decoded)});
    return it->second;
  }

  const tinygltf::Model& model_;
  Scene& scene_;
  std::vector<uint8_t> state_;
  std::map<int, std::vector<uint32_t>> mesh_cache_;
  std::map<std::pair<int, bool>, uint32_t> material_cache_;  // (glTF material, has TEXCOORD_0)
  std::map<int, int32_t> texture_cache_;                     // glTF image -> Scene::textures
  uint32_t next_object_id_ = 0;
};

void appendLibraryWarnings(const std::string& text, LoadReport& report) {
  std::istringstream lines(text);
  std::string line;
  size_t added = 0;
  while (std::getline(lines, line)) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (added++ == kMaxLibraryWarnings) {
      report.warnings.push_back("(further tinygltf warnings omitted)");
      break;
    }
    report.warnings.push_back("tinygltf: " + firstLine(line));
  }
}

// The last non-blank line of a library message ("unknown error" when there is none).
std::string lastLine(const std::string& text) {
  const size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "unknown error";
  const size_t begin = text.find_last_of("\r\n", end);
  return firstLine(text.substr(begin == std::string::npos ? 0 : begin + 1));
}

// tinygltf reads glTF 2.0 only and reports a 1.0 file as some structural error; recognising
// the version gives the user the real reason.
bool looksLikeGltf1(const std::string& path, bool binary) {
  std::ifstream in(path, std::ios::binary);
  if (binary) {
    unsigned char header[8] = {};
    in.read(reinterpret_cast<char*>(header), sizeof header);
    return in && std::memcmp(header, "glTF", 4) == 0 && header[4] == 1 && header[5] == 0 &&
           header[6] == 0 && header[7] == 0;
  }
  std::string text(64 * 1024, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  for (size_t at = text.find("\"version\""); at != std::string::npos;
       at = text.find("\"version\"", at + 1)) {
    const size_t quote = text.find_first_not_of(" \t\r\n:", at + 9);
    if (quote != std::string::npos && text.compare(quote, 3, "\"1.") == 0) return true;
  }
  return false;
}

}  // namespace

Scene loadGltf(const std::string& path, bool binary) {
  AssetFolderGuard guard(path);
  tinygltf::TinyGLTF gltf;
  gltf.SetImageLoader(&keepImageBytes, nullptr);
  gltf.SetFsCallbacks(guard.callbacks());

  tinygltf::Model model;
  std::string err, warn;
  // An absolute path makes every URI probe start with the asset's folder, which is how the guard
  // tells the URI apart from tinygltf's fallback probe of the current directory.
  const bool ok = binary ? gltf.LoadBinaryFromFile(&model, &err, &warn, guard.assetFile())
                         : gltf.LoadASCIIFromFile(&model, &err, &warn, guard.assetFile());
  if (!guard.rejections().empty()) fail(path, guard.rejections().front());
  const bool version1 = ok ? model.asset.version.rfind("1.", 0) == 0 : looksLikeGltf1(path, binary);
  if (version1) fail(path, "glTF 1.0 is not supported (only glTF 2.0)");
  // Some failures (an image file of 0 bytes) leave `err` empty and say why in `warn`'s last line.
  if (!ok)
    fail(path, "cannot parse as " + std::string(binary ? "GLB" : "glTF") + ": " +
                   (err.find_first_not_of(" \t\r\n") == std::string::npos ? lastLine(warn)
                                                                          : firstLine(err)));

  Scene scene;
  scene.source = path;
  appendLibraryWarnings(warn, scene.report);
  for (const tinygltf::Buffer& buffer : model.buffers) {
    if (isAbsoluteReference(buffer.uri) && buffer.uri.rfind("data:", 0) != 0)
      fail(path, "buffer URI '" + buffer.uri + "' is absolute; only relative URIs are allowed");
  }
  for (const tinygltf::Image& image : model.images) {
    if (isAbsoluteReference(image.uri) && image.uri.rfind("data:", 0) != 0)
      fail(path, "image URI '" + image.uri + "' is absolute; only relative URIs are allowed");
  }

  try {
    GltfSceneBuilder(model, scene).build();
  } catch (const FormatProblem& p) {
    fail(path, p.message);
  }
  validateScene(scene);
  compactObjectIds(scene);  // validation may have removed instances
  return scene;
}

}  // namespace strata::loader
