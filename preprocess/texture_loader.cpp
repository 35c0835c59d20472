// Texture decoding with OpenImageIO (see texture_loader.h for the texel rule).
//
// Order of checks, so that a bad input costs nothing and never crashes or hangs:
//   1. the file exists, is a regular file and is not empty (memory: not empty);
//   2. OpenImageIO reads the header only (ImageInput::open); its size is checked against
//      kMaxTextureSize per side and kMaxTextureTexels in all BEFORE any texel is allocated;
//   3. the pixels are decoded straight into the texels' memory (strided read of at most four
//      channels, no intermediate buffer), band by band into a reserve that grows with them (a
//      truncated file claiming a huge size fails having touched one band), then scaled and
//      expanded to RGBA in place.
// Failures of OpenImageIO (unknown format, corrupt or truncated data) become one-line Errors
// "<name>: <problem>". PNG data is checked first (chunk CRCs, a complete zlib stream, an IEND):
// OpenImageIO's PNG reader leaves libpng's default error handler in place, which prints its own
// "libpng error: ..." line on stderr for a truncated or damaged file.
#include "preprocess/texture_loader.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <new>
#include <string>
#include <system_error>
#include <vector>

#include <climits>
#include <fstream>

#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/image_library.h"
#include "preprocess/png_check.h"
#include "preprocess/scene/scene.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

[[noreturn]] void refuse(const std::string& name, const std::string& problem) {
  throw Error(oneLine(name + ": " + problem));
}

#if STRATA_WITH_OPENIMAGEIO
// The error text of a failed ImageInput call (or OpenImageIO's global one), cleared after use so
// it does not leak into the next message of this thread.
std::string inputError(OIIO::ImageInput* in) {
  std::string why = in ? in->geterror() : std::string();
  const std::string global = OIIO::geterror();
  if (why.empty()) why = global;
  return oneLine(why);
}

// The file extension OpenImageIO should try first for data starting with `head`: the formats
// glTF allows (PNG, JPEG) and a few common others. Empty when none matches.
std::string sniffExtension(const unsigned char* head, size_t size) {
  auto starts = [&](const char* magic, size_t n) {
    return size >= n && std::memcmp(head, magic, n) == 0;
  };
  if (starts("\x89PNG\r\n\x1a\n", 8)) return ".png";
  if (starts("\xFF\xD8\xFF", 3)) return ".jpg";
  if (starts("BM", 2)) return ".bmp";
  if (starts("GIF87a", 6) || starts("GIF89a", 6)) return ".gif";
  if (size >= 12 && std::memcmp(head, "RIFF", 4) == 0 && std::memcmp(head + 8, "WEBP", 4) == 0)
    return ".webp";
  if (starts("DDS ", 4)) return ".dds";
  if (starts("\x76\x2f\x31\x01", 4)) return ".exr";
  if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6)) return ".hdr";
  if (starts("II*\0", 4) || starts("MM\0*", 4)) return ".tif";
  return {};
}

// `why` with every mention of `pseudo` (the made-up file name a memory read is opened under,
// which means nothing to the user) replaced by "the data".
std::string hidePseudoName(std::string why, const std::string& pseudo) {
  if (pseudo.empty()) return why;
  for (size_t at = why.find(pseudo); at != std::string::npos; at = why.find(pseudo, at))
    why.replace(at, pseudo.size(), "the data");
  return why;
}

// Decodes the already opened image `in` (its header read, no pixels yet).
std::shared_ptr<const TextureImage> decodeOpened(OIIO::ImageInput& in, const std::string& name,
                                                 const std::string& pseudo = {}) {
  const OIIO::ImageSpec spec = in.spec();
  const long long w = spec.width, h = spec.height;
  const std::string size_text = std::to_string(w) + "x" + std::to_string(h);
  if (w <= 0 || h <= 0 || spec.nchannels <= 0)
    refuse(name, "image has no pixels (" + size_text + ", " + std::to_string(spec.nchannels) +
                     " channels)");
  if (spec.depth > 1)
    refuse(name, "volume image (depth " + std::to_string(spec.depth) + ") is not a texture");
  if (w > kMaxTextureSize || h > kMaxTextureSize)
    refuse(name, "image size " + size_text + " exceeds the largest texture side " +
                     std::to_string(kMaxTextureSize));
  if (w * h > kMaxTextureTexels)
    refuse(name, "image size " + size_text + " exceeds the largest texture of " +
                     std::to_string(kMaxTextureTexels) + " texels");

  auto image = std::make_shared<TextureImage>();
  image->width = static_cast<int>(w);
  image->height = static_cast<int>(h);
  // Reserved, not filled: the texels are grown band by band as their rows decode (below), so
  // that a few bytes claiming a huge image fail at their first band having touched only it.
  try {
    image->texels.reserve(static_cast<size_t>(w * h));
  } catch (const std::bad_alloc&) {
    refuse(name, "out of memory for a " + size_text + " texture");
  }

  // At most four channels, written straight into the texels (a texel is 16 bytes, a row w
  // texels). 8 and 16-bit images are read as such into the first bytes of each texel and scaled
  // in place to value / 255 (65535) exactly; anything else is read as float by OpenImageIO.
  const int channels = std::min(spec.nchannels, 4);
  const bool uniform = spec.channelformats.empty();
  const OIIO::TypeDesc read_type =
      uniform && spec.format == OIIO::TypeDesc::UINT8    ? OIIO::TypeDesc::UINT8
      : uniform && spec.format == OIIO::TypeDesc::UINT16 ? OIIO::TypeDesc::UINT16
                                                         : OIIO::TypeDesc::FLOAT;
  const OIIO::stride_t xstride = sizeof(glm::vec4);
  const OIIO::stride_t ystride = xstride * static_cast<OIIO::stride_t>(w);
  // Bands of about a million texels (whole rows of tiles for a tiled image), each decoded into
  // texels the vector grows to hold it (within its reserve: no reallocation).
  const long long tile_rows = spec.tile_width > 0 ? std::max(spec.tile_height, 1) : 1;
  const long long rows = std::max(1LL, (1LL << 20) / w);
  const long long band = (rows + tile_rows - 1) / tile_rows * tile_rows;
  for (long long y0 = 0; y0 < h; y0 += band) {
    const long long y1 = std::min(h, y0 + band);
    image->texels.resize(static_cast<size_t>(y1 * w), glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
    void* rows = image->texels.data() + y0 * w;
    const int ya = spec.y + static_cast<int>(y0), yb = spec.y + static_cast<int>(y1);
    const bool read =
        spec.tile_width > 0
            ? in.read_tiles(0, 0, spec.x, spec.x + spec.width, ya, yb, spec.z, spec.z + 1, 0,
                            channels, read_type, rows, xstride, ystride, OIIO::AutoStride)
            : in.read_scanlines(0, 0, ya, yb, spec.z, 0, channels, read_type, rows, xstride,
                                ystride);
    if (!read || in.has_error())
      refuse(name,
             "corrupt or truncated image data (" + hidePseudoName(inputError(&in), pseudo) + ")");
  }
  in.close();

  // Scale to 0..1 and expand to RGBA: grey -> (g, g, g, 1); grey + alpha -> (g, g, g, a);
  // RGB -> (r, g, b, 1). Float formats may hold non-finite values, which would spread through
  // every mip level: they become 0.
  for (glm::vec4& t : image->texels) {
    float v[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    if (read_type == OIIO::TypeDesc::UINT8) {
      uint8_t raw[4];
      std::memcpy(raw, &t, sizeof raw);
      for (int c = 0; c < channels; ++c) v[c] = raw[c] / 255.0f;
    } else if (read_type == OIIO::TypeDesc::UINT16) {
      uint16_t raw[4];
      std::memcpy(raw, &t, sizeof raw);
      for (int c = 0; c < channels; ++c) v[c] = raw[c] / 65535.0f;
    } else {
      for (int c = 0; c < channels; ++c) v[c] = std::isfinite(t[c]) ? t[c] : 0.0f;
    }
    if (channels == 1)
      t = glm::vec4(v[0], v[0], v[0], 1.0f);
    else if (channels == 2)
      t = glm::vec4(v[0], v[0], v[0], v[1]);
    else
      t = glm::vec4(v[0], v[1], v[2], channels == 4 ? v[3] : 1.0f);
  }
  return image;
}

// Straight (unassociated) alpha: OpenImageIO would otherwise premultiply PNG's colour by alpha.
OIIO::ImageSpec readConfig() {
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  return config;
}

#else

// Without OpenImageIO (the relocatable bundle's build): stb_image, which reads PNG, JPEG, BMP,
// TGA, GIF, PSD, HDR and PNM. 8 and 16-bit values scale to value / 255 (65535) as with
// OpenImageIO; HDR is read as float (stb applies no transfer function to it).
std::shared_ptr<const TextureImage> decodeWithStb(const unsigned char* data, size_t size,
                                                  const std::string& name) {
  if (size > size_t(INT_MAX)) refuse(name, "image data larger than 2 GiB");
  const int bytes = static_cast<int>(size);
  int w = 0, h = 0, n = 0;
  if (!stbi_info_from_memory(data, bytes, &w, &h, &n))
    refuse(name, std::string("cannot read as an image (") + stbi_failure_reason() +
                     "; this build reads PNG, JPEG, BMP, TGA, GIF, PSD, HDR and PNM)");
  const std::string size_text = std::to_string(w) + "x" + std::to_string(h);
  if (w <= 0 || h <= 0) refuse(name, "image has no pixels (" + size_text + ")");
  if (w > kMaxTextureSize || h > kMaxTextureSize)
    refuse(name, "image size " + size_text + " exceeds the largest texture side " +
                     std::to_string(kMaxTextureSize));
  if ((long long)w * h > kMaxTextureTexels)
    refuse(name, "image size " + size_text + " exceeds the largest texture of " +
                     std::to_string(kMaxTextureTexels) + " texels");
  auto image = std::make_shared<TextureImage>();
  image->width = w;
  image->height = h;
  const size_t count = size_t(w) * size_t(h);
  int dw = 0, dh = 0, dn = 0;
  auto fail = [&] {
    refuse(name, std::string("corrupt or truncated image data (") + stbi_failure_reason() + ")");
  };
  try {
    image->texels.resize(count);
    if (stbi_is_hdr_from_memory(data, bytes)) {
      float* p = stbi_loadf_from_memory(data, bytes, &dw, &dh, &dn, 4);
      if (!p) fail();
      for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < 4; ++c)
          image->texels[i][c] = std::isfinite(p[i * 4 + c]) ? p[i * 4 + c] : 0.0f;
      stbi_image_free(p);
    } else if (stbi_is_16_bit_from_memory(data, bytes)) {
      stbi_us* p = stbi_load_16_from_memory(data, bytes, &dw, &dh, &dn, 4);
      if (!p) fail();
      for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < 4; ++c) image->texels[i][c] = p[i * 4 + c] / 65535.0f;
      stbi_image_free(p);
    } else {
      stbi_uc* p = stbi_load_from_memory(data, bytes, &dw, &dh, &dn, 4);
      if (!p) fail();
      for (size_t i = 0; i < count; ++i)
        for (int c = 0; c < 4; ++c) image->texels[i][c] = p[i * 4 + c] / 255.0f;
      stbi_image_free(p);
    }
  } catch (const std::bad_alloc&) {
    refuse(name, "out of memory for a " + size_text + " texture");
  }
  if (dw != w || dh != h) refuse(name, "image size changed between header and data");
  return image;
}

#endif

}  // namespace

std::shared_ptr<const TextureImage> loadTextureFile(const std::string& path) {
  [[maybe_unused]] const uintmax_t bytes = inputFileSize(path, "an image");
#if !STRATA_WITH_OPENIMAGEIO
  // Read once: the PNG check and the decoder share the bytes.
  if (bytes > uintmax_t(INT_MAX)) refuse(path, "image file larger than 2 GiB");
  std::vector<unsigned char> whole(static_cast<size_t>(bytes));
  std::ifstream file(path, std::ios::binary);
  file.read(reinterpret_cast<char*>(whole.data()), std::streamsize(whole.size()));
  if (size_t(file.gcount()) != whole.size()) refuse(path, "cannot read the whole file");
  if (isPng(whole.data(), whole.size()))
    if (const std::string damage = pngDamage(whole.data(), whole.size()); !damage.empty())
      refuse(path, damage);
  return decodeWithStb(whole.data(), whole.size(), path);
#else
  if (const std::string damage = pngFileDamage(path); !damage.empty()) refuse(path, damage);

  const OIIO::ImageSpec config = readConfig();
  std::unique_ptr<OIIO::ImageInput> in;
  try {
    in = OIIO::ImageInput::open(path, &config);
  } catch (const std::exception& e) {
    refuse(path, std::string("cannot read as an image: ") + e.what());
  }
  if (!in) refuse(path, "cannot read as an image (" + inputError(nullptr) + ")");
  try {
    return decodeOpened(*in, path);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    refuse(path, std::string("cannot decode: ") + e.what());
  }
#endif
}

std::shared_ptr<const TextureImage> loadTextureMemory(const unsigned char* data, size_t size,
                                                      const std::string& name) {
  if (data == nullptr || size == 0) refuse(name, "empty image data (0 bytes)");

  // OpenImageIO picks the reader from the name's extension first, then tries every reader that
  // can read from memory. The data's signature is a better guide than a glTF image's name.
  if (isPng(data, size))
    if (const std::string damage = pngDamage(data, size); !damage.empty()) refuse(name, damage);
#if !STRATA_WITH_OPENIMAGEIO
  return decodeWithStb(data, size, name);
#else
  const std::string sniffed = sniffExtension(data, size);
  std::string ext = sniffed;
  if (ext.empty()) ext = fs::path(name).extension().string();
  if (ext.empty()) ext = ".png";
  const std::string pseudo_name = "memory" + ext;

  OIIO::Filesystem::IOMemReader proxy(data, size);
  OIIO::ImageSpec config = readConfig();
  OIIO::Filesystem::IOProxy* proxy_ptr = &proxy;
  config.attribute("oiio:ioproxy", OIIO::TypeDesc::PTR, &proxy_ptr);
  std::unique_ptr<OIIO::ImageInput> in;
  try {
    in = OIIO::ImageInput::open(pseudo_name, &config, &proxy);
  } catch (const std::exception& e) {
    refuse(name, std::string("cannot read as an image: ") + e.what());
  }
  if (!in) {
    const std::string why = hidePseudoName(inputError(nullptr), pseudo_name);
    if (sniffed.empty())  // OpenImageIO's message would be about a file "the data"
      refuse(name,
             "cannot read as an image (no PNG, JPEG, BMP, GIF, WebP, DDS, OpenEXR, HDR or "
             "TIFF signature, and no reader accepts the data)");
    refuse(name, "cannot read as an image (" + why + ")");
  }
  try {
    return decodeOpened(*in, name, pseudo_name);
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    refuse(name, std::string("cannot decode: ") + e.what());
  }
#endif
}

}  // namespace strata
