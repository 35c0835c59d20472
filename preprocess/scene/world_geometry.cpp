#include "preprocess/scene/world_geometry.h"

#include "kernels/strata_shared.h"
#include "preprocess/scene/material_state.h"

namespace strata {

WorldGeometry WorldGeometry::fromScene(const Scene& scene, float alpha_override) {
  WorldGeometry g;
  for (const Material& m : scene.materials) {
    const float a = alpha_override >= 0.0f ? alpha_override : m.opacity;
    g.material_colors.emplace_back(glm::vec3(m.color), a);
    uint64_t state = draw_state::kTwoSided;  // every method shades both sides
    if (m.texture >= 0) state |= draw_state::kTextured;
    if (a < 1.0f) state |= draw_state::kAlphaBlend | draw_state::kTransparent;
    state |= uint64_t(m.shader_variant & 0xFFFFu) << draw_state::kKernelVariantShift;
    g.material_state.push_back(state);
  }
  if (g.material_colors.empty()) {
    g.material_colors.emplace_back(0.8f, 0.8f, 0.8f, kDefaultOpacity);
    g.material_state.push_back(draw_state::kTwoSided | draw_state::kAlphaBlend |
                               draw_state::kTransparent);
  }
  // Texturing: only materials whose texture decoded; triangle_uv only when one exists.
  bool any_textured = false;
  for (const SceneTexture& t : scene.textures) g.textures.push_back(t.image);
  for (const Material& m : scene.materials) {
    const bool ok = m.texture >= 0 && size_t(m.texture) < scene.textures.size() &&
                    scene.textures[size_t(m.texture)].image;
    g.material_texture.push_back(ok ? m.texture : -1);
    g.material_sampler.push_back(m.sampler);
    any_textured |= ok;
  }
  if (!any_textured) {
    g.material_texture.clear();
    g.material_sampler.clear();
    g.textures.clear();
  } else if (g.material_texture.empty()) {
    g.material_texture.push_back(-1);
    g.material_sampler.emplace_back();
  }
  g.out_of_core = scene.out_of_core;
  g.mesh_first_vertex.push_back(0);
  g.mesh_first_triangle.push_back(0);
  for (const Mesh& mesh : scene.meshes) {
    g.mesh_positions.insert(g.mesh_positions.end(), mesh.positions.begin(), mesh.positions.end());
    g.mesh_indices.insert(g.mesh_indices.end(), mesh.indices.begin(), mesh.indices.end());
    g.mesh_first_vertex.push_back(uint32_t(g.mesh_positions.size()));
    g.mesh_first_triangle.push_back(uint32_t(g.mesh_indices.size() / 3));
  }
  const uint64_t total = scene.triangleCount();
  g.indices.reserve(total * 3);
  g.triangle_material.reserve(total);
  g.triangle_object.reserve(total);
  for (const Instance& inst : scene.instances) {
    const Mesh& mesh = scene.meshes[inst.mesh];
    const uint32_t base = uint32_t(g.positions.size());
    g.parts.push_back({inst.mesh, g.triangleCount(), uint32_t(mesh.triangleCount()), base,
                       uint32_t(mesh.positions.size()), inst.transform});
    for (const glm::vec3& p : mesh.positions)
      g.positions.emplace_back(inst.transform * glm::vec4(p, 1.0f));
    for (uint32_t i : mesh.indices) g.indices.push_back(base + i);
    const uint32_t mat = mesh.material < g.material_colors.size() ? mesh.material : 0;
    g.triangle_material.insert(g.triangle_material.end(), mesh.triangleCount(), mat);
    g.triangle_object.insert(g.triangle_object.end(), mesh.triangleCount(), inst.object_id);
    if (any_textured) {
      const bool has_uv = mesh.texcoords.size() == mesh.positions.size();
      for (uint32_t i : mesh.indices)
        g.triangle_uv.push_back(has_uv && i < mesh.texcoords.size() ? mesh.texcoords[i]
                                                                    : glm::vec2(0.0f));
    }
  }
  return g;
}

glm::vec4 shadeTriangle(const WorldGeometry& geo, uint32_t t, const glm::vec3& light_dir) {
  const glm::vec3 a = geo.positions[geo.indices[3 * t]];
  const glm::vec3 b = geo.positions[geo.indices[3 * t + 1]];
  const glm::vec3 c = geo.positions[geo.indices[3 * t + 2]];
  glm::vec3 n = glm::cross(b - a, c - a);
  const float len = glm::length(n);
  n = len > 0.0f ? n / len : glm::vec3(0.0f);
  const glm::vec4 m = geo.material_colors[geo.triangle_material[t]];
  const float k = st_diffuse_factor(glm::dot(n, light_dir));
  return {glm::vec3(m) * k, m.a};
}

namespace {

[[noreturn]] void invalid(const std::string& what) { throw Error("invalid geometry: " + what); }

void checkLength(size_t have, size_t want, const char* what, const char* per) {
  if (have != want)
    invalid(std::string(what) + " has " + std::to_string(have) + " entries, expected " +
            std::to_string(want) + " (" + per + ")");
}

void checkIndices(const std::vector<uint32_t>& indices, size_t first, size_t count, size_t limit,
                  const char* what) {
  for (size_t i = first; i < first + count; ++i)
    if (indices[i] >= limit)
      invalid(std::string(what) + " " + std::to_string(i) + " is " + std::to_string(indices[i]) +
              ", past the " + std::to_string(limit) + " vertices");
}

}  // namespace

void validateWorldGeometry(const WorldGeometry& g) {
  if (g.indices.size() % 3 != 0)
    invalid(std::to_string(g.indices.size()) + " corner indices is not three per triangle");
  const size_t triangles = g.indices.size() / 3;
  if (triangles > UINT32_MAX / 4 || g.positions.size() > UINT32_MAX / 4)
    invalid("more than " + std::to_string(UINT32_MAX / 4) + " triangles or vertices");
  checkIndices(g.indices, 0, g.indices.size(), g.positions.size(), "corner index");
  checkLength(g.triangle_material.size(), triangles, "triangle_material", "one per triangle");
  if (!g.triangle_object.empty())
    checkLength(g.triangle_object.size(), triangles, "triangle_object",
                "one per triangle, or none");
  const size_t materials = g.material_colors.size();
  for (size_t t = 0; t < triangles; ++t)
    if (g.triangle_material[t] >= materials)
      invalid("triangle " + std::to_string(t) + " has material " +
              std::to_string(g.triangle_material[t]) + ", past the " + std::to_string(materials) +
              " material colours");
  if (!g.material_state.empty())
    checkLength(g.material_state.size(), materials, "material_state", "one per material, or none");
  if (g.textured()) {
    checkLength(g.triangle_uv.size(), triangles * 3, "triangle_uv", "three per triangle");
    checkLength(g.material_texture.size(), materials, "material_texture", "one per material");
    checkLength(g.material_sampler.size(), materials, "material_sampler", "one per material");
    for (size_t m = 0; m < materials; ++m) {
      const int32_t t = g.material_texture[m];
      if (t < -1 || t >= int32_t(g.textures.size()) || (t >= 0 && !g.textures[size_t(t)]))
        invalid("material " + std::to_string(m) + " samples texture " + std::to_string(t) +
                ", but " + std::to_string(g.textures.size()) + " textures are given");
    }
  }
  // The mesh pool is there when it has positions (world-space-only geometry leaves it empty).
  const size_t meshes =
      g.mesh_positions.empty() || g.mesh_first_vertex.empty() ? 0 : g.mesh_first_vertex.size() - 1;
  if (!g.mesh_positions.empty()) {
    checkLength(g.mesh_first_triangle.size(), meshes + 1, "mesh_first_triangle", "meshes + 1");
    if (g.mesh_first_vertex.empty() || g.mesh_first_vertex.back() != g.mesh_positions.size() ||
        g.mesh_first_triangle.back() * size_t(3) != g.mesh_indices.size())
      invalid("the mesh offsets do not cover mesh_positions and mesh_indices");
    for (size_t m = 0; m < meshes; ++m) {
      if (g.mesh_first_vertex[m] > g.mesh_first_vertex[m + 1] ||
          g.mesh_first_triangle[m] > g.mesh_first_triangle[m + 1])
        invalid("the offsets of mesh " + std::to_string(m) + " decrease");
      checkIndices(g.mesh_indices, size_t(g.mesh_first_triangle[m]) * 3,
                   size_t(g.mesh_first_triangle[m + 1] - g.mesh_first_triangle[m]) * 3,
                   g.mesh_first_vertex[m + 1] - g.mesh_first_vertex[m], "mesh-local corner index");
    }
  }
  for (size_t i = 0; i < g.parts.size(); ++i) {
    const GeometryPart& p = g.parts[i];
    if (size_t(p.first_triangle) + p.triangle_count > triangles ||
        size_t(p.first_vertex) + p.vertex_count > g.positions.size())
      invalid("part " + std::to_string(i) + " reaches past the geometry");
    if (meshes > 0 && p.mesh >= meshes)
      invalid("part " + std::to_string(i) + " is an instance of mesh " + std::to_string(p.mesh) +
              ", past the " + std::to_string(meshes) + " meshes");
    checkIndices(g.indices, size_t(p.first_triangle) * 3, size_t(p.triangle_count) * 3,
                 size_t(p.first_vertex) + p.vertex_count, "corner index");
    for (size_t c = size_t(p.first_triangle) * 3;
         c < size_t(p.first_triangle + p.triangle_count) * 3; ++c)
      if (g.indices[c] < p.first_vertex)
        invalid("corner index " + std::to_string(c) + " of part " + std::to_string(i) +
                " points before the part's vertices");
  }
}

}  // namespace strata
