// The scene flattened to one world-space triangle list: what every renderer (OpenCL methods and
// the Embree reference) consumes, so they all see the same triangles with the same ids.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/scene.h"

namespace strata {

// One instance's slice of the flattened geometry: its triangles and vertices are contiguous,
// in the mesh's own order, so per-mesh preprocessing (convex cells) applies to every instance.
struct GeometryPart {
  uint32_t mesh = 0;
  uint32_t first_triangle = 0, triangle_count = 0;
  uint32_t first_vertex = 0, vertex_count = 0;
  glm::mat4 transform{1.0f};  // object -> world
};

struct WorldGeometry {
  std::vector<glm::vec3> positions;  // world space
  std::vector<uint32_t> indices;     // three per triangle; triangle id = position / 3
  std::vector<uint32_t> triangle_material;
  std::vector<uint32_t> triangle_object;
  std::vector<glm::vec4> material_colors;  // RGB + effective opacity, per material
  std::vector<GeometryPart> parts;         // empty: the whole geometry is one part
  // The meshes once each, in object space (instancing): mesh m has vertices
  // [mesh_first_vertex[m], mesh_first_vertex[m + 1]) and triangles [mesh_first_triangle[m], ...)
  // with mesh-local indices; parts[i].mesh indexes them. Empty: not known (world space only).
  std::vector<glm::vec3> mesh_positions;
  std::vector<uint32_t> mesh_indices;
  std::vector<uint32_t> mesh_first_vertex, mesh_first_triangle;  // meshes + 1 entries each
  // Render-state bits per material (draw_state::, preprocess/scene/material_state.h): textured,
  // alpha mode, shader variant. Empty: derived from material_colors' alpha.
  std::vector<uint64_t> material_state;
  // Texturing (empty when no material is textured): per material the index into `textures` it
  // samples (-1: none) and its sampler; three texture coordinates per triangle, in corner order.
  std::vector<int32_t> material_texture;
  std::vector<Sampler> material_sampler;
  std::vector<glm::vec2> triangle_uv;
  std::vector<std::shared_ptr<const TextureImage>> textures;
  // Set for an out-of-core octree scene: the triangles above stay empty and live in the file.
  // The octree method streams them from it; other renderers read it whole first (inCore,
  // preprocess/octree_scene.h).
  std::shared_ptr<const OutOfCoreTriangles> out_of_core;

  uint32_t triangleCount() const { return uint32_t(indices.size() / 3); }
  bool textured() const { return !triangle_uv.empty(); }
  // The texture triangle t samples (-1: none).
  int32_t triangleTexture(uint32_t t) const {
    return textured() ? material_texture[triangle_material[t]] : -1;
  }

  // Flattens every instance into world space. alpha_override >= 0 replaces every material's
  // opacity.
  static WorldGeometry fromScene(const Scene& scene, float alpha_override = -1.0f);
};

// Throws Error naming the first inconsistency: a corner index past the vertices, per-triangle
// arrays of the wrong length, a material, texture or mesh index out of range, a part outside the
// geometry. Every renderer checks this before it reads anything (non-finite positions are
// allowed: the front end drops and counts their triangles, as the loaders do).
void validateWorldGeometry(const WorldGeometry& geometry);

// Flat-shaded colour of one triangle, the rule every renderer applies (kernels use the same
// constants from strata_shared.h): material colour times two-sided diffuse, alpha = opacity.
glm::vec4 shadeTriangle(const WorldGeometry& geo, uint32_t triangle, const glm::vec3& light_dir);

}  // namespace strata
