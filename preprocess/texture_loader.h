// Decoding of texture images with OpenImageIO (PNG, JPEG, ... whatever it reads) into
// TextureImage texels. No OpenCL here.
//
// Texels are the stored 8-bit (or wider) values scaled to 0..1 with no transfer function: the
// renderer writes its shading values to 8-bit output as they are, so a texture shows as authored.
// Grey and grey+alpha images are expanded to RGBA; a missing alpha channel is 1.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "preprocess/scene/texture.h"

namespace strata {

// Largest texel count of one texture (256 Mi texels, 4 GiB as float RGBA): beyond it an image
// is refused as absurd rather than decoded.
inline constexpr long long kMaxTextureTexels = 1LL << 28;

// Throws strata::Error with a one-line message naming `path` (or `name`) and the problem: not
// found, not an image, corrupt or truncated data, a size of 0 or beyond kMaxTextureSize per side
// or kMaxTextureTexels in all.
std::shared_ptr<const TextureImage> loadTextureFile(const std::string& path);
std::shared_ptr<const TextureImage> loadTextureMemory(const unsigned char* data, size_t size,
                                                      const std::string& name);

}  // namespace strata
