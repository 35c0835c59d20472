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

// Calls `visit` with every instance's world-space corner of a triangle. Vertices no triangle uses
// (those of triangles the loaders dropped, or simply stray ones) do not count: a far unused
// vertex must not frame the view nor size the octree.
template <typename Visit>
void forEachUsedCorner(const Scene& scene, Visit&& visit) {
  std::vector<std::vector<uint32_t>> used(scene.meshes.size());  // per mesh, made on first use
  std::vector<bool> made(scene.meshes.size(), false);
  for (const Instance& inst : scene.instances) {
    const Mesh& mesh = scene.meshes[inst.mesh];
    if (!made[inst.mesh]) {
      made[inst.mesh] = true;
      std::vector<bool> flag(mesh.positions.size(), false);
      for (uint32_t i : mesh.indices)
        if (i < flag.size()) flag[i] = true;
      for (uint32_t v = 0; v < flag.size(); ++v)
        if (flag[v]) used[inst.mesh].push_back(v);
    }
    for (uint32_t v : used[inst.mesh])
      visit(glm::vec3(inst.transform * glm::vec4(mesh.positions[v], 1.0f)));
  }
}

}  // namespace

Bounds Scene::worldBounds() const {
  if (out_of_core) return out_of_core->bounds;
  Bounds b;
  forEachUsedCorner(*this, [&](const glm::vec3& p) { b.extend(p); });
  return b;
}

BoundingSphere Scene::boundingSphere() const {
  // Centre of the box and the farthest point from it: a tight-enough sphere for framing.
  if (out_of_core) return out_of_core->sphere;
  Bounds b = worldBounds();
  BoundingSphere s;
  if (b.empty()) return s;
  s.center = b.center();
  float r2 = 0.0f;
  forEachUsedCorner(*this, [&](const glm::vec3& p) {
    const glm::vec3 d = p - s.center;
    r2 = std::max(r2, glm::dot(d, d));
  });
  s.radius = std::max(std::sqrt(r2), 1e-6f);
  return s;
}

}  // namespace strata
