#include "preprocess/png_check.h"

#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

#include <zlib.h>

namespace strata {

namespace {

constexpr size_t kPngSignatureBytes = 8;

}  // namespace

bool isPng(const unsigned char* data, size_t size) {
  return size >= kPngSignatureBytes && std::memcmp(data, "\x89PNG\r\n\x1a\n", 8) == 0;
}

// Why PNG data is damaged, or "" when its chunk structure, CRCs and image data stream are whole
// (semantic checks stay with the decoder).
std::string pngDamage(const unsigned char* data, size_t size) {
  auto u32 = [](const unsigned char* p) {
    return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | uint32_t(p[3]);
  };
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) return "cannot check the PNG data (zlib could not start)";
  struct End {
    z_stream* zs;
    ~End() { inflateEnd(zs); }
  } end{&zs};
  unsigned char scratch[16384];
  bool stream_done = false, seen_idat = false;
  size_t at = kPngSignatureBytes;
  while (true) {
    if (size - at < 12) return "truncated PNG image (it ends inside a chunk, before IEND)";
    const uint32_t length = u32(data + at);
    const unsigned char* type = data + at + 4;
    if (length > 0x7fffffffu || length > size - at - 12)
      return "truncated PNG image (a chunk runs past the end of the data)";
    const unsigned char* body = type + 4;
    for (int i = 0; i < 4; ++i)
      if (!std::isalpha(type[i])) return "corrupt PNG image (a chunk type that is not 4 letters)";
    const uLong crc = crc32(crc32(0L, Z_NULL, 0), type, 4 + length);
    if (crc != u32(body + length))
      return "corrupt PNG image (CRC mismatch in chunk " + std::string(type, type + 4) + ")";
    if (at == kPngSignatureBytes) {
      // The header: what libpng's png_check_IHDR refuses.
      if (std::memcmp(type, "IHDR", 4) != 0 || length != 13)
        return "corrupt PNG image (it does not start with a 13-byte IHDR chunk)";
      const uint32_t w = u32(body), h = u32(body + 4);
      const int depth = body[8], colour = body[9];
      const bool depth_ok =
          colour == 0 ? (depth == 1 || depth == 2 || depth == 4 || depth == 8 || depth == 16)
          : colour == 3
              ? (depth == 1 || depth == 2 || depth == 4 || depth == 8)
              : (colour == 2 || colour == 4 || colour == 6) && (depth == 8 || depth == 16);
      if (w == 0 || h == 0 || w > 0x7fffffffu || h > 0x7fffffffu || !depth_ok || body[10] != 0 ||
          body[11] != 0 || body[12] > 1)
        return "corrupt PNG image (invalid IHDR: size, bit depth, colour type or methods)";
      // libpng's default user limits (PNG_USER_WIDTH_MAX, PNG_USER_HEIGHT_MAX).
      if (w > 1000000u || h > 1000000u)
        return "PNG image of " + std::to_string(w) + "x" + std::to_string(h) +
               " pixels, more than the 1000000 per side that libpng reads";
    }
    if (std::memcmp(type, "IDAT", 4) == 0) {
      seen_idat = true;
      zs.next_in = const_cast<unsigned char*>(body);
      zs.avail_in = length;
      while (zs.avail_in > 0 && !stream_done) {
        zs.next_out = scratch;
        zs.avail_out = sizeof(scratch);
        const int r = inflate(&zs, Z_NO_FLUSH);
        if (r == Z_STREAM_END)
          stream_done = true;
        else if (r != Z_OK && r != Z_BUF_ERROR)
          return std::string("corrupt PNG image data (zlib: ") + (zs.msg ? zs.msg : "error") + ")";
      }
    }
    at += 12 + size_t(length);
    if (std::memcmp(type, "IEND", 4) == 0) break;
  }
  if (!seen_idat) return "corrupt PNG image (no IDAT chunk)";
  if (!stream_done) return "truncated PNG image data (its zlib stream does not end)";
  return {};
}

std::string pngFileDamage(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  unsigned char head[kPngSignatureBytes] = {};
  file.read(reinterpret_cast<char*>(head), sizeof(head));
  if (!isPng(head, size_t(file.gcount()))) return {};
  std::error_code ec;
  const uintmax_t bytes = std::filesystem::file_size(path, ec);
  if (ec || bytes > (uintmax_t(1) << 30)) return {};
  std::vector<unsigned char> whole(size_t(bytes), 0);
  file.seekg(0);
  file.read(reinterpret_cast<char*>(whole.data()), std::streamsize(whole.size()));
  if (size_t(file.gcount()) != whole.size()) return "cannot read the whole file";
  return pngDamage(whole.data(), whole.size());
}

}  // namespace strata
