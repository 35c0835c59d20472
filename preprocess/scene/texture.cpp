#include "preprocess/scene/texture.h"

#include <string>

#include "strata/error.h"

namespace strata {

namespace {
std::string sizeText(glm::ivec2 s) { return std::to_string(s.x) + "x" + std::to_string(s.y); }
}  // namespace

void validateTextureSize(glm::ivec2 s, const char* what) {
  if (s.x <= 0 || s.y <= 0 || s.x > kMaxTextureSize || s.y > kMaxTextureSize)
    throw Error(std::string(what) + ": size " + sizeText(s) + " is out of range (1.." +
                std::to_string(kMaxTextureSize) + " per side)");
}

void validateTexture(const TextureImage& image, const char* what) {
  validateTextureSize({image.width, image.height}, what);
  if (image.texels.size() != size_t(image.width) * size_t(image.height))
    throw Error(std::string(what) + ": " + std::to_string(image.texels.size()) + " texels for a " +
                sizeText({image.width, image.height}) + " image");
}

}  // namespace strata
