#include "engine/texture_shading.h"

#include "preprocess/texture_loader.h"

namespace strata {

StTexTriangle makeTexTriangle(const WorldGeometry& g, uint32_t t, uint32_t entry) {
  StTexTriangle r{};
  const glm::vec3 a = g.positions[g.indices[3 * t]];
  const glm::vec3 b = g.positions[g.indices[3 * t + 1]];
  const glm::vec3 c = g.positions[g.indices[3 * t + 2]];
  for (int k = 0; k < 3; ++k) {
    r.p0[k] = a[k];
    r.e1[k] = b[k] - a[k];
    r.e2[k] = c[k] - a[k];
  }
  if (g.textured()) {
    const glm::vec2 u0 = g.triangle_uv[3 * t], u1 = g.triangle_uv[3 * t + 1],
                    u2 = g.triangle_uv[3 * t + 2];
    for (int k = 0; k < 2; ++k) {
      r.uv0[k] = u0[k];
      r.duv1[k] = u1[k] - u0[k];
      r.duv2[k] = u2[k] - u0[k];
    }
  }
  r.texture = entry;
  return r;
}

ReferenceTextures ReferenceTextures::build(const WorldGeometry& g) {
  ReferenceTextures r;
  for (const auto& image : g.textures) {
    std::vector<TextureImage> mips;
    if (image) {
      mips = buildMipChain(*image);
      mips.resize(size_t(keptMipLevels({image->width, image->height})));
    }
    r.mips.push_back(std::move(mips));
  }
  return r;
}

glm::vec4 referenceTexel(const WorldGeometry& g, const ReferenceTextures& textures,
                         const StViewConstants& view, uint32_t t, int x, int y) {
  const int32_t tex = g.triangleTexture(t);
  if (tex < 0 || size_t(tex) >= textures.mips.size() || textures.mips[size_t(tex)].empty())
    return glm::vec4(1.0f);
  const std::vector<TextureImage>& mips = textures.mips[size_t(tex)];
  const StTexTriangle tri = makeTexTriangle(g, t, uint32_t(tex));
  float uv[2], duv[4];
  st_texcoords_at_pixel(&view, &tri, x, y, uv, duv);
  const int levels = int(mips.size());
  const float lod = lodFromDerivatives(duv[0], duv[1], duv[2], duv[3],
                                       {mips[0].width, mips[0].height}, levels);
  return sampleTexture(mips, g.material_sampler[g.triangle_material[t]], {uv[0], uv[1]}, lod,
                       levels);
}

int applyTexture(Scene& scene, const std::string& path, const Sampler& sampler) {
  std::shared_ptr<const TextureImage> image = loadTextureFile(path);  // first: a bad file says so
  if (scene.materials.empty()) scene.materials.emplace_back();
  std::vector<bool> has_uv(scene.materials.size(), false);
  for (Mesh& mesh : scene.meshes) {
    if (mesh.material >= scene.materials.size()) mesh.material = 0;
    if (!mesh.texcoords.empty() && mesh.texcoords.size() == mesh.positions.size())
      has_uv[mesh.material] = true;
  }
  std::vector<size_t> targets;
  for (size_t m = 0; m < scene.materials.size(); ++m)
    if (scene.materials[m].texture < 0 && has_uv[m]) targets.push_back(m);
  if (targets.empty())
    throw Error(path + ": --texture: no untextured material of " + scene.source +
                " has texture coordinates to map it with");
  SceneTexture t;
  t.name = path;
  t.image = std::move(image);
  scene.textures.push_back(std::move(t));
  for (size_t m : targets) {
    scene.materials[m].texture = int32_t(scene.textures.size() - 1);
    scene.materials[m].sampler = sampler;
    scene.materials[m].base_color_texture = path;
  }
  return int(targets.size());
}

}  // namespace strata
