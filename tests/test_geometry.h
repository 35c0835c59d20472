// World geometry built directly in tests (no scene, no loader): materials, triangles, quads,
// boxes and UV spheres, each wound counter-clockwise seen from outside (from +z for a quad)
// unless flipped.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/world_geometry.h"

namespace strata::test {

inline uint32_t addMaterial(WorldGeometry& g, glm::vec3 rgb, float opacity) {
  g.material_colors.emplace_back(rgb, opacity);
  return uint32_t(g.material_colors.size() - 1);
}

inline void addTriangle(WorldGeometry& g, uint32_t a, uint32_t b, uint32_t c, uint32_t material) {
  g.indices.insert(g.indices.end(), {a, b, c});
  g.triangle_material.push_back(material);
  g.triangle_object.push_back(0);
}

// Corners b..b+3 as two triangles: counter-clockwise, or clockwise with `flip`.
inline void addQuadCorners(WorldGeometry& g, uint32_t a, uint32_t b, uint32_t c, uint32_t d,
                           uint32_t material, bool flip) {
  if (flip) {
    addTriangle(g, a, c, b, material);
    addTriangle(g, a, d, c, material);
  } else {
    addTriangle(g, a, b, c, material);
    addTriangle(g, a, c, d, material);
  }
}

// An axis-aligned rectangle in the plane z.
inline void addQuad(WorldGeometry& g, float x0, float y0, float x1, float y1, float z,
                    uint32_t material, bool flip = false) {
  const uint32_t b = uint32_t(g.positions.size());
  g.positions.insert(g.positions.end(), {{x0, y0, z}, {x1, y0, z}, {x1, y1, z}, {x0, y1, z}});
  addQuadCorners(g, b, b + 1, b + 2, b + 3, material, flip);
}

// A closed box: 8 shared corners, 12 triangles.
inline void addBox(WorldGeometry& g, glm::vec3 lo, glm::vec3 hi, uint32_t material,
                   bool flip = false) {
  const uint32_t b = uint32_t(g.positions.size());
  for (int i = 0; i < 8; ++i)
    g.positions.emplace_back(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
  const uint32_t faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces)
    addQuadCorners(g, b + f[0], b + f[1], b + f[2], b + f[3], material, flip);
}

// A closed UV sphere (poles welded, seam shared), each point of the unit sphere placed by `at`.
template <class Place>
void addSphereAt(WorldGeometry& g, int slices, int stacks, uint32_t material, Place at) {
  const uint32_t base = uint32_t(g.positions.size());
  const float pi = 3.14159265358979f;
  g.positions.push_back(at(glm::vec3(0, 1, 0)));  // north pole
  for (int i = 1; i < stacks; ++i) {
    const float theta = pi * float(i) / float(stacks);
    for (int j = 0; j < slices; ++j) {
      const float phi = 2.0f * pi * float(j) / float(slices);
      g.positions.push_back(at(glm::vec3(std::sin(theta) * std::cos(phi), std::cos(theta),
                                         std::sin(theta) * std::sin(phi))));
    }
  }
  const uint32_t south = uint32_t(g.positions.size());
  g.positions.push_back(at(glm::vec3(0, -1, 0)));
  const auto ring = [&](int i, int j) {
    return base + 1 + uint32_t((i - 1) * slices + j % slices);
  };
  for (int j = 0; j < slices; ++j) addTriangle(g, base, ring(1, j + 1), ring(1, j), material);
  for (int i = 1; i + 1 < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      addTriangle(g, ring(i, j), ring(i, j + 1), ring(i + 1, j + 1), material);
      addTriangle(g, ring(i, j), ring(i + 1, j + 1), ring(i + 1, j), material);
    }
  for (int j = 0; j < slices; ++j)
    addTriangle(g, south, ring(stacks - 1, j), ring(stacks - 1, j + 1), material);
}

// The unit sphere transformed by `m`.
inline void addSphere(WorldGeometry& g, const glm::mat4& m, int slices, int stacks,
                      uint32_t material) {
  addSphereAt(g, slices, stacks, material,
              [&](glm::vec3 p) { return glm::vec3(m * glm::vec4(p, 1)); });
}

// Radius r around c.
inline void addSphere(WorldGeometry& g, glm::vec3 c, float r, int slices, int stacks,
                      uint32_t material) {
  addSphereAt(g, slices, stacks, material, [&](glm::vec3 p) { return c + r * p; });
}

// Layers of one quad stacked under the top-down view (test_support.h's orthoTopDown of kStackSize
// pixels, 2 x 2 world units): each layer one colour and opacity, in the plane z (the camera at
// z = 5 sees it at view distance 5 - z). The quad's corners lie off the pixel centres; pixel
// (kInsideX, kInsideY) is covered by every layer.
constexpr int kStackSize = 64;
constexpr float kStackX0 = -0.53f, kStackY0 = -0.45f, kStackX1 = 0.47f, kStackY1 = 0.55f;
constexpr int kInsideX = 30, kInsideY = 33;
struct StackedLayer {
  glm::vec3 color;
  float alpha;
  float z;
};
inline WorldGeometry stackedQuads(const std::vector<StackedLayer>& layers) {
  WorldGeometry g;
  for (const StackedLayer& l : layers)
    addQuad(g, kStackX0, kStackY0, kStackX1, kStackY1, l.z, addMaterial(g, l.color, l.alpha));
  return g;
}

// A value in [0, 1] as the image stores it.
inline uint8_t unorm8(double v) {
  return uint8_t(std::floor(std::clamp(v, 0.0, 1.0) * 255.0 + 0.5));
}

}  // namespace strata::test
