#include "preprocess/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace strata {

uint64_t Scene::triangleCount() const {
  if (out_of_core) return out_of_core->triangles;
  uint64_t n = 0;
  for (const Instance& inst : instances) n += meshes[inst.mesh].triangleCount();
  return n;
}

namespace {

// Per mesh, the vertices some triangle uses. Vertices no triangle uses (those of triangles the
// loaders dropped, or stray ones) do not count: a far unused vertex must not frame the view nor
// size the octree.
std::vector<std::vector<uint32_t>> usedVertices(const Scene& scene) {
  std::vector<std::vector<uint32_t>> used(scene.meshes.size());
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    std::vector<bool> flag(mesh.positions.size(), false);
    for (uint32_t i : mesh.indices)
      if (i < flag.size()) flag[i] = true;
    for (uint32_t v = 0; v < flag.size(); ++v)
      if (flag[v]) used[m].push_back(v);
  }
  return used;
}

// Calls `visit` with every instance's world-space used vertex.
template <typename Visit>
void forEachUsedCorner(const Scene& scene, const std::vector<std::vector<uint32_t>>& used,
                       Visit&& visit) {
  for (const Instance& inst : scene.instances)
    for (uint32_t v : used[inst.mesh])
      visit(glm::vec3(inst.transform * glm::vec4(scene.meshes[inst.mesh].positions[v], 1.0f)));
}

Bounds usedBounds(const Scene& scene, const std::vector<std::vector<uint32_t>>& used) {
  Bounds b;
  forEachUsedCorner(scene, used, [&](const glm::vec3& p) { b.extend(p); });
  return b;
}

}  // namespace

Bounds Scene::worldBounds() const {
  if (out_of_core) return out_of_core->bounds;
  return usedBounds(*this, usedVertices(*this));
}

BoundingSphere Scene::boundingSphere() const {
  // Centre of the box and the farthest point from it: a tight-enough sphere for framing.
  if (out_of_core) return out_of_core->sphere;
  const std::vector<std::vector<uint32_t>> used = usedVertices(*this);
  const Bounds b = usedBounds(*this, used);
  BoundingSphere s;
  if (b.empty()) return s;
  s.center = b.center();
  float r2 = 0.0f;
  forEachUsedCorner(*this, used, [&](const glm::vec3& p) {
    const glm::vec3 d = p - s.center;
    r2 = std::max(r2, glm::dot(d, d));
  });
  s.radius = std::max(std::sqrt(r2), 1e-6f);
  return s;
}

}  // namespace strata
