#include "preprocess/scene/camera.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

namespace strata {

Camera Camera::lookAt(glm::vec3 eye, glm::vec3 target, glm::vec3 up) {
  Camera c;
  c.eye = eye;
  c.target = target;
  c.up = up;
  return c;
}

Camera Camera::orbit(const BoundingSphere& sphere, const OrbitView& view, Projection projection,
                     float fov_y_deg) {
  const float az = glm::radians(view.azimuth_deg);
  const float el = glm::radians(std::clamp(view.elevation_deg, -89.9f, 89.9f));
  const glm::vec3 dir(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
  const float fit = 1.0f / std::sin(glm::radians(fov_y_deg) * 0.5f);  // sphere fits the view
  const float dist_radii = view.distance_radii.value_or(fit * 1.05f);
  const float r = sphere.radius;
  Camera c;
  c.projection = projection;
  c.fov_y_deg = fov_y_deg;
  c.target = sphere.center;
  c.eye = sphere.center + dir * (dist_radii * r);
  c.up = {0.0f, 1.0f, 0.0f};
  c.ortho_height = 2.1f * r;
  // Near plane just in front of the sphere, but never at or behind the eye.
  c.near_distance = std::max((dist_radii - 1.02f) * r, 1e-3f * r);
  if (projection == Projection::Orthographic) {
    // An orthographic eye outside the sphere sees all of it regardless of distance.
    c.eye = sphere.center + dir * (std::max(dist_radii, 1.5f) * r);
    c.near_distance = std::max((std::max(dist_radii, 1.5f) - 1.02f) * r, 1e-3f * r);
    if (view.ortho_height) c.ortho_height = *view.ortho_height;
  }
  return c;
}

Camera Camera::turned(float degrees) const {
  Camera c = *this;
  if (degrees == 0.0f) return c;
  // Rotated in double precision about the axis through the target, so that many small steps
  // and one large one land on the same eye to float rounding.
  const glm::dvec3 axis = glm::normalize(glm::dvec3(up));
  const glm::dvec3 offset = glm::dvec3(eye) - glm::dvec3(target);
  const double a = glm::radians(double(degrees)), cs = std::cos(a), sn = std::sin(a);
  // Rodrigues' rotation formula.
  const glm::dvec3 r =
      offset * cs + glm::cross(axis, offset) * sn + axis * glm::dot(axis, offset) * (1.0 - cs);
  c.eye = glm::vec3(glm::dvec3(target) + r);
  return c;
}

glm::mat4 Camera::viewMatrix() const { return glm::lookAt(eye, target, up); }

glm::mat4 Camera::projectionMatrix(float aspect) const {
  // Rows x, y and w of a standard projection; row z is unused (depth is the view distance,
  // interpolated as (d/w)/(1/w)), so clip.z carries d itself.
  glm::mat4 p(0.0f);
  if (projection == Projection::Perspective) {
    const float f = 1.0f / std::tan(glm::radians(fov_y_deg) * 0.5f);
    p[0][0] = f / aspect;
    p[1][1] = f;
    p[2][2] = -1.0f;  // clip.z = -z_view = d
    p[2][3] = -1.0f;  // clip.w = -z_view = d
  } else {
    const float h = ortho_height * 0.5f;
    p[0][0] = 1.0f / (h * aspect);
    p[1][1] = 1.0f / h;
    p[2][2] = -1.0f;
    p[3][3] = 1.0f;
  }
  return p;
}

void Camera::pixelRay(int x, int y, int width, int height, glm::vec3& origin,
                      glm::vec3& dir) const {
  const float aspect = float(width) / float(height);
  const float ndc_x = ((x + 0.5f) / width) * 2.0f - 1.0f;
  const float ndc_y = 1.0f - ((y + 0.5f) / height) * 2.0f;
  const glm::vec3 fwd = forward();
  const glm::vec3 right = glm::normalize(glm::cross(fwd, up));
  const glm::vec3 cam_up = glm::cross(right, fwd);
  if (projection == Projection::Perspective) {
    const float t = std::tan(glm::radians(fov_y_deg) * 0.5f);
    origin = eye;
    dir = glm::normalize(fwd + right * (ndc_x * t * aspect) + cam_up * (ndc_y * t));
  } else {
    const float h = ortho_height * 0.5f;
    origin = eye + right * (ndc_x * h * aspect) + cam_up * (ndc_y * h);
    dir = fwd;
  }
}

glm::vec3 Camera::lightDirection() const {
  const glm::vec3 fwd = forward();
  const glm::vec3 right = glm::normalize(glm::cross(fwd, up));
  const glm::vec3 cam_up = glm::cross(right, fwd);
  // From the viewer, slightly up and to the left: faces toward the viewer are lit.
  return glm::normalize(-fwd + 0.5f * cam_up - 0.35f * right);
}

}  // namespace strata
