#include "engine/frontend/texture_shading.h"

#include <algorithm>
#include <cmath>

#include "preprocess/texture_loader.h"

namespace strata {

namespace {

using dvec3 = glm::dvec3;

dvec3 viewVector(const float* v) { return {v[0], v[1], v[2]}; }

// Coefficients (of px, of py, constant) of dot(a + b px + c py, n).
glm::dvec3 planeOf(const dvec3& a, const dvec3& b, const dvec3& c, const dvec3& n) {
  return {glm::dot(b, n), glm::dot(c, n), glm::dot(a, n)};
}

}  // namespace

StTexTriangle makeTexTriangle(const WorldGeometry& g, uint32_t t, uint32_t entry,
                              const StViewConstants& view) {
  StTexTriangle r{};
  r.texture = entry;
  const dvec3 p0 = g.positions[g.indices[3 * t]];
  const dvec3 e1 = dvec3(g.positions[g.indices[3 * t + 1]]) - p0;
  const dvec3 e2 = dvec3(g.positions[g.indices[3 * t + 2]]) - p0;
  glm::dvec2 uv0(0.0), duv1(0.0), duv2(0.0);
  if (g.textured()) {
    uv0 = g.triangle_uv[3 * t];
    duv1 = glm::dvec2(g.triangle_uv[3 * t + 1]) - uv0;
    duv2 = glm::dvec2(g.triangle_uv[3 * t + 2]) - uv0;
  }
  const dvec3 n = glm::cross(e1, e2);
  const double nn = glm::dot(n, n);
  // The pixel ray through pixel centre (px, py) (st_pixel_ray / Camera::pixelRay), affine in
  // (px, py): origin o0 + ox px + oy py, direction d0 + dx px + dy py.
  const double W = view.width, H = view.height;
  const dvec3 F = viewVector(view.forward), R = viewVector(view.right), U = viewVector(view.up);
  dvec3 o0 = viewVector(view.eye), ox(0.0), oy(0.0), d0 = F, dx(0.0), dy(0.0);
  if (view.projection == ST_PROJ_PERSPECTIVE) {
    const double tx = view.ray_tan[0], ty = view.ray_tan[1];
    d0 = F - R * tx + U * ty;
    dx = R * (2.0 * tx / W);
    dy = -U * (2.0 * ty / H);
  } else {
    const double hx = view.ray_tan[2], hy = view.ray_tan[3];
    o0 = o0 - R * hx + U * hy;
    ox = R * (2.0 * hx / W);
    oy = -U * (2.0 * hy / H);
  }
  if (!(nn > 0.0) || !std::isfinite(nn)) {  // no plane: the corner's coordinates everywhere
    r.u_plane[2] = float(uv0.x);
    r.v_plane[2] = float(uv0.y);
    r.w_plane[2] = 1.0f;
    return r;
  }
  // Barycentrics of a point q of the plane: b1 = (q - p0).m1, b2 = (q - p0).m2 (dual basis).
  const dvec3 m1 = glm::cross(e2, n) / nn, m2 = glm::cross(n, e1) / nn;
  glm::dvec3 up, vp, wp;
  if (view.projection == ST_PROJ_PERSPECTIVE) {
    // hit = o + t d with t = k / (d.n), k = (p0 - o).n: b_i = (o - p0).m_i + k (d.m_i) / (d.n),
    // so uv = [base (d.n) + k ((d.m1) duv1 + (d.m2) duv2)] / (d.n).
    const double k = glm::dot(p0 - o0, n);
    const glm::dvec2 base = uv0 + glm::dot(o0 - p0, m1) * duv1 + glm::dot(o0 - p0, m2) * duv2;
    const glm::dvec3 dn = planeOf(d0, dx, dy, n), dm1 = planeOf(d0, dx, dy, m1),
                     dm2 = planeOf(d0, dx, dy, m2);
    up = base.x * dn + k * (duv1.x * dm1 + duv2.x * dm2);
    vp = base.y * dn + k * (duv1.y * dm1 + duv2.y * dm2);
    wp = dn;
    // Fragments exist only where the plane lies in front (W > 0 there); scale so W's largest
    // coefficient is 1 (a ratio is unchanged by the scale).
    const double scale = std::max({std::abs(wp.x), std::abs(wp.y), std::abs(wp.z)});
    if (scale > 0.0 && std::isfinite(scale)) {
      const double sgn = 1.0 / scale;
      up *= sgn;
      vp *= sgn;
      wp *= sgn;
    }
    // Orient so W > 0 where the ray meets the plane in front of the eye (t = k / W > 0).
    if (k < 0.0) {
      up = -up;
      vp = -vp;
      wp = -wp;
    }
  } else {
    // d = F fixed: t = (p0 - o).n / (F.n) is affine, and so are the barycentrics and uv.
    const double fn = glm::dot(F, n);
    if (!(std::abs(fn) > 0.0)) {  // seen edge-on: no fragments
      r.u_plane[2] = float(uv0.x);
      r.v_plane[2] = float(uv0.y);
      r.w_plane[2] = 1.0f;
      return r;
    }
    // t(px, py) = (p0 - o0).n / fn - (ox.n) px / fn - (oy.n) py / fn
    const glm::dvec3 tp(-glm::dot(ox, n) / fn, -glm::dot(oy, n) / fn, glm::dot(p0 - o0, n) / fn);
    // b_i = (o - p0).m_i + t (F.m_i)
    auto bary = [&](const dvec3& m) {
      const double fm = glm::dot(F, m);
      return glm::dvec3(glm::dot(ox, m), glm::dot(oy, m), glm::dot(o0 - p0, m)) + fm * tp;
    };
    const glm::dvec3 b1 = bary(m1), b2 = bary(m2);
    up = duv1.x * b1 + duv2.x * b2 + glm::dvec3(0.0, 0.0, uv0.x);
    vp = duv1.y * b1 + duv2.y * b2 + glm::dvec3(0.0, 0.0, uv0.y);
    wp = glm::dvec3(0.0, 0.0, 1.0);
  }
  for (int c = 0; c < 3; ++c) {
    r.u_plane[c] = float(up[c]);
    r.v_plane[c] = float(vp[c]);
    r.w_plane[c] = float(wp[c]);
  }
  return r;
}

std::vector<StTexTriangle> makeTexTriangles(const WorldGeometry& g,
                                            const std::vector<uint32_t>& material_entry,
                                            const StViewConstants& view) {
  std::vector<StTexTriangle> out;
  if (!g.textured()) return out;
  out.resize(g.triangleCount());
  for (uint32_t t = 0; t < g.triangleCount(); ++t) {
    const uint32_t m = g.triangle_material[t];
    const uint32_t entry = m < material_entry.size() ? material_entry[m] : ST_NO_TEXTURE;
    out[t] = entry == ST_NO_TEXTURE ? StTexTriangle{{0, 0, 0}, {0, 0, 0}, {0, 0, 1}, ST_NO_TEXTURE}
                                    : makeTexTriangle(g, t, entry, view);
  }
  return out;
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
  const StTexTriangle tri = makeTexTriangle(g, t, uint32_t(tex), view);
  float uv[2], duv[4];
  st_texcoords_at_pixel(&tri, x, y, uv, duv);
  const int levels = int(mips.size());
  const float lod =
      lodFromDerivatives(duv[0], duv[1], duv[2], duv[3], {mips[0].width, mips[0].height}, levels);
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
