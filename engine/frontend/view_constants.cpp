#include "engine/frontend/view_constants.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include <glm/gtc/type_ptr.hpp>

namespace strata {

void validateFrameSize(int width, int height) {
  if (width <= 0 || height <= 0)
    throw Error("image size " + std::to_string(width) + "x" + std::to_string(height) +
                " is empty: width and height must be at least 1");
  if (width > ST_MAX_IMAGE_SIDE || height > ST_MAX_IMAGE_SIDE)
    throw Error("image size " + std::to_string(width) + "x" + std::to_string(height) +
                " is too large: the largest side supported is " +
                std::to_string(ST_MAX_IMAGE_SIDE));
}

bool updateViewConstants(StViewConstants& current, const FrameSettings& frame) {
  StViewConstants v = makeViewConstants(frame);
  v.textured = current.textured;
  if (std::memcmp(&v, &current, sizeof(v)) == 0) return false;
  current = v;
  return true;
}

StViewConstants makeViewConstants(const FrameSettings& s) {
  StViewConstants v;
  std::memset(&v, 0, sizeof(v));
  const Camera& cam = s.camera;
  const float aspect = float(s.width) / float(s.height);
  const glm::mat4 vp = cam.projectionMatrix(aspect) * cam.viewMatrix();
  std::memcpy(v.view_proj, glm::value_ptr(vp), sizeof(v.view_proj));
  const glm::vec3 fwd = cam.forward();
  v.view_row[0] = fwd.x;
  v.view_row[1] = fwd.y;
  v.view_row[2] = fwd.z;
  v.view_row[3] = -glm::dot(fwd, cam.eye);
  const glm::vec3 l = cam.lightDirection();
  v.light_dir[0] = l.x;
  v.light_dir[1] = l.y;
  v.light_dir[2] = l.z;
  for (int c = 0; c < 3; ++c) {
    v.background[c] = s.background.color[c];
    v.background2[c] = s.background.color2[c];
  }
  v.background[3] = v.background2[3] = 1.0f;
  for (int k = 0; k < 2; ++k) {
    const float* c = k == 0 ? v.background : v.background2;
    v.background_rgba8[k] =
        st_to_unorm8(c[0]) | st_to_unorm8(c[1]) << 8 | st_to_unorm8(c[2]) << 16 | 0xFF000000u;
  }
  const glm::vec3 right = glm::normalize(glm::cross(fwd, cam.up));
  const glm::vec3 cam_up = glm::cross(right, fwd);
  for (int c = 0; c < 3; ++c) {
    v.eye[c] = cam.eye[c];
    v.forward[c] = fwd[c];
    v.right[c] = right[c];
    v.up[c] = cam_up[c];
  }
  if (cam.projection == Projection::Perspective) {
    const float t = std::tan(glm::radians(cam.fov_y_deg) * 0.5f);
    v.ray_tan[0] = t * aspect;
    v.ray_tan[1] = t;
  } else {
    v.ray_tan[2] = cam.ortho_height * 0.5f * aspect;
    v.ray_tan[3] = cam.ortho_height * 0.5f;
  }
  v.effect = s.effect == Effect::Translucency ? ST_EFFECT_TRANSLUCENCY : ST_EFFECT_TRANSPARENCY;
  v.sigma = s.sigma;
  v.width = s.width;
  v.height = s.height;
  v.near_distance = cam.near_distance;
  v.projection =
      cam.projection == Projection::Perspective ? ST_PROJ_PERSPECTIVE : ST_PROJ_ORTHOGRAPHIC;
  v.background_kind = s.background.checker ? ST_BACKGROUND_CHECKER : ST_BACKGROUND_SOLID;
  return v;
}

glm::ivec4 boxPixelRect(const glm::vec3& lo, const glm::vec3& hi, const StViewConstants& v) {
  const glm::ivec4 full(0, 0, v.width - 1, v.height - 1);
  if (!std::isfinite(lo.x) || !std::isfinite(lo.y) || !std::isfinite(lo.z) ||
      !std::isfinite(hi.x) || !std::isfinite(hi.y) || !std::isfinite(hi.z))
    return full;
  float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
  for (int c = 0; c < 8; ++c) {
    const glm::vec3 p((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
    const float* m = v.view_proj;  // column-major
    const float cx = m[0] * p.x + m[4] * p.y + m[8] * p.z + m[12];
    const float cy = m[1] * p.x + m[5] * p.y + m[9] * p.z + m[13];
    const float cw = m[3] * p.x + m[7] * p.y + m[11] * p.z + m[15];
    const float d = v.view_row[0] * p.x + v.view_row[1] * p.y + v.view_row[2] * p.z + v.view_row[3];
    if (!(d > v.near_distance) || !(cw > 0.0f)) return full;
    const float px = (cx / cw * 0.5f + 0.5f) * float(v.width);
    const float py = (0.5f - cy / cw * 0.5f) * float(v.height);
    x0 = std::min(x0, px);
    x1 = std::max(x1, px);
    y0 = std::min(y0, py);
    y1 = std::max(y1, py);
  }
  if (!(x1 >= -2.0f && y1 >= -2.0f && x0 <= float(v.width) + 2.0f && y0 <= float(v.height) + 2.0f))
    return glm::ivec4(INT32_MAX, INT32_MAX, -1, -1);  // off the image (or not a number)
  return glm::ivec4(int(std::max(0.0f, std::floor(x0) - 2.0f)),
                    int(std::max(0.0f, std::floor(y0) - 2.0f)),
                    int(std::min(float(v.width - 1), std::ceil(x1) + 2.0f)),
                    int(std::min(float(v.height - 1), std::ceil(y1) + 2.0f)));
}

}  // namespace strata
