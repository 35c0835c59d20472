// Per-fragment texturing rules shared by the OpenCL methods and the Embree reference: the
// per-triangle texturing record (StTexTriangle, strata_shared.h) and the reference texel of a
// fragment, sampled from the original, un-packed textures (the oracle of the atlas).
// No OpenCL here.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/features/texture_atlas.h"
#include "kernels/strata_shared.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

// Triangle t's texturing record for one view (its U, V, W planes over the pixel centre, computed
// in double precision), naming atlas entry `entry` (ST_NO_TEXTURE: untextured).
StTexTriangle makeTexTriangle(const WorldGeometry& g, uint32_t t, uint32_t entry,
                              const StViewConstants& view);
// Every triangle's record, its entry from its material (material_entry[m], ST_NO_TEXTURE:
// untextured); empty when the geometry is not textured.
std::vector<StTexTriangle> makeTexTriangles(const WorldGeometry& g,
                                            const std::vector<uint32_t>& material_entry,
                                            const StViewConstants& view);

// The mip chains of a geometry's textures, each limited to the levels the atlas keeps for it
// (keptMipLevels), so reference and atlas agree on which levels exist.
struct ReferenceTextures {
  std::vector<std::vector<TextureImage>> mips;  // per WorldGeometry::textures entry
  static ReferenceTextures build(const WorldGeometry& g);
};

// The texel (RGBA) that multiplies the flat-shaded colour of triangle t at pixel (x, y):
// texture coordinates and derivatives by st_texcoords_at_pixel, level by lodFromDerivatives,
// sampled by sampleTexture. (1, 1, 1, 1) when t is untextured.
glm::vec4 referenceTexel(const WorldGeometry& g, const ReferenceTextures& textures,
                         const StViewConstants& view, uint32_t t, int x, int y);

// Gives every untextured material of `scene` whose meshes have texture coordinates the base-colour
// texture in `path` (decoded with OpenImageIO; a scene without materials gets a default one):
// the CLI's --texture, for meshes without a material file (spot.obj and its spot_texture.png).
// Throws Error naming the file when it cannot be decoded, or when no mesh has texture
// coordinates. Returns the number of materials given the texture.
int applyTexture(Scene& scene, const std::string& path, const Sampler& sampler = {});

}  // namespace strata
