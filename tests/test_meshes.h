// Meshes for the preprocessing tests: a model's meshes as one, a MeshView of a Mesh, and meshes
// unwelded, moved and concatenated.
#pragma once

#include <string>

#include "preprocess/mesh_loader.h"
#include "preprocess/mesh_view.h"
#include "preprocess/scene/scene.h"
#include "test_support.h"

namespace strata::test {

inline MeshView view(const Mesh& m) {
  MeshView v;
  v.positions = m.positions.data();
  v.vertex_count = m.positions.size();
  v.indices = m.indices.data();
  v.triangle_count = m.triangleCount();
  return v;
}

// b's triangles appended to a's.
inline Mesh concat(const Mesh& a, const Mesh& b) {
  Mesh out = a;
  const uint32_t base = uint32_t(out.positions.size());
  out.positions.insert(out.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t i : b.indices) out.indices.push_back(base + i);
  return out;
}

// The shared model's meshes concatenated (object space; the models are single meshes).
inline Mesh loadMesh(const std::string& name) {
  const Scene s = loadSceneFile(modelPath(name));
  Mesh out;
  for (const Mesh& m : s.meshes) out = concat(out, m);
  return out;
}

// Every corner its own vertex.
inline Mesh unweld(const Mesh& m) {
  Mesh out;
  for (uint32_t i : m.indices) {
    out.indices.push_back(uint32_t(out.positions.size()));
    out.positions.push_back(m.positions[i]);
  }
  return out;
}

inline Mesh translated(const Mesh& m, glm::vec3 d) {
  Mesh out = m;
  for (glm::vec3& p : out.positions) p += d;
  return out;
}

}  // namespace strata::test
