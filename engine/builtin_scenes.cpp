#include "engine/builtin_scenes.h"

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

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
  for (int j = 0; j < slices; ++j) m.indices.insert(m.indices.end(), {0u, ring(1, j), ring(1, j + 1)});
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
  const glm::vec3 palette[4] = {{0.9f, 0.35f, 0.3f}, {0.3f, 0.75f, 0.4f}, {0.35f, 0.5f, 0.95f},
                                {0.95f, 0.8f, 0.3f}};
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

// A crowd for batching and draw sorting (issue 5): N instances of a few meshes (sphere, torus,
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
  const Paint paints[8] = {{"red", {0.92f, 0.3f, 0.25f}, 0.5f},   {"amber", {0.98f, 0.72f, 0.2f}, 0.4f},
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
  auto hash = [](uint32_t x) {
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
  };
  auto unit = [&](uint32_t i, uint32_t salt) { return float(hash(i * 4u + salt) >> 8) / 16777216.0f; };
  for (int i = 0; i < count; ++i) {
    const int layer = i / per_layer, cell = i % per_layer;
    const int gx = cell % side, gz = cell / side;
    const uint32_t h = hash(uint32_t(i) * 2654435761u + 17u);
    const uint32_t shape = h % 4, paint = (h >> 8) % 8;
    const glm::vec3 centre((float(gx) - 0.5f * float(side - 1)) * spacing,
                           (float(layer) - 0.5f * float(layers - 1)) * spacing,
                           (float(gz) - 0.5f * float(side - 1)) * spacing);
    const glm::vec3 axis = glm::normalize(glm::vec3(unit(i, 0) - 0.5f, unit(i, 1) - 0.5f, unit(i, 2) - 0.5f) +
                                          glm::vec3(0.0f, 0.01f, 0.0f));
    const float angle = 2.0f * kPi * unit(i, 3);
    const glm::vec3 scale(0.7f + 0.5f * unit(i, 4), 0.7f + 0.5f * unit(i, 5), 0.7f + 0.5f * unit(i, 6));
    Instance inst;
    inst.mesh = shape * 8 + paint;
    inst.transform = glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), centre), angle, axis), scale);
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

int parseIntArg(const std::string& spec, const std::string& arg) {
  size_t used = 0;
  int v = 0;
  try {
    v = std::stoi(arg, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != arg.size() || arg.empty())
    throw Error(spec + ": '" + arg + "' is not a whole number");
  return v;
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
  if (name == "crowd") {
    const int n = arg.empty() ? 1000 : parseIntArg(spec, arg);
    if (n < 1 || n > 100000)
      throw Error(spec + ": the instance count must be a whole number from 1 to 100000");
    return makeCrowd(n);
  }
  throw Error("unknown built-in scene '" + spec +
              "' (known: builtin:demo, builtin:spheres:N, builtin:crowd:N)");
}

Scene loadScene(const std::string& spec) {
  if (spec.rfind(kPrefix, 0) == 0) return makeBuiltinScene(spec);
  return loadSceneFile(spec);
}

}  // namespace strata
