// Scene description: meshes, materials, instances. No OpenCL here: this header is public.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/texture.h"
#include "strata/error.h"

namespace strata {

inline constexpr float kDefaultOpacity = 0.5f;

struct Material {
  std::string name;
  glm::vec4 color{0.8f, 0.8f, 0.8f, 1.0f};  // base colour RGBA (linear)
  float opacity = kDefaultOpacity;          // used by transparency methods
  std::string base_color_texture;           // URI/path of the texture, empty if none
  // The decoded base-colour texture: an index into Scene::textures (-1: untextured) and how it
  // is sampled. The texel multiplies the colour (RGB) and the opacity (A).
  int32_t texture = -1;
  Sampler sampler;
  // Kernel-variant bits a material system would select (draw-unit state for batching and
  // sorting, engine/features/batching.h; every variant renders with the same kernels today).
  uint32_t shader_variant = 0;
};

// A decoded texture: linear RGBA texels, row 0 at the top of the image; texture coordinate
// (0, 0) is its top-left corner (glTF's convention; OBJ's v is flipped on load).
struct SceneTexture {
  std::string name;  // file or glTF image name, for messages
  std::shared_ptr<const TextureImage> image;
};

struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> texcoords;  // empty, or one per position
  std::vector<uint32_t> indices;     // three per triangle
  uint32_t material = 0;             // index into Scene::materials

  size_t triangleCount() const { return indices.size() / 3; }
};

struct Instance {
  uint32_t mesh = 0;
  glm::mat4 transform{1.0f};  // object -> world
  uint32_t object_id = 0;
  std::string name;
};

// What loading and validation did to the input, so nothing is dropped silently.
struct LoadReport {
  uint64_t polygons_triangulated = 0;  // faces with more than three corners
  uint64_t triangles_loaded = 0;
  uint64_t dropped_nonfinite = 0;     // triangles touching a non-finite vertex
  uint64_t dropped_out_of_range = 0;  // triangles with an index past the vertex count
  uint64_t dropped_degenerate = 0;    // zero-area triangles (repeated or collinear corners)
  std::vector<std::string> warnings;
};

struct Bounds {
  glm::vec3 min{1e30f}, max{-1e30f};
  bool empty() const { return min.x > max.x; }
  void extend(const glm::vec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  glm::vec3 center() const { return (min + max) * 0.5f; }
};

struct BoundingSphere {
  glm::vec3 center{0.0f};
  float radius = 1.0f;
};

enum class Projection { Perspective, Orthographic };

// A view given as orbit angles around the scene's bounding sphere.
struct OrbitView {
  float azimuth_deg = 30.0f;
  float elevation_deg = 20.0f;
  std::optional<float> distance_radii;  // unset: auto-frame
  std::optional<float> ortho_height;    // orthographic: world height of the view (unset: fit)
};

class OctreeSceneFile;  // preprocess/octree_scene.h

// Triangles that stay on disk in an out-of-core octree scene file (strata prep --octree
// --out-of-core): only the octree method streams them; everything else reads them whole.
struct OutOfCoreTriangles {
  std::shared_ptr<const OctreeSceneFile> file;
  std::string path;
  uint64_t triangles = 0;  // of the scene the file was made from
  Bounds bounds;
  BoundingSphere sphere;
};

struct Scene {
  std::string source;  // file path or builtin:NAME
  std::vector<Mesh> meshes;
  std::vector<Material> materials;
  std::vector<SceneTexture> textures;
  std::vector<Instance> instances;
  LoadReport report;
  std::optional<OrbitView> default_view;  // a scene's natural view (e.g. along a stacking axis)
  std::optional<Projection> default_projection;
  // Set for an out-of-core octree scene, whose meshes stay empty.
  std::shared_ptr<const OutOfCoreTriangles> out_of_core;

  uint64_t triangleCount() const;
  Bounds worldBounds() const;
  BoundingSphere boundingSphere() const;
};

}  // namespace strata
