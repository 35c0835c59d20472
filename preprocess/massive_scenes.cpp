#include "preprocess/massive_scenes.h"

#include <cmath>
#include <string>

#include "preprocess/core/hash.h"

namespace strata {

namespace {

constexpr float kPi = 3.14159265358979f;

// A deterministic stream of numbers from an integer hash of (seed, counter).
class HashSequence {
 public:
  explicit HashSequence(uint32_t seed) : seed_(seed * 0x9E3779B9u + 0x7F4A7C15u) {}
  uint32_t nextU32() { return mixU32(seed_ ^ (counter_++ * 0x85EBCA6Bu)); }
  float unit() { return float(nextU32() >> 8) / 16777216.0f; }  // [0, 1)
  float range(float lo, float hi) { return lo + (hi - lo) * unit(); }
  glm::vec3 direction() {
    const float z = range(-1.0f, 1.0f), a = range(0.0f, 2.0f * kPi);
    const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
    return {s * std::cos(a), s * std::sin(a), z};
  }
  glm::vec3 inBall(float radius) { return direction() * (radius * std::cbrt(unit())); }

 private:
  uint32_t seed_;
  uint32_t counter_ = 0;
};

uint32_t addMaterial(Scene& s, const std::string& name, glm::vec3 color, float opacity) {
  Material m;
  m.name = name;
  m.color = glm::vec4(color, 1.0f);
  m.opacity = opacity;
  s.materials.push_back(m);
  return uint32_t(s.materials.size() - 1);
}

void addMesh(Scene& s, Mesh mesh, uint32_t material, const std::string& name) {
  mesh.material = material;
  mesh.name = name;
  s.meshes.push_back(std::move(mesh));
  Instance inst;
  inst.mesh = uint32_t(s.meshes.size() - 1);
  inst.object_id = uint32_t(s.instances.size());
  inst.name = name;
  s.instances.push_back(inst);
}

glm::vec3 perpendicular(const glm::vec3& t) {
  const glm::vec3 a = std::abs(t.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  return glm::normalize(glm::cross(t, a));
}

// A closed tube around a polyline: rings of `sides` vertices in parallel-transported frames,
// a fan cap at each end.
void appendTube(Mesh& m, const std::vector<glm::vec3>& centers, float radius, int sides) {
  const uint32_t base = uint32_t(m.positions.size());
  const size_t n = centers.size();
  glm::vec3 normal(0.0f);
  for (size_t i = 0; i < n; ++i) {
    const glm::vec3 t =
        glm::normalize(centers[std::min(i + 1, n - 1)] - centers[i > 0 ? i - 1 : 0]);
    normal = i == 0 ? perpendicular(t) : glm::normalize(normal - glm::dot(normal, t) * t);
    const glm::vec3 binormal = glm::cross(t, normal);
    for (int k = 0; k < sides; ++k) {
      const float a = 2.0f * kPi * float(k) / float(sides);
      m.positions.push_back(centers[i] + radius * (std::cos(a) * normal + std::sin(a) * binormal));
    }
  }
  auto ring = [&](size_t i, int k) { return base + uint32_t(i * sides + (k % sides)); };
  for (size_t i = 0; i + 1 < n; ++i)
    for (int k = 0; k < sides; ++k) {
      m.indices.insert(m.indices.end(), {ring(i, k), ring(i, k + 1), ring(i + 1, k + 1)});
      m.indices.insert(m.indices.end(), {ring(i, k), ring(i + 1, k + 1), ring(i + 1, k)});
    }
  const uint32_t first_cap = uint32_t(m.positions.size());
  m.positions.push_back(centers.front());
  m.positions.push_back(centers.back());
  for (int k = 0; k < sides; ++k) {
    m.indices.insert(m.indices.end(), {first_cap, ring(0, k + 1), ring(0, k)});
    m.indices.insert(m.indices.end(), {first_cap + 1, ring(n - 1, k), ring(n - 1, k + 1)});
  }
}

// A box face subdivided into k x k quads, its own vertices (corner o, edges u and v).
void appendGrid(Mesh& m, const glm::vec3& o, const glm::vec3& u, const glm::vec3& v, int k) {
  const uint32_t base = uint32_t(m.positions.size());
  for (int j = 0; j <= k; ++j)
    for (int i = 0; i <= k; ++i) m.positions.push_back(o + u * (float(i) / k) + v * (float(j) / k));
  auto at = [&](int i, int j) { return base + uint32_t(j * (k + 1) + i); };
  for (int j = 0; j < k; ++j)
    for (int i = 0; i < k; ++i) {
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      m.indices.insert(m.indices.end(), {at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
}

// A tessellated box [lo, hi]; `open_face` (0..5 in the order -x, +x, -y, +y, -z, +z) is left
// out, -1 for none.
void appendBox(Mesh& m, const glm::vec3& lo, const glm::vec3& hi, int k, int open_face) {
  const glm::vec3 d = hi - lo;
  const glm::vec3 X(d.x, 0, 0), Y(0, d.y, 0), Z(0, 0, d.z);
  // Each face counter-clockwise seen from outside.
  const glm::vec3 o[6] = {lo, lo + X, lo, lo + Y, lo, lo + Z};
  const glm::vec3 u[6] = {Z, Y, X, Z, Y, X};
  const glm::vec3 v[6] = {Y, Z, Z, X, X, Y};
  for (int f = 0; f < 6; ++f)
    if (f != open_face) appendGrid(m, o[f], u[f], v[f], k);
}

}  // namespace

Scene makeHairball(int tubes) {
  Scene s;
  s.source = "builtin:hairball:" + std::to_string(tubes);
  const int segments = 150, sides = 8;
  const float step = 4.0f / float(segments), radius = 0.012f;
  Mesh m;
  m.positions.reserve(size_t(tubes) * (segments * sides + 2));
  m.indices.reserve(size_t(tubes) * 3 * (2 * sides * segments));
  std::vector<glm::vec3> centers(segments);
  for (int t = 0; t < tubes; ++t) {
    HashSequence r(uint32_t(t) + 1u);
    glm::vec3 p = r.inBall(0.8f), dir = r.direction();
    for (int i = 0; i < segments; ++i) {
      centers[i] = p;
      dir = glm::normalize(dir + 0.35f * r.direction());
      // Keep inside the unit ball: turn back towards the centre near its surface.
      const float len = glm::length(p);
      if (len > 0.9f && glm::dot(dir, p) > 0.0f)
        dir = glm::normalize(dir - 2.0f * glm::dot(dir, p / len) * (p / len));
      p += step * dir;
    }
    appendTube(m, centers, radius, sides);
  }
  addMesh(s, std::move(m), addMaterial(s, "hair", {0.62f, 0.45f, 0.28f}, kDefaultOpacity),
          "hairball");
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

Scene makeCity(int blocks) {
  Scene s;
  s.source = "builtin:city:" + std::to_string(blocks);
  const float block = 1.0f, street = 0.25f, pitch = block + street, lot = block / 3.0f;
  const int k = 4;  // facade tessellation: k x k quads per face
  Mesh m;
  const float half = 0.5f * pitch * float(blocks);
  for (int bz = 0; bz < blocks; ++bz)
    for (int bx = 0; bx < blocks; ++bx) {
      HashSequence r(uint32_t(bz * blocks + bx) + 7u);
      const glm::vec3 origin(float(bx) * pitch - half, 0.0f, float(bz) * pitch - half);
      // The block's ground, coplanar with the buildings' floors.
      appendGrid(m, origin, glm::vec3(0, 0, block), glm::vec3(block, 0, 0), 1);
      // Lots of 3 x 3: buildings fill their lots, so neighbours share wall planes exactly.
      for (int lz = 0; lz < 3; ++lz)
        for (int lx = 0; lx < 3; ++lx) {
          const float h = r.range(0.4f, 2.5f) * (r.unit() < 0.1f ? 3.0f : 1.0f);
          const glm::vec3 lo = origin + glm::vec3(float(lx) * lot, 0.0f, float(lz) * lot);
          const glm::vec3 hi = lo + glm::vec3(lot, h, lot);
          const int open = r.unit() < 0.15f ? int(r.nextU32() % 6u) : -1;
          appendBox(m, lo, hi, k, open);
          if (r.unit() < 0.2f) {  // a tower standing on the roof, its floor on the roof plane
            const float inset = lot * r.range(0.15f, 0.3f);
            appendBox(m, lo + glm::vec3(inset, h, inset),
                      hi + glm::vec3(-inset, r.range(0.5f, 3.0f), -inset), k, -1);
          }
        }
      // A dangling single triangle: a sign at the block's corner.
      const glm::vec3 c = origin + glm::vec3(-0.08f, 0.0f, -0.08f);
      const uint32_t b = uint32_t(m.positions.size());
      m.positions.insert(m.positions.end(),
                         {c, c + glm::vec3(0.1f, 0.35f, 0.0f), c + glm::vec3(0.0f, 0.3f, 0.0f)});
      m.indices.insert(m.indices.end(), {b, b + 1, b + 2});
    }
  addMesh(s, std::move(m), addMaterial(s, "city", {0.7f, 0.72f, 0.78f}, kDefaultOpacity), "city");
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

Scene makeShells(int shells) {
  Scene s;
  s.source = "builtin:shells:" + std::to_string(shells);
  const int slices = 256, stacks = 128;
  const float spacing = 0.7f / float(shells), amplitude = 0.3f * spacing;
  for (int i = 0; i < shells; ++i) {
    const float base = 0.3f + spacing * float(i + 1);
    // Bumps below a third of the spacing: the shells never touch.
    auto radius = [&](float phi, float theta) {
      const float f = 0.5f * std::sin(3.0f * theta + float(i)) * std::sin(4.0f * phi) +
                      0.5f * std::sin(7.0f * theta) * std::cos(5.0f * phi + 0.7f * float(i));
      return base + amplitude * f;
    };
    Mesh m;
    m.positions.push_back({0.0f, radius(0.0f, 0.0f), 0.0f});
    for (int a = 1; a < stacks; ++a) {
      const float phi = kPi * float(a) / float(stacks);
      for (int b = 0; b < slices; ++b) {
        const float theta = 2.0f * kPi * float(b) / float(slices);
        m.positions.push_back(radius(phi, theta) * glm::vec3(std::sin(phi) * std::cos(theta),
                                                             std::cos(phi),
                                                             -std::sin(phi) * std::sin(theta)));
      }
    }
    m.positions.push_back({0.0f, -radius(kPi, 0.0f), 0.0f});
    const uint32_t south = uint32_t(m.positions.size() - 1);
    auto ring = [&](int a, int b) { return uint32_t(1 + (a - 1) * slices + (b % slices)); };
    for (int b = 0; b < slices; ++b)
      m.indices.insert(m.indices.end(), {0u, ring(1, b), ring(1, b + 1)});
    for (int a = 1; a + 1 < stacks; ++a)
      for (int b = 0; b < slices; ++b) {
        m.indices.insert(m.indices.end(), {ring(a, b), ring(a + 1, b), ring(a + 1, b + 1)});
        m.indices.insert(m.indices.end(), {ring(a, b), ring(a + 1, b + 1), ring(a, b + 1)});
      }
    for (int b = 0; b < slices; ++b)
      m.indices.insert(m.indices.end(), {ring(stacks - 1, b), south, ring(stacks - 1, b + 1)});
    const float t = shells > 1 ? float(i) / float(shells - 1) : 0.0f;
    const uint32_t mat =
        addMaterial(s, "shell" + std::to_string(i),
                    glm::mix(glm::vec3(0.95f, 0.85f, 0.6f), glm::vec3(0.8f, 0.25f, 0.2f), t), 0.2f);
    addMesh(s, std::move(m), mat, "shell " + std::to_string(i));
  }
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

Scene makeSoup(int triangles) {
  Scene s;
  s.source = "builtin:soup:" + std::to_string(triangles);
  HashSequence r(12345u);
  Mesh m;
  auto fresh = [&](const glm::vec3& p) {
    m.positions.push_back(p);
    return uint32_t(m.positions.size() - 1);
  };
  while (m.indices.size() / 3 < size_t(triangles)) {
    const float kind = r.unit();
    const size_t have = m.indices.size() / 3;
    if (have > 0 && kind < 0.1f) {  // an exact duplicate of an earlier face
      const size_t t = r.nextU32() % have;
      for (int c = 0; c < 3; ++c) m.indices.push_back(m.indices[t * 3 + c]);
    } else if (have > 0 && kind < 0.2f) {  // coplanar with an earlier face, overlapping it
      const size_t t = r.nextU32() % have;
      const glm::vec3 a = m.positions[m.indices[t * 3]], b = m.positions[m.indices[t * 3 + 1]],
                      c = m.positions[m.indices[t * 3 + 2]];
      const glm::vec3 shift = 0.3f * r.unit() * (b - a) + 0.3f * r.unit() * (c - a);
      m.indices.insert(m.indices.end(),
                       {fresh(a + shift), fresh(b + shift), fresh(c + 0.5f * shift)});
    } else if (have > 0 && kind < 0.3f) {  // a fan: more faces on an earlier face's edge
      const size_t t = r.nextU32() % have;
      const uint32_t a = m.indices[t * 3], b = m.indices[t * 3 + 1];
      const float size = glm::length(m.positions[b] - m.positions[a]);
      for (int f = 0; f < 3 && m.indices.size() / 3 < size_t(triangles); ++f)
        m.indices.insert(m.indices.end(), {a, b, fresh(m.positions[a] + size * r.direction())});
    } else {  // a random face, a sliver now and then, of sizes from 0.3% to 12% of the box
      const glm::vec3 c(r.unit(), r.unit(), r.unit());
      const float size = 0.003f * std::pow(40.0f, r.unit());
      const glm::vec3 p0 = c + size * r.direction(), p1 = c + size * r.direction();
      const glm::vec3 p2 = kind < 0.35f ? glm::mix(p0, p1, 0.5f) + 0.001f * size * r.direction()
                                        : c + size * r.direction();
      m.indices.insert(m.indices.end(), {fresh(p0), fresh(p1), fresh(p2)});
    }
  }
  addMesh(s, std::move(m), addMaterial(s, "soup", {0.4f, 0.7f, 0.6f}, kDefaultOpacity), "soup");
  s.report.triangles_loaded = s.triangleCount();
  return s;
}

}  // namespace strata
