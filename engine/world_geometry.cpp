#include "engine/world_geometry.h"

#include "engine/draw_sort.h"
#include "kernels/strata_shared.h"

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

}  // namespace strata
