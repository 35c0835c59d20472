#include "engine/texture_shading.h"

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

}  // namespace strata
