#include "preprocess/image_io.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <system_error>

#include <unistd.h>

#include <climits>
#include <fstream>
#include <vector>

#include "preprocess/core/check.h"
#include "preprocess/core/files.h"
#include "preprocess/image_library.h"
#include "preprocess/png_check.h"
#include "strata/error.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

void checkSameSize(const Image& a, const Image& b) {
  if (a.width != b.width || a.height != b.height)
    throw Error("image sizes differ: " + std::to_string(a.width) + "x" + std::to_string(a.height) +
                " vs " + std::to_string(b.width) + "x" + std::to_string(b.height));
}

}  // namespace

void writeImage(const Image& image, const std::string& path) {
  if (image.width <= 0 || image.height <= 0 ||
      image.rgba.size() != size_t(image.width) * size_t(image.height) * 4)
    throw Error(path + ": cannot write an empty or malformed image (" +
                std::to_string(image.width) + "x" + std::to_string(image.height) + ")");
  const fs::path target(path);
  if (target.filename().empty()) throw Error(path + ": not a file name");

  // Find a writer for the format first, so an unknown format creates no file at all.
  const std::string ext = target.extension().string();
  if (ext.empty() || ext == ".")
    throw Error(path + ": no file extension to choose an image format from (e.g. .png)");
#if !STRATA_WITH_OPENIMAGEIO
  // Without OpenImageIO (the relocatable bundle's build): stb_image_write, encoded in memory.
  std::string lower = ext;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  std::vector<unsigned char> encoded;
  auto append = [](void* context, void* data, int size) {
    auto* out = static_cast<std::vector<unsigned char>*>(context);
    out->insert(out->end(), static_cast<unsigned char*>(data),
                static_cast<unsigned char*>(data) + size);
  };
  const int w = image.width, h = image.height;
  const void* px = image.rgba.data();
  int ok = 0;
  if (lower == ".png")
    ok = stbi_write_png_to_func(append, &encoded, w, h, 4, px, w * 4);
  else if (lower == ".bmp")
    ok = stbi_write_bmp_to_func(append, &encoded, w, h, 4, px);
  else if (lower == ".tga")
    ok = stbi_write_tga_to_func(append, &encoded, w, h, 4, px);
  else if (lower == ".jpg" || lower == ".jpeg")
    ok = stbi_write_jpg_to_func(append, &encoded, w, h, 4, px, 95);
  else
    throw Error(path + ": no image format is known for the extension \"" + ext +
                "\" (this build, without OpenImageIO, writes .png, .bmp, .tga and .jpg)");
  if (!ok || encoded.empty()) throw Error(path + ": the image encoder failed");
  std::error_code dir_ec;
  const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (!fs::is_directory(folder, dir_ec))
    throw Error(path + ": folder " + folder.string() + " does not exist");
#else
  // Creating the writer opens no file, so an unknown format creates nothing.
  if (!OIIO::ImageOutput::create(target.string())) {
    OIIO::geterror();  // clear OpenImageIO's message
    throw Error(path + ": no image format is known for the extension \"" + ext + "\"");
  }
  std::error_code dir_ec;
  const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  if (!fs::is_directory(folder, dir_ec))
    throw Error(path + ": folder " + folder.string() + " does not exist");

  // Encoded in memory first (an encoder that meets a full disk may neither say so nor return:
  // libjpeg exits the process), then written with every write checked and moved into place.
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(target.string());
  if (!out) throw Error(path + ": " + oneLine(OIIO::geterror()));
  std::vector<unsigned char> encoded;
  OIIO::Filesystem::IOVecOutput memory(encoded);
  if (!out->supports("ioproxy") || !out->set_ioproxy(&memory))
    throw Error(path + ": the " + std::string(out->format_name()) +
                " writer cannot encode to memory");
  // Formats without alpha (JPEG, ...) get RGB: the stride skips the alpha byte.
  const int channels = out->supports("alpha") ? 4 : 3;
  OIIO::ImageSpec spec(image.width, image.height, channels, OIIO::TypeDesc::UINT8);
  if (channels == 4) spec.alpha_channel = 3;
  // The bytes are written as given (straight alpha), not un-premultiplied.
  spec.attribute("oiio:UnassociatedAlpha", 1);
  if (!out->open(target.string(), spec)) throw Error(path + ": " + oneLine(out->geterror()));
  const bool written = out->write_image(OIIO::TypeDesc::UINT8, image.rgba.data(), 4);
  std::string why = written ? std::string() : oneLine(out->geterror());
  const bool closed = out->close();
  if (written && !closed) why = oneLine(out->geterror());
  if (!written || !closed) throw Error(path + ": " + why);
  if (encoded.empty()) throw Error(path + ": the image encoder produced no bytes");
#endif
  writeFileAtomically(
      target, "image",
      std::string_view(reinterpret_cast<const char*>(encoded.data()), encoded.size()));
}

Image readImage(const std::string& path) {
  inputFileSize(path, "an image");

  if (const std::string damage = pngFileDamage(path); !damage.empty())
    throw Error(path + ": " + damage);

#if !STRATA_WITH_OPENIMAGEIO
  std::ifstream file(path, std::ios::binary);
  std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(file)),
                                   std::istreambuf_iterator<char>());
  if (bytes.empty() || bytes.size() > size_t(INT_MAX))
    throw Error(path + ": cannot read as an image (empty, or larger than 2 GiB)");
  int w = 0, h = 0, n = 0;
  if (!stbi_info_from_memory(bytes.data(), int(bytes.size()), &w, &h, &n))
    throw Error(path + ": cannot read as an image (" + stbi_failure_reason() + ")");
  if (w > (1 << 16) || h > (1 << 16))
    throw Error(path + ": image " + std::to_string(w) + "x" + std::to_string(h) +
                " is too large (largest side read: 65536)");
  stbi_uc* px = stbi_load_from_memory(bytes.data(), int(bytes.size()), &w, &h, &n, 4);
  if (!px) throw Error(path + ": corrupt or truncated image (" + stbi_failure_reason() + ")");
  Image image(w, h);
  std::memcpy(image.rgba.data(), px, size_t(w) * size_t(h) * 4);
  stbi_image_free(px);
  return image;
#else
  // Ask for straight (unassociated) alpha so a written image reads back byte for byte.
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path, &config);
  if (!in) throw Error(path + ": " + oneLine(OIIO::geterror()));
  const OIIO::ImageSpec& spec = in->spec();
  const int w = spec.width, h = spec.height, nc = spec.nchannels;
  if (w <= 0 || h <= 0 || nc <= 0)
    throw Error(path + ": image has no pixels (" + std::to_string(w) + "x" + std::to_string(h) +
                ", " + std::to_string(nc) + " channels)");
  const int side_limit = 1 << 16;
  if (w > side_limit || h > side_limit)
    throw Error(path + ": image " + std::to_string(w) + "x" + std::to_string(h) +
                " is too large (largest side read: " + std::to_string(side_limit) + ")");

  // Read every channel as 8-bit (OpenImageIO converts other depths), then map to RGBA.
  std::vector<uint8_t> raw(size_t(w) * size_t(h) * size_t(nc));
  if (!in->read_image(0, 0, 0, nc, OIIO::TypeDesc::UINT8, raw.data())) {
    const std::string why = oneLine(in->geterror());
    throw Error(path + ": " + why);
  }
  in->close();

  Image image(w, h);
  const size_t pixels = size_t(w) * size_t(h);
  for (size_t i = 0; i < pixels; ++i) {
    const uint8_t* s = &raw[i * nc];
    uint8_t* d = &image.rgba[i * 4];
    if (nc == 1 || nc == 2) {  // grey, or grey + alpha
      d[0] = d[1] = d[2] = s[0];
      d[3] = nc == 2 ? s[1] : 255;
    } else {
      d[0] = s[0];
      d[1] = s[1];
      d[2] = s[2];
      d[3] = nc >= 4 ? s[3] : 255;
    }
  }
  return image;
#endif
}

ImageDiff compareImages(const Image& a, const Image& b) {
  checkSameSize(a, b);
  ImageDiff d;
  d.pixels = uint64_t(a.width) * uint64_t(a.height);
  uint64_t sum_abs = 0, sum_sq = 0, within_1 = 0, within_2 = 0;
  for (uint64_t i = 0; i < d.pixels; ++i) {
    int worst = 0;
    for (int c = 0; c < 3; ++c) {
      const int diff = std::abs(int(a.rgba[i * 4 + c]) - int(b.rgba[i * 4 + c]));
      worst = std::max(worst, diff);
      sum_abs += uint64_t(diff);
      sum_sq += uint64_t(diff * diff);
    }
    d.max_abs = std::max(d.max_abs, worst);
    within_1 += worst <= 1;
    within_2 += worst <= 2;
  }
  if (d.pixels == 0) {
    d.psnr = std::numeric_limits<double>::infinity();
    d.within_1 = d.within_2 = 1.0;
    return d;
  }
  const double samples = double(d.pixels) * 3.0;
  d.mean_abs = double(sum_abs) / samples;
  d.within_1 = double(within_1) / double(d.pixels);
  d.within_2 = double(within_2) / double(d.pixels);
  const double mse = double(sum_sq) / samples;
  d.rmse = std::sqrt(mse);
  d.psnr =
      mse == 0.0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(255.0 * 255.0 / mse);
  return d;
}

Image differenceImage(const Image& a, const Image& b) {
  checkSameSize(a, b);
  Image out(a.width, a.height);
  const size_t pixels = size_t(a.width) * size_t(a.height);
  for (size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c) {
      const int diff = std::abs(int(a.rgba[i * 4 + c]) - int(b.rgba[i * 4 + c]));
      out.rgba[i * 4 + c] = uint8_t(std::min(255, diff * 8));
    }
    out.rgba[i * 4 + 3] = 255;
  }
  return out;
}

}  // namespace strata
