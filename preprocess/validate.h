// Triangle validation shared by every loader: drops triangles the renderer cannot draw and counts
// them in a LoadReport, so that nothing is lost silently.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/scene.h"

namespace strata {

// A triangle whose doubled area |(b - a) x (c - a)| is at most this fraction of its longest edge
// squared counts as zero-area. The ratio is the sine of the triangle's flattest angle, so it does
// not depend on the model's scale. Corners that were collinear before their coordinates were
// rounded to float come out at up to a few 1e-7 (seen in assimp's OBJ/regr01.obj), so the bound
// sits just above that; real meshes stay far above it (the shared test models' flattest
// triangles are at 7e-3).
inline constexpr double kDegenerateRelativeArea = 1e-6;

enum class TriangleFault { kNone, kOutOfRange, kNonFinite, kDegenerate };

// Classifies one triangle of `positions`; checks run in the order listed in TriangleFault so
// that each dropped triangle is counted once.
TriangleFault classifyTriangle(const std::vector<glm::vec3>& positions, uint32_t a, uint32_t b,
                               uint32_t c);

// Removes the triangles of `mesh` that classifyTriangle rejects (and a trailing partial
// triangle, counted as out of range), keeps the rest in order, and adds the counts to `report`
// (triangles_loaded included). Vertices are left as they are, used or not.
void validateMesh(Mesh& mesh, LoadReport& report);

// Validates every mesh of `scene`, then drops meshes left without triangles together with the
// instances that use them, so the renderer never sees an empty draw. Throws Error("<source>: no
// triangles ...") when nothing is left.
void validateScene(Scene& scene);

}  // namespace strata
