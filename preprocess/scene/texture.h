// A decoded texture and how it is sampled: part of the scene model (loaders produce it, the
// atlas packs it, renderers sample it). No OpenCL here.
#pragma once

#include <vector>

#include <glm/glm.hpp>

namespace strata {

struct TextureImage {
  int width = 0, height = 0;
  std::vector<glm::vec4> texels;  // linear RGBA, row-major, width * height
};

enum class Wrap { Repeat, MirroredRepeat, Clamp };
enum class Filter { Nearest, Bilinear, Trilinear };
struct Sampler {
  Wrap wrap_s = Wrap::Repeat, wrap_t = Wrap::Repeat;
  Filter filter = Filter::Bilinear;
};

inline constexpr int kMaxTextureSize = 16384;

// Throws strata::Error naming `what` for a side <= 0 or > kMaxTextureSize.
void validateTextureSize(glm::ivec2 size, const char* what);
// Throws strata::Error for a size out of range or a texel count that does not match.
void validateTexture(const TextureImage& image, const char* what = "texture");

}  // namespace strata
