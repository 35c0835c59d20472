// Camera: look-at and orbit around a bounding sphere, perspective or orthographic.
#pragma once

#include <glm/glm.hpp>

#include "preprocess/scene/scene.h"

namespace strata {

struct Camera {
  glm::vec3 eye{0.0f, 0.0f, 3.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  Projection projection = Projection::Perspective;
  float fov_y_deg = 40.0f;      // perspective
  float ortho_height = 2.0f;    // orthographic: world-space height of the view
  float near_distance = 0.01f;  // view-space distance of the near plane (both projections)

  static Camera lookAt(glm::vec3 eye, glm::vec3 target, glm::vec3 up = {0.0f, 1.0f, 0.0f});

  // Orbit around a sphere: azimuth around +Y (0 looks along -Z), elevation above the XZ plane.
  // Distance is in sphere radii; unset means auto-frame (the sphere just fits the view).
  static Camera orbit(const BoundingSphere& sphere, const OrbitView& view,
                      Projection projection = Projection::Perspective, float fov_y_deg = 40.0f);

  // The same camera turned by `degrees` of azimuth about the vertical (up) axis through the
  // target: distance and elevation kept. A moving camera's frame f is turned(f * step).
  Camera turned(float degrees) const;

  glm::vec3 forward() const { return glm::normalize(target - eye); }
  glm::mat4 viewMatrix() const;
  glm::mat4 projectionMatrix(float aspect) const;  // clip = P * V * world; clip.w = distance
  // Unit direction of the ray through pixel centre (x + 0.5, y + 0.5) and its origin.
  void pixelRay(int x, int y, int width, int height, glm::vec3& origin, glm::vec3& dir) const;
  // Direction towards the key light (a fixed offset from the view direction), shared by every
  // renderer so images compare.
  glm::vec3 lightDirection() const;
};

}  // namespace strata
