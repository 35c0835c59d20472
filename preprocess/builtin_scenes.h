// Procedural scenes that need no files: `builtin:demo`, `builtin:spheres:N`, `builtin:crowd:N`,
// `builtin:textured:N`, and the massive ones of preprocess/massive_scenes.h (`builtin:hairball:N`,
// `builtin:city:N`, `builtin:shells:N`, `builtin:soup:N`).
#pragma once

#include <string>
#include <vector>

#include "preprocess/scene/scene.h"

namespace strata {

// Builds "builtin:NAME[:ARG]"; throws Error naming an unknown scene or a bad argument.
Scene makeBuiltinScene(const std::string& spec);

// Loads a scene from a file path or a builtin:NAME spec.
Scene loadScene(const std::string& spec);

// Mesh generators (also used by tests).
Mesh makeUvSphere(float radius, int slices, int stacks);
Mesh makeBox(glm::vec3 half_extent);
Mesh makeTorus(float major_radius, float minor_radius, int major_segments, int minor_segments);
Mesh makeCylinder(float radius, float half_height, int segments);

// Textured variants (texture coordinates per vertex; (0, 0) is the texture's top-left corner).
// A quad in the XY plane facing +Z, x in [-hx, hx], y in [-hy, hy]: its bottom-left corner gets
// (uv_min.x, uv_max.y), its top-right corner (uv_max.x, uv_min.y).
Mesh makeTexturedQuad(glm::vec2 half_size, glm::vec2 uv_min, glm::vec2 uv_max);
// A box with 24 vertices (each face its own four corners, so the texture does not wrap around
// edges); face_uv holds (u_min, v_min, u_max, v_max) for every face (one entry) or per face (six,
// in makeBox's face order: -Z, +Z, -Y, +Y, -X, +X).
Mesh makeTexturedBox(glm::vec3 half_extent, const std::vector<glm::vec4>& face_uv);
// makeUvSphere's shape with a seam (the first column repeated at u = uv_max.x) and one pole
// vertex per slice: u runs around the sphere from uv_min.x to uv_max.x, v from the north pole
// (uv_min.y) to the south pole (uv_max.y). 2 * slices * (stacks - 1) triangles.
Mesh makeTexturedUvSphere(float radius, int slices, int stacks, glm::vec2 uv_min, glm::vec2 uv_max);

// The procedural texture of builtin:textured's texture i (its size depends on i alone).
TextureImage makeProceduralTexture(int i);

}  // namespace strata
