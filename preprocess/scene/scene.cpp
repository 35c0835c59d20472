#include "preprocess/scene/scene.h"

#include <algorithm>

namespace strata {

uint64_t Scene::triangleCount() const {
  if (out_of_core) return out_of_core->triangles;
  uint64_t n = 0;
  for (const Instance& inst : instances) n += meshes[inst.mesh].triangleCount();
  return n;
}

Bounds Scene::worldBounds() const {
  if (out_of_core) return out_of_core->bounds;
  Bounds b;
  for (const Instance& inst : instances) {
    for (const glm::vec3& p : meshes[inst.mesh].positions)
      b.extend(glm::vec3(inst.transform * glm::vec4(p, 1.0f)));
  }
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
  for (const Instance& inst : instances) {
    for (const glm::vec3& p : meshes[inst.mesh].positions) {
      glm::vec3 w(inst.transform * glm::vec4(p, 1.0f));
      glm::vec3 d = w - s.center;
      r2 = std::max(r2, glm::dot(d, d));
    }
  }
  s.radius = std::max(std::sqrt(r2), 1e-6f);
  return s;
}

}  // namespace strata
