// Procedural scenes that need no files: `builtin:demo`, `builtin:spheres:N`, `builtin:crowd:N`.
#pragma once

#include <string>
#include <vector>

#include "engine/scene.h"

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

}  // namespace strata
