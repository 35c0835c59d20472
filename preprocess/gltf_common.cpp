// What the glTF 2.0 reader (gltf_loader.cpp, through tinygltf) and the glTF 1.0 reader
// (gltf1_loader.cpp, through nlohmann::json) share: accessor components and bounds, a triangle
// primitive's mesh from its accessors (strips and fans assembled), node transforms and
// instances, object ids and the confinement of URIs to the asset's folder. The two versions lay
// out their JSON differently but use the same GL enums, the same binary layout of accessors and
// the same primitive modes, so these pieces are written once.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "preprocess/loader_internal.h"

namespace strata::loader {

namespace fs = std::filesystem;

size_t gltfComponentSize(int component_type) {
  switch (component_type) {
    case gl::kByte:
    case gl::kUnsignedByte:
      return 1;
    case gl::kShort:
    case gl::kUnsignedShort:
      return 2;
    case gl::kUnsignedInt:
    case gl::kFloat:
      return 4;
    default:
      return 0;
  }
}

double readGltfComponent(const unsigned char* p, int component_type, bool normalized) {
  switch (component_type) {
    case gl::kFloat: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case gl::kUnsignedByte:
      return normalized ? *p / 255.0 : *p;
    case gl::kByte: {
      const int8_t v = static_cast<int8_t>(*p);
      return normalized ? std::max(v / 127.0, -1.0) : v;
    }
    case gl::kUnsignedShort: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0 : v;
    }
    case gl::kShort: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0, -1.0) : v;
    }
    case gl::kUnsignedInt: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
    default:
      return 0.0;
  }
}

bool elementsFit(uint64_t offset, uint64_t count, size_t element, size_t stride, size_t size) {
  if (count == 0) return true;
  // The last element starts at offset + (count - 1) * stride and ends `element` bytes later;
  // dividing instead of multiplying keeps every step inside the range of the types.
  return offset <= size && element <= size - offset &&
         (count - 1) <= (size - offset - element) / stride;
}

std::string describeElements(uint64_t count, size_t element, size_t stride, uint64_t offset) {
  return std::to_string(count) + " elements of " + std::to_string(element) + " bytes (stride " +
         std::to_string(stride) + ") at offset " + std::to_string(offset);
}

namespace {

// Appends to `indices` the triangles of the vertices in `order` for primitive mode `mode`;
// returns how many trailing indices of a TRIANGLES list form no triangle (not appended).
size_t assembleTriangles(int mode, const std::vector<uint32_t>& order,
                         std::vector<uint32_t>& indices) {
  if (mode == gl::kTriangles) {
    const size_t whole = order.size() / 3 * 3;
    indices.insert(indices.end(), order.begin(),
                   order.begin() + static_cast<std::ptrdiff_t>(whole));
    return order.size() - whole;
  }
  if (order.size() < 3) return 0;
  const size_t n = order.size() - 2;
  indices.reserve(indices.size() + 3 * n);
  for (size_t i = 0; i < n; ++i) {
    if (mode == gl::kTriangleStrip) {
      // glTF 2.0 spec, 3.7.2.1 (and 1.0, which follows GL): odd triangles swap their last two
      // corners to keep the winding.
      const bool odd = i % 2 == 1;
      indices.insert(indices.end(), {order[i], order[i + (odd ? 2 : 1)], order[i + (odd ? 1 : 2)]});
    } else {
      indices.insert(indices.end(), {order[i + 1], order[i + 2], order[0]});
    }
  }
  return 0;
}

}  // namespace

void buildTriangleMesh(int mode, const PrimitiveRows& rows, const std::string& what,
                       const std::function<void(const std::string&)>& warn, Mesh& mesh) {
  const std::vector<double>& xyz = rows.positions;
  const size_t vertex_count = xyz.size() / 3;
  mesh.positions.resize(vertex_count);
  for (size_t i = 0; i < vertex_count; ++i)
    mesh.positions[i] =
        glm::vec3(toFloat(xyz[3 * i]), toFloat(xyz[3 * i + 1]), toFloat(xyz[3 * i + 2]));

  if (rows.texcoords) {
    const std::vector<double>& uv = *rows.texcoords;
    if (uv.size() / 2 == vertex_count) {
      mesh.texcoords.resize(vertex_count);
      for (size_t i = 0; i < vertex_count; ++i)
        mesh.texcoords[i] = glm::vec2(toFloat(uv[2 * i]), toFloat(uv[2 * i + 1]));
    } else {
      warn(what + ": TEXCOORD_0 count differs from POSITION; texture coordinates ignored");
    }
  }

  std::vector<uint32_t> order;  // vertex order before the mode's assembly into triangles
  if (rows.indices) {
    const std::vector<double>& idx = *rows.indices;
    order.resize(idx.size());
    for (size_t i = 0; i < idx.size(); ++i) order[i] = static_cast<uint32_t>(idx[i]);
  } else {
    order.resize(vertex_count);
    for (size_t i = 0; i < vertex_count; ++i) order[i] = static_cast<uint32_t>(i);
  }
  if (const size_t trailing = assembleTriangles(mode, order, mesh.indices))
    warn(what + ": " + std::to_string(trailing) +
         " trailing indices do not form a triangle; ignored");
}

glm::dmat4 finiteTransform(const glm::dmat4& m, const std::string& what) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      if (!std::isfinite(m[c][r])) problem(what + ": transform is not finite");
  return m;
}

bool toFloatTransform(const glm::dmat4& world, glm::mat4& out) {
  for (int c = 0; c < 4; ++c) {
    for (int r = 0; r < 4; ++r) {
      out[c][r] = toFloat(world[c][r]);
      if (!std::isfinite(out[c][r])) return false;
    }
  }
  return true;
}

void addNodeInstances(Scene& scene, const std::vector<uint32_t>& meshes, const glm::mat4& transform,
                      uint32_t object_id, const std::string& name) {
  for (uint32_t m : meshes) {
    Instance inst;
    inst.mesh = m;
    inst.transform = transform;
    inst.object_id = object_id;
    inst.name = name;
    scene.instances.push_back(std::move(inst));
  }
}

void compactObjectIds(Scene& scene) {
  std::unordered_map<uint32_t, uint32_t> dense;
  for (Instance& inst : scene.instances) {
    auto [it, inserted] = dense.try_emplace(inst.object_id, static_cast<uint32_t>(dense.size()));
    inst.object_id = it->second;
  }
}

fs::path confinementFolder(const fs::path& folder) {
  std::error_code ec;
  fs::path canonical = fs::weakly_canonical(folder, ec);
  // On failure weakly_canonical returns an empty path, inside which isInsideFolder would find
  // everything; the folder as given still confines (a link inside it is then resolved against
  // the unresolved folder, which refuses more, not less).
  if (ec || canonical.empty()) canonical = folder;
  return canonical;
}

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

std::string percentDecode(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && hexValue(s[i + 1]) >= 0 && hexValue(s[i + 2]) >= 0) {
      out.push_back(static_cast<char>(hexValue(s[i + 1]) * 16 + hexValue(s[i + 2])));
      i += 2;
    } else {
      out.push_back(s[i]);
    }
  }
  return out;
}

std::string uriRefusal(const std::string& uri, const std::string& decoded, const fs::path& opened,
                       const fs::path& canonical_folder) {
  // A NUL byte in a message would cut what() short (tinygltf hands over the URI decoded, so a
  // "%00" arrives as a NUL byte): it is shown as %00.
  std::string shown;
  for (char c : uri) c == '\0' ? shown += "%00" : shown += c;
  const std::string absolute =
      "URI '" + shown + "' is absolute; only files in the asset's folder may be read";
  if (isAbsoluteReference(uri)) return absolute;
  if (decoded.find('\0') != std::string::npos) return "URI '" + shown + "' holds a NUL";
  if (isAbsoluteReference(decoded)) return absolute;
  // Symbolic links resolved: a link inside the folder that leads out of it is refused.
  std::error_code ec;
  const fs::path target = fs::weakly_canonical(opened, ec);
  if (ec || !isInsideFolder(canonical_folder, target))
    return "URI '" + shown + "' resolves outside the asset's folder; refused";
  return {};
}

}  // namespace strata::loader
