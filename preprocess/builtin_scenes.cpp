#include "preprocess/builtin_scenes.h"

#include "preprocess/massive_scenes.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <memory>

#include <glm/gtc/matrix_transform.hpp>

#include "preprocess/core/hash.h"
#include "preprocess/core/numbers.h"
#include "preprocess/mesh_loader.h"

namespace strata {

namespace {
constexpr float kPi = 3.14159265358979f;
const char kPrefix[] = "builtin:";
}  // namespace

Mesh makeUvSphere(float radius, int slices, int stacks) {
  // Poles are single vertices, so the sphere is closed: 2 * slices * (stacks - 1) triangles.
  Mesh m;
  m.name = "sphere";
  m.positions.push_back({0.0f, radius, 0.0f});
  for (int i = 1; i < stacks; ++i) {
    const float phi = kPi * float(i) / float(stacks);
    for (int j = 0; j < slices; ++j) {
      const float theta = 2.0f * kPi * float(j) / float(slices);
      m.positions.push_back(radius * glm::vec3(std::sin(phi) * std::cos(theta), std::cos(phi),
                                               -std::sin(phi) * std::sin(theta)));
    }
  }
  m.positions.push_back({0.0f, -radius, 0.0f});
  const uint32_t south = uint32_t(m.positions.size() - 1);
  auto ring = [&](int i, int j) { return uint32_t(1 + (i - 1) * slices + (j % slices)); };
  for (int j = 0; j < slices; ++j)
    m.indices.insert(m.indices.end(), {0u, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i + 1 < stacks; ++i) {
    for (int j = 0; j < slices; ++j) {
      m.indices.insert(m.indices.end(), {ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      m.indices.insert(m.indices.end(), {ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  }
  for (int j = 0; j < slices; ++j)
    m.indices.insert(m.indices.end(), {ring(stacks - 1, j), south, ring(stacks - 1, j + 1)});
  return m;
}

Mesh makeBox(glm::vec3 h) {
  Mesh m;
  m.name = "box";
  for (int i = 0; i < 8; ++i)
    m.positions.push_back({(i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? h.z : -h.z});
  // Counter-clockwise seen from outside.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads)
    m.indices.insert(m.indices.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  return m;
}

Mesh makeTorus(float R, float r, int nu, int nv) {
  Mesh m;
  m.name = "torus";
  for (int i = 0; i < nu; ++i) {
    const float u = 2.0f * kPi * float(i) / float(nu);
    for (int j = 0; j < nv; ++j) {
      const float v = 2.0f * kPi * float(j) / float(nv);
      m.positions.push_back({(R + r * std::cos(v)) * std::cos(u), r * std::sin(v),
                             (R + r * std::cos(v)) * std::sin(u)});
    }
  }
  auto at = [&](int i, int j) { return uint32_t((i % nu) * nv + (j % nv)); };
  for (int i = 0; i < nu; ++i)
    for (int j = 0; j < nv; ++j) {
      m.indices.insert(m.indices.end(), {at(i, j), at(i, j + 1), at(i + 1, j + 1)});
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j + 1), at(i + 1, j)});
    }
  return m;
}

Mesh makeCylinder(float radius, float hh, int n) {
  // Closed: side quads plus two fan caps around centre vertices.
  Mesh m;
  m.name = "cylinder";
  for (int i = 0; i < n; ++i) {
    const float a = 2.0f * kPi * float(i) / float(n);
    m.positions.push_back({radius * std::cos(a), -hh, -radius * std::sin(a)});
    m.positions.push_back({radius * std::cos(a), hh, -radius * std::sin(a)});
  }
  const uint32_t bottom = uint32_t(m.positions.size()), top = bottom + 1;
  m.positions.push_back({0.0f, -hh, 0.0f});
  m.positions.push_back({0.0f, hh, 0.0f});
  for (int i = 0; i < n; ++i) {
    const uint32_t b0 = 2 * i, t0 = 2 * i + 1, b1 = 2 * ((i + 1) % n), t1 = b1 + 1;
    m.indices.insert(m.indices.end(), {b0, b1, t1, b0, t1, t0});
    m.indices.insert(m.indices.end(), {bottom, b1, b0, top, t0, t1});
  }
  return m;
}

Mesh makeTexturedQuad(glm::vec2 h, glm::vec2 uv_min, glm::vec2 uv_max) {
  Mesh m;
  m.name = "quad";
  m.positions = {{-h.x, -h.y, 0.0f}, {h.x, -h.y, 0.0f}, {h.x, h.y, 0.0f}, {-h.x, h.y, 0.0f}};
  m.texcoords = {
      {uv_min.x, uv_max.y}, {uv_max.x, uv_max.y}, {uv_max.x, uv_min.y}, {uv_min.x, uv_min.y}};
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

Mesh makeTexturedBox(glm::vec3 h, const std::vector<glm::vec4>& face_uv) {
  if (face_uv.size() != 1 && face_uv.size() != 6)
    throw Error("makeTexturedBox: give one texture-coordinate range or six (got " +
                std::to_string(face_uv.size()) + ")");
  Mesh m;
  m.name = "box";
  // makeBox's corners and faces (counter-clockwise seen from outside), four corners per face.
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (int f = 0; f < 6; ++f) {
    const glm::vec4 r = face_uv[face_uv.size() == 1 ? 0 : size_t(f)];
    const glm::vec2 uv[4] = {{r.x, r.w}, {r.z, r.w}, {r.z, r.y}, {r.x, r.y}};
    const uint32_t base = uint32_t(m.positions.size());
    for (int k = 0; k < 4; ++k) {
      const uint32_t i = quads[f][k];
      m.positions.push_back({(i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? h.z : -h.z});
      m.texcoords.push_back(uv[k]);
    }
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
  }
  return m;
}

Mesh makeTexturedUvSphere(float radius, int slices, int stacks, glm::vec2 uv_min,
                          glm::vec2 uv_max) {
  Mesh m;
  m.name = "sphere";
  // Rows 0 (north pole) .. stacks (south pole), slices + 1 columns each (the last repeats the
  // first position at u = uv_max.x); a pole row's vertex j sits at the middle of slice j.
  const int cols = slices + 1;
  for (int i = 0; i <= stacks; ++i) {
    const float phi = kPi * float(i) / float(stacks);
    const float v = uv_min.y + (uv_max.y - uv_min.y) * float(i) / float(stacks);
    for (int j = 0; j < cols; ++j) {
      const bool pole = i == 0 || i == stacks;
      const float fj = pole ? float(j) + 0.5f : float(j);
      const float theta = 2.0f * kPi * float(j % slices) / float(slices);
      if (i == 0)
        m.positions.push_back({0.0f, radius, 0.0f});
      else if (i == stacks)
        m.positions.push_back({0.0f, -radius, 0.0f});
      else
        m.positions.push_back(radius * glm::vec3(std::sin(phi) * std::cos(theta), std::cos(phi),
                                                 -std::sin(phi) * std::sin(theta)));
      m.texcoords.push_back({uv_min.x + (uv_max.x - uv_min.x) * fj / float(slices), v});
    }
  }
  auto at = [&](int i, int j) { return uint32_t(i * cols + j); };
  for (int j = 0; j < slices; ++j)
    m.indices.insert(m.indices.end(), {at(0, j), at(1, j), at(1, j + 1)});
  for (int i = 1; i + 1 < stacks; ++i)
    for (int j = 0; j < slices; ++j) {
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  for (int j = 0; j < slices; ++j)
    m.indices.insert(m.indices.end(), {at(stacks - 1, j), at(stacks, j), at(stacks - 1, j + 1)});
  return m;
}

namespace {

uint32_t addMaterial(Scene& s, const std::string& name, glm::vec3 color) {
  Material mat;
  mat.name = name;
  mat.color = glm::vec4(color, 1.0f);
  s.materials.push_back(mat);
  return uint32_t(s.materials.size() - 1);
}

void addObject(Scene& s, Mesh mesh, uint32_t material, const glm::mat4& transform,
               const std::string& name) {
  mesh.material = material;
  s.meshes.push_back(std::move(mesh));
  Instance inst;
  inst.mesh = uint32_t(s.meshes.size() - 1);
  inst.transform = transform;
  inst.object_id = uint32_t(s.instances.size());
  inst.name = name;
  s.instances.push_back(inst);
}

// Nested and interpenetrating transparent shapes: a sphere holding a box, a torus cutting the
// sphere's surface, a cylinder piercing both.
Scene makeDemo() {
  Scene s;
  s.source = "builtin:demo";
  const glm::mat4 I(1.0f);
  addObject(s, makeUvSphere(1.0f, 48, 24), addMaterial(s, "glass-blue", {0.35f, 0.55f, 0.95f}), I,
            "outer sphere");
  addObject(s, makeBox({0.4f, 0.4f, 0.4f}), addMaterial(s, "red", {0.95f, 0.3f, 0.25f}),
            glm::rotate(I, 0.6f, glm::normalize(glm::vec3(1.0f, 1.0f, 0.3f))), "inner box");
  addObject(s, makeTorus(1.0f, 0.22f, 64, 24), addMaterial(s, "amber", {0.98f, 0.75f, 0.2f}),
            glm::rotate(glm::translate(I, {0.25f, 0.1f, 0.0f}), 1.1f, glm::vec3(1.0f, 0.0f, 0.0f)),
            "torus");
  addObject(s, makeCylinder(0.18f, 1.5f, 40), addMaterial(s, "green", {0.3f, 0.85f, 0.4f}),
            glm::rotate(I, 0.9f, glm::vec3(0.0f, 0.0f, 1.0f)), "cylinder");
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

// The convex-cells paper's depth test: 4 columns (2 x 2) of UV spheres of 39,600 triangles,
// N/2 spheres deep along the viewing axis (Z), so the depth complexity at a pixel is up to N.
Scene makeSpheres(int layers) {
  Scene s;
  s.source = "builtin:spheres:" + std::to_string(layers);
  Mesh sphere = makeUvSphere(1.0f, 200, 100);  // 2 * 200 * 99 = 39,600 triangles
  sphere.material = 0;
  s.meshes.push_back(std::move(sphere));
  const glm::vec3 palette[4] = {
      {0.9f, 0.35f, 0.3f}, {0.3f, 0.75f, 0.4f}, {0.35f, 0.5f, 0.95f}, {0.95f, 0.8f, 0.3f}};
  const int depth = layers / 2;
  const float spacing = 2.2f;
  for (int c = 0; c < 4; ++c) {
    Material mat;
    mat.name = "column" + std::to_string(c);
    mat.color = glm::vec4(palette[c], 1.0f);
    s.materials.push_back(mat);
  }
  // Every sphere is its own mesh copy of the same geometry so each column has its own material.
  std::vector<Mesh> column_meshes(4, s.meshes[0]);
  s.meshes.clear();
  for (int c = 0; c < 4; ++c) {
    column_meshes[c].material = uint32_t(c);
    s.meshes.push_back(column_meshes[c]);
  }
  for (int c = 0; c < 4; ++c) {
    const float x = (c & 1) ? spacing * 0.5f : -spacing * 0.5f;
    const float y = (c & 2) ? spacing * 0.5f : -spacing * 0.5f;
    for (int k = 0; k < depth; ++k) {
      Instance inst;
      inst.mesh = uint32_t(c);
      const float z = (float(depth - 1) * 0.5f - float(k)) * spacing;
      inst.transform = glm::translate(glm::mat4(1.0f), {x, y, z});
      inst.object_id = uint32_t(s.instances.size());
      inst.name = "sphere c" + std::to_string(c) + " d" + std::to_string(k);
      s.instances.push_back(inst);
    }
  }
  // Default view: orthographic along the stacking axis, so every sphere of a column covers the
  // same pixels and the depth complexity there is N, as in the paper's test.
  const float half_length = float(depth) * spacing * 0.5f;
  const float bound_radius = std::sqrt(half_length * half_length + 2.0f * spacing * spacing);
  const float front_distance = (spacing * 1.15f) / std::tan(glm::radians(20.0f));
  OrbitView v;
  v.azimuth_deg = 0.0f;
  v.elevation_deg = 0.0f;
  v.distance_radii = (half_length + front_distance) / bound_radius;
  v.ortho_height = 2.0f * (spacing * 0.5f + 1.0f) * 1.08f;  // the 2x2 columns plus a margin
  s.default_view = v;
  s.default_projection = Projection::Orthographic;
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

// A 32-bit integer hash (deterministic scene variation).
uint32_t hashU32(uint32_t x) { return mixU32(x); }

// A crowd for batching and draw sorting: N instances of a few meshes (sphere, torus,
// box, cylinder) on a grid of 4 layers, each with its own rotation, non-uniform scale and one of
// 8 transparent materials (colours, opacities 0.35..0.6, shader variants 0..7 so the materials
// differ in render state). Meshes are per (shape, material), as a mesh carries its material, so
// every mesh has about N / 32 instances. Shapes and materials are hashed from the grid cell, so
// neighbours (and consecutive instances) differ.
Scene makeCrowd(int count) {
  Scene s;
  s.source = "builtin:crowd:" + std::to_string(count);
  struct Paint {
    const char* name;
    glm::vec3 color;
    float opacity;
  };
  const Paint paints[8] = {
      {"red", {0.92f, 0.3f, 0.25f}, 0.5f},   {"amber", {0.98f, 0.72f, 0.2f}, 0.4f},
      {"green", {0.3f, 0.82f, 0.4f}, 0.55f}, {"teal", {0.2f, 0.7f, 0.75f}, 0.35f},
      {"blue", {0.3f, 0.5f, 0.95f}, 0.6f},   {"violet", {0.65f, 0.4f, 0.9f}, 0.45f},
      {"pink", {0.95f, 0.5f, 0.7f}, 0.5f},   {"grey", {0.7f, 0.72f, 0.75f}, 0.4f}};
  for (uint32_t m = 0; m < 8; ++m) {
    Material mat;
    mat.name = paints[m].name;
    mat.color = glm::vec4(paints[m].color, 1.0f);
    mat.opacity = paints[m].opacity;
    mat.shader_variant = m;
    s.materials.push_back(mat);
  }
  const Mesh shapes[4] = {makeUvSphere(0.42f, 20, 10), makeTorus(0.3f, 0.11f, 24, 8),
                          makeBox({0.3f, 0.3f, 0.3f}), makeCylinder(0.2f, 0.38f, 16)};
  for (const Mesh& shape : shapes)
    for (uint32_t m = 0; m < 8; ++m) {
      Mesh mesh = shape;
      mesh.name = shape.name + "-" + paints[m].name;
      mesh.material = m;
      s.meshes.push_back(std::move(mesh));
    }
  const int layers = 4;
  const int per_layer = (count + layers - 1) / layers;
  const int side = std::max(1, int(std::ceil(std::sqrt(double(per_layer)))));
  const float spacing = 1.0f;
  auto unit = [&](uint32_t i, uint32_t salt) {
    return float(hashU32(i * 4u + salt) >> 8) / 16777216.0f;
  };
  for (int i = 0; i < count; ++i) {
    const int layer = i / per_layer, cell = i % per_layer;
    const int gx = cell % side, gz = cell / side;
    const uint32_t h = hashU32(uint32_t(i) * 2654435761u + 17u);
    const uint32_t shape = h % 4, paint = (h >> 8) % 8;
    const glm::vec3 centre((float(gx) - 0.5f * float(side - 1)) * spacing,
                           (float(layer) - 0.5f * float(layers - 1)) * spacing,
                           (float(gz) - 0.5f * float(side - 1)) * spacing);
    const glm::vec3 axis =
        glm::normalize(glm::vec3(unit(i, 0) - 0.5f, unit(i, 1) - 0.5f, unit(i, 2) - 0.5f) +
                       glm::vec3(0.0f, 0.01f, 0.0f));
    const float angle = 2.0f * kPi * unit(i, 3);
    const glm::vec3 scale(0.7f + 0.5f * unit(i, 4), 0.7f + 0.5f * unit(i, 5),
                          0.7f + 0.5f * unit(i, 6));
    Instance inst;
    inst.mesh = shape * 8 + paint;
    inst.transform =
        glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), centre), angle, axis), scale);
    inst.object_id = uint32_t(i);
    inst.name = shapes[shape].name + " " + std::to_string(i) + " (" + paints[paint].name + ")";
    s.instances.push_back(inst);
  }
  OrbitView v;
  v.azimuth_deg = 30.0f;
  v.elevation_deg = 35.0f;
  s.default_view = v;
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

// ---- builtin:textured:N ----------------------------------------------------------------------

// The first 16 textures: every size class (8x8 to 512x512, non-square, non-power-of-two; those
// with a side of 256 or more keep mip levels > 0 in the atlas) and every wrap pair and filter.
struct TextureSpec {
  int w, h;
  Wrap wrap_s, wrap_t;
  Filter filter;
};
constexpr Wrap R = Wrap::Repeat, M = Wrap::MirroredRepeat, C = Wrap::Clamp;
constexpr Filter kNear = Filter::Nearest, kBil = Filter::Bilinear, kTri = Filter::Trilinear;
const TextureSpec kFeatured[16] = {
    {512, 512, R, R, kTri},  // 0 floor, -1..2 (minified towards the horizon: 3 mip levels)
    {8, 8, C, C, kNear},     // 1 back wall, -0.5..1.5 (magnified, clamped past [0, 1])
    {13, 29, M, M, kBil},    // 2 front panel, [0, 1] (magnified)
    {64, 64, R, M, kNear},   // 3 sphere, u 0..2
    {512, 256, R, C, kTri},  // 4 side wall, u 0..2 at a grazing angle (2 mip levels)
    {100, 60, M, C, kBil},   // 5 panel, [0, 1]
    {48, 80, C, R, kTri},    // 6 panel, u -1..2
    {32, 8, C, M, kNear},    // 7 panel, -3..4
    {256, 256, R, R, kBil},  // 8 tall box, -0.5..1.5 (minified: 2 mip levels)
    {17, 17, M, R, kTri},    // 9 panel, v -1..2
    {128, 32, R, R, kNear},  // 10 high sphere, u -1..1
    {24, 40, C, C, kBil},    // 11 panel, -0.5..1.5
    {300, 260, M, M, kTri},  // 12 flat box, -0.5..1.5 (minified: 2 mip levels)
    {9, 15, R, M, kBil},     // 13 box, faces -3..4, [0, 1] and -1..2
    {40, 24, C, R, kNear},   // 14 gallery only
    {384, 256, M, C, kTri},  // 15 small sphere (minified: 2 mip levels)
};

TextureSpec textureSpec(int i) {
  if (i < 16) return kFeatured[i];
  // Small textures beyond the first 16, so thousands stay cheap (about 1,000 texels each).
  static const int sides[10] = {8, 11, 16, 20, 24, 31, 32, 40, 48, 64};
  const uint32_t h = hashU32(uint32_t(i) * 2654435761u + 101u);
  return {sides[h % 10], sides[(h >> 4) % 10], Wrap((h >> 8) % 3), Wrap((h >> 10) % 3),
          Filter((h >> 12) % 3)};
}

glm::vec3 hsv(float h, float s, float v) {
  h = (h - std::floor(h)) * 6.0f;
  const float c = v * s, x = c * (1.0f - std::abs(std::fmod(h, 2.0f) - 1.0f)), m = v - c;
  glm::vec3 rgb;
  if (h < 1.0f)
    rgb = {c, x, 0.0f};
  else if (h < 2.0f)
    rgb = {x, c, 0.0f};
  else if (h < 3.0f)
    rgb = {0.0f, c, x};
  else if (h < 4.0f)
    rgb = {0.0f, x, c};
  else if (h < 5.0f)
    rgb = {x, 0.0f, c};
  else
    rgb = {c, 0.0f, x};
  return rgb + m;
}

}  // namespace

// Texture i: a hue of its own (golden-ratio steps), a border in the complementary hue (so a
// neighbour's texels bleeding in through an atlas gutter show), a white marker at the top-left
// corner inside the border (so flips show), and one of four coarse patterns (features of about a
// quarter of the shorter side, so moderately minified faces stay readable) by i % 4: checkers,
// diagonal stripes, a gradient with grid lines, rings. Textures with i % 5 == 3 have their second
// colour at alpha 0.35 (everything else is alpha 1).
TextureImage makeProceduralTexture(int i) {
  const TextureSpec spec = textureSpec(i);
  const int w = spec.w, h = spec.h, lo = std::min(w, h);
  const float hue = 0.08f + 0.618034f * float(i);
  const glm::vec3 base = hsv(hue, 0.7f, 0.95f), dark = hsv(hue, 0.85f, 0.35f);
  const glm::vec3 border = hsv(hue + 0.5f, 1.0f, 1.0f);
  const float second_alpha = i % 5 == 3 ? 0.35f : 1.0f;
  const int b = std::max(1, lo / 32);      // border width
  const int marker = std::max(1, lo / 8);  // top-left marker side
  TextureImage im;
  im.width = w;
  im.height = h;
  im.texels.resize(size_t(w) * size_t(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      glm::vec4 c;
      if (x < b || y < b || x >= w - b || y >= h - b) {
        c = glm::vec4(border, 1.0f);
      } else if (x < b + marker && y < b + marker) {
        c = glm::vec4(1.0f);
      } else {
        bool second = false;
        glm::vec3 col = base;
        switch (i % 4) {
          case 0: {  // checkers, 4 across the shorter side
            const int cell = std::max(1, lo / 4);
            second = ((x / cell + y / cell) & 1) != 0;
            break;
          }
          case 1: {  // diagonal stripes
            const int period = std::max(2, lo / 3);
            second = ((x + 2 * y) / period) % 2 != 0;
            if (second) col = glm::mix(base, glm::vec3(1.0f), 0.6f);
            break;
          }
          case 2: {  // gradient (dark left, bright right, dimmer down) with grid lines
            const float fx = w > 1 ? float(x) / float(w - 1) : 0.0f;
            const float fy = h > 1 ? float(y) / float(h - 1) : 0.0f;
            col = glm::mix(dark, base, fx) * (1.0f - 0.4f * fy);
            const int gx = std::max(2, w / 4), gy = std::max(2, h / 4);
            const int lw = std::max(1, lo / 16);  // line width
            second = (x % gx < lw) || (y % gy < lw);
            if (second) col = glm::vec3(0.95f);
            break;
          }
          default: {  // rings around the centre
            const float dx = (float(x) + 0.5f) / float(w) - 0.5f;
            const float dy = (float(y) + 0.5f) / float(h) - 0.5f;
            second = int(std::sqrt(dx * dx + dy * dy) * 6.0f) % 2 != 0;
            break;
          }
        }
        if (second && i % 4 == 0) col = dark;
        if (second && i % 4 == 3) col = dark;
        c = glm::vec4(col, second ? second_alpha : 1.0f);
      }
      im.texels[size_t(y) * size_t(w) + size_t(x)] = c;
    }
  return im;
}

namespace {

// Textured materials: N textures of different sizes, one material each, plus one
// material sampling texture 1 (texture 0 when N = 1) with other wrap modes (an atlas places that
// texture twice) and one untextured material. Every object uses material (its slot) mod N:
//  - a floor (texture 0, 512x512, repeat, trilinear, coordinates -1..2: minified towards the
//    horizon), a back wall (texture 1, 8x8, clamp, nearest, -0.5..1.5: magnified) and a side wall
//    at a grazing angle (texture 4, 512x256, coordinates 0..2 along it);
//  - six overlapping panels between the viewer and the back wall (depth complexity 8 and more
//    with the walls, the gallery and the pillar), with coordinates in [0, 1] up to -3..4;
//  - boxes (a per-face mix of [0, 1], -1..2 and -3..4; the large textures at -0.5..1.5) and
//    spheres (u wrapping twice);
// Texel densities are chosen for the default view at 512x512: the textures that keep mip levels
// (a side of 256 or more) are minified, the small ones (level 0 only) at most about 2 texels per
// pixel, so nothing aliases badly.
//  - a gallery of N small quads in front of the back wall, one per material, so every texture
//    is on screen;
//  - an untextured pillar piercing the panels.
Scene makeTextured(int count) {
  Scene s;
  s.source = "builtin:textured:" + std::to_string(count);
  for (int i = 0; i < count; ++i) {
    const TextureSpec spec = textureSpec(i);
    SceneTexture tex;
    tex.name =
        "texture" + std::to_string(i) + "-" + std::to_string(spec.w) + "x" + std::to_string(spec.h);
    tex.image = std::make_shared<const TextureImage>(makeProceduralTexture(i));
    s.textures.push_back(std::move(tex));
    Material mat;
    mat.name = "textured" + std::to_string(i);
    mat.color = glm::vec4(1.0f);
    mat.texture = i;
    mat.sampler = {spec.wrap_s, spec.wrap_t, spec.filter};
    s.materials.push_back(mat);
  }
  const int shared_texture = count > 1 ? 1 : 0;
  const uint32_t shared_material = uint32_t(count), plain_material = uint32_t(count + 1);
  {
    Material mat;
    mat.name = "textured" + std::to_string(shared_texture) + "-mirrored";
    mat.color = glm::vec4(1.0f);
    mat.texture = shared_texture;
    mat.sampler = {Wrap::MirroredRepeat, Wrap::Repeat, Filter::Nearest};
    s.materials.push_back(mat);
    Material plain;
    plain.name = "untextured-green";
    plain.color = glm::vec4(0.3f, 0.85f, 0.4f, 1.0f);
    s.materials.push_back(plain);
  }
  const auto mat = [&](int slot) { return uint32_t(slot % count); };
  const glm::mat4 I(1.0f);
  const glm::vec3 X(1.0f, 0.0f, 0.0f), Y(0.0f, 1.0f, 0.0f), Z(0.0f, 0.0f, 1.0f);
  const auto deg = [](float d) { return glm::radians(d); };

  // Floor (y = 0, facing up), back wall (z = -4.6), side wall (x = -4.6, facing +x).
  addObject(s, makeTexturedQuad({5.0f, 5.0f}, {-1.0f, -1.0f}, {2.0f, 2.0f}), mat(0),
            glm::rotate(I, deg(-90.0f), X), "floor");
  addObject(s, makeTexturedQuad({4.2f, 1.7f}, {-0.5f, -0.5f}, {1.5f, 1.5f}), mat(1),
            glm::translate(I, {0.0f, 1.7f, -4.6f}), "back wall");
  addObject(s, makeTexturedQuad({4.4f, 1.3f}, {0.0f, 0.0f}, {2.0f, 1.0f}), mat(4),
            glm::rotate(glm::translate(I, {-4.6f, 1.3f, -0.2f}), deg(90.0f), Y), "side wall");

  // Six overlapping panels, front to back, each turned a little more about Y.
  const int panel_slots[6] = {2, 5, 7, 9, 11, 6};
  const glm::vec4 panel_uv[6] = {{0.0f, 0.0f, 1.0f, 1.0f},   {0.0f, 0.0f, 1.0f, 1.0f},
                                 {-3.0f, -3.0f, 4.0f, 4.0f}, {0.0f, -1.0f, 1.0f, 2.0f},
                                 {-0.5f, -0.5f, 1.5f, 1.5f}, {-1.0f, 0.0f, 2.0f, 1.0f}};
  for (int k = 0; k < 6; ++k) {
    const glm::vec3 centre(-0.9f + 0.3f * float(k), 1.35f + 0.08f * float(k),
                           2.4f - 0.62f * float(k));
    addObject(s,
              makeTexturedQuad({1.3f, 0.95f}, {panel_uv[k].x, panel_uv[k].y},
                               {panel_uv[k].z, panel_uv[k].w}),
              mat(panel_slots[k]),
              glm::rotate(glm::translate(I, centre), deg(8.0f + 4.0f * float(k)), Y),
              "panel " + std::to_string(k));
  }

  // Boxes: a per-face mix of ranges on a small texture, a tall and a flat one with large
  // textures (minified), and the shared texture's second sampler on a box at -3..4.
  const glm::vec4 unit(0.0f, 0.0f, 1.0f, 1.0f), wide(-3.0f, -3.0f, 4.0f, 4.0f),
      mid(-1.0f, -1.0f, 2.0f, 2.0f), half(-0.5f, -0.5f, 1.5f, 1.5f);
  addObject(
      s, makeTexturedBox({0.6f, 0.6f, 0.6f}, {wide, unit, mid, wide, unit, mid}), mat(13),
      glm::rotate(glm::rotate(glm::translate(I, {2.4f, 0.9f, 1.6f}), deg(30.0f), Y), deg(10.0f), X),
      "mixed box");
  addObject(s, makeTexturedBox({0.45f, 1.1f, 0.45f}, {half}), mat(8),
            glm::rotate(glm::translate(I, {3.1f, 1.12f, -2.4f}), deg(20.0f), Y),
            "tall box");  // clear of the floor: coplanar faces would z-fight
  addObject(s, makeTexturedBox({0.7f, 0.35f, 0.5f}, {half}), mat(12),
            glm::rotate(glm::translate(I, {-2.6f, 0.36f, 2.4f}), deg(-25.0f), Y), "flat box");
  addObject(s, makeTexturedBox({0.45f, 0.45f, 0.45f}, {wide}), shared_material,
            glm::rotate(glm::translate(I, {0.9f, 0.46f, 3.3f}), deg(40.0f), Y), "shared box");

  // Spheres.
  addObject(s, makeTexturedUvSphere(0.85f, 48, 24, {0.0f, 0.0f}, {2.0f, 1.0f}), mat(3),
            glm::translate(I, {-2.5f, 0.86f, -1.4f}), "sphere");
  addObject(s, makeTexturedUvSphere(0.6f, 32, 16, {-1.0f, 0.0f}, {1.0f, 1.0f}), mat(10),
            glm::translate(I, {1.9f, 2.5f, -1.2f}), "high sphere");
  addObject(s, makeTexturedUvSphere(0.5f, 32, 16, {0.0f, 0.0f}, {1.0f, 1.0f}), mat(15),
            glm::translate(I, {-0.6f, 0.51f, 3.6f}), "small sphere");

  // The untextured pillar through the panels.
  addObject(s, makeCylinder(0.15f, 1.6f, 40), plain_material,
            glm::rotate(glm::translate(I, {0.2f, 1.6f, 0.9f}), deg(12.0f), Z), "pillar");

  // The gallery: one quad per material in a grid in front of the back wall.
  const float gx0 = -3.8f, gx1 = 3.8f, gy0 = 0.35f, gy1 = 3.1f, gz = -4.3f;
  const int cols =
      std::max(1, int(std::ceil(std::sqrt(double(count) * (gx1 - gx0) / (gy1 - gy0)))));
  const int rows = (count + cols - 1) / cols;
  const float cw = (gx1 - gx0) / float(cols), ch = (gy1 - gy0) / float(rows);
  const glm::vec4 gallery_uv[3] = {unit, {-0.25f, -0.25f, 1.25f, 1.25f}, half};
  for (int i = 0; i < count; ++i) {
    const int r = i / cols, c = i % cols;
    const glm::vec4 uv = gallery_uv[i % 3];
    addObject(s, makeTexturedQuad({0.42f * cw, 0.42f * ch}, {uv.x, uv.y}, {uv.z, uv.w}),
              uint32_t(i),
              glm::translate(I, {gx0 + (float(c) + 0.5f) * cw, gy1 - (float(r) + 0.5f) * ch, gz}),
              "tile " + std::to_string(i));
  }

  OrbitView v;
  v.azimuth_deg = 35.0f;
  v.elevation_deg = 26.0f;
  v.distance_radii = 1.85f;  // closer than auto-framing: the floor's corners may leave the view
  s.default_view = v;
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

// The raster micro-benchmark's scene: kGridLayers translucent square layers of N x N quads
// (2 N^2 triangles each) stacked along the view axis and seen head-on through an orthographic
// camera, so every layer covers the same 91% of the image height and the triangle size in pixels
// is set by N alone: about (0.91 * image height / N)^2 / 2.
constexpr int kGridLayers = 8;
Scene makeGrid(int n) {
  Scene s;
  s.source = "builtin:grid:" + std::to_string(n);
  Mesh m;
  m.name = "grid";
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      m.positions.push_back(
          {2.0f * float(i) / float(n) - 1.0f, 2.0f * float(j) / float(n) - 1.0f, 0.0f});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n) + 2,
                     d = a + uint32_t(n) + 1;
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});  // counter-clockwise from +Z
    }
  const uint32_t material = addMaterial(s, "grid", {0.35f, 0.6f, 0.9f});
  s.materials[material].color.a = 0.5f;
  m.material = material;
  s.meshes.push_back(std::move(m));
  const float spacing = 0.1f;
  for (int k = 0; k < kGridLayers; ++k) {
    Instance inst;
    inst.mesh = 0;
    inst.transform = glm::translate(
        glm::mat4(1.0f), {0.0f, 0.0f, (float(k) - 0.5f * float(kGridLayers - 1)) * spacing});
    inst.object_id = uint32_t(k);
    inst.name = "layer " + std::to_string(k);
    s.instances.push_back(inst);
  }
  OrbitView v;
  v.azimuth_deg = 0.0f;
  v.elevation_deg = 0.0f;
  v.ortho_height = 2.2f;
  s.default_view = v;
  s.default_projection = Projection::Orthographic;
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

int parseIntArg(const std::string& spec, const std::string& arg) {
  const std::optional<long long> v = wholeInteger(arg);
  if (!v || *v < INT_MIN || *v > INT_MAX)
    throw Error(spec + ": '" + arg + "' is not a whole number");
  return int(*v);
}

}  // namespace

Scene makeBuiltinScene(const std::string& spec) {
  const std::string body = spec.substr(sizeof(kPrefix) - 1);
  const size_t colon = body.find(':');
  const std::string name = body.substr(0, colon);
  const std::string arg = colon == std::string::npos ? "" : body.substr(colon + 1);
  if (name == "demo" && arg.empty()) return makeDemo();
  if (name == "spheres") {
    const int n = arg.empty() ? 16 : parseIntArg(spec, arg);
    if (n < 16 || n > 96 || n % 2)
      throw Error(spec + ": the layer count must be an even number from 16 to 96");
    return makeSpheres(n);
  }
  if (name == "grid") {
    const int n = arg.empty() ? 64 : parseIntArg(spec, arg);
    if (n < 1 || n > 2048)
      throw Error(spec + ": the quads per side must be a whole number from 1 to 2048");
    return makeGrid(n);
  }
  if (name == "crowd") {
    const int n = arg.empty() ? 1000 : parseIntArg(spec, arg);
    if (n < 1 || n > 100000)
      throw Error(spec + ": the instance count must be a whole number from 1 to 100000");
    return makeCrowd(n);
  }
  if (name == "textured") {
    if (arg.empty())
      throw Error(spec +
                  ": give the number of textured materials, builtin:textured:N with N a "
                  "whole number from 1 to 4096");
    const int n = parseIntArg(spec, arg);
    if (n < 1 || n > 4096)
      throw Error(spec + ": the textured material count must be a whole number from 1 to 4096");
    return makeTextured(n);
  }
  // The massive scenes: name, default, largest argument, what the argument counts.
  struct Massive {
    const char* name;
    int fallback, lo, hi;
    const char* what;
    Scene (*make)(int);
  };
  static const Massive kMassive[] = {
      {"hairball", kDefaultHairballTubes, 1, 8000, "tube count", makeHairball},
      {"city", kDefaultCityBlocks, 1, 80, "blocks per side", makeCity},
      {"shells", kDefaultShells, 1, 64, "shell count", makeShells},
      {"soup", kDefaultSoupTriangles, 1, 20000000, "triangle count", makeSoup},
  };
  for (const Massive& m : kMassive) {
    if (name != m.name) continue;
    const int n = arg.empty() ? m.fallback : parseIntArg(spec, arg);
    if (n < m.lo || n > m.hi)
      throw Error(spec + ": the " + m.what + " must be a whole number from " +
                  std::to_string(m.lo) + " to " + std::to_string(m.hi));
    return m.make(n);
  }
  throw Error("unknown built-in scene '" + spec +
              "' (known: builtin:demo, builtin:spheres:N, builtin:crowd:N, builtin:textured:N, "
              "builtin:grid:N, builtin:hairball:N, builtin:city:N, builtin:shells:N, "
              "builtin:soup:N)");
}

Scene loadScene(const std::string& spec) {
  if (spec.rfind(kPrefix, 0) == 0) return makeBuiltinScene(spec);
  return loadSceneFile(spec);
}

}  // namespace strata
