// Texture decoding (preprocess/texture_loader.h) and textures attached to scenes by the glTF and
// OBJ + MTL loaders. Every input is written by the test into STRATA_TEST_OUTPUT_DIR (images with
// OpenImageIO, or byte for byte where the bytes themselves are the point), except assimp's models.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <sys/resource.h>

#include <glm/glm.hpp>

#include "preprocess/mesh_loader.h"
#include "preprocess/scene/scene.h"
#include "preprocess/texture_loader.h"
#include "test_support.h"

namespace {

using namespace strata;
using namespace strata::test;  // test_support.h
namespace fs = std::filesystem;

// A fresh folder per test.
fs::path outDir() { return strata::test::freshTestDir("texture_loading"); }

// Writes `data` (nc channels of `type`, row-major, top row first) with OpenImageIO. Two and four
// channels carry straight alpha.
void writeOiio(const fs::path& path, int w, int h, int nc, OIIO::TypeDesc type, const void* data,
               int jpeg_quality = 100) {
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(path.string());
  ASSERT_TRUE(out) << OIIO::geterror();
  OIIO::ImageSpec spec(w, h, nc, type);
  if (nc == 2 || nc == 4) spec.alpha_channel = nc - 1;
  spec.attribute("oiio:UnassociatedAlpha", 1);
  spec.attribute("Compression", "jpeg:" + std::to_string(jpeg_quality));
  ASSERT_TRUE(out->open(path.string(), spec)) << out->geterror();
  ASSERT_TRUE(out->write_image(type, data)) << out->geterror();
  ASSERT_TRUE(out->close());
}

// A 3x2 RGBA image with distinct texels and alphas: the decoder's reference.
const uint8_t kRgba3x2[] = {255, 0,  0,  255, 0,   255, 0,  128, 0, 0, 255, 0,
                            10,  20, 30, 40,  200, 100, 50, 255, 1, 2, 3,   254};

void writeRgbaPng(const fs::path& path) {
  writeOiio(path, 3, 2, 4, OIIO::TypeDesc::UINT8, kRgba3x2);
}

glm::vec4 rgba8(const uint8_t* p) { return glm::vec4(p[0], p[1], p[2], p[3]) / 255.0f; }

void expectTexelsNear(const TextureImage& t, const std::vector<glm::vec4>& expected, float tol) {
  ASSERT_EQ(t.texels.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i)
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(t.texels[i][c], expected[i][c], tol) << "texel " << i << " channel " << c;
}

// The Error's message: one line naming `name`, holding `fragment`.
template <typename F>
void expectTextureError(F&& load, const std::string& name, const std::string& fragment) {
  try {
    load();
    ADD_FAILURE() << name << " decoded but should have failed";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(name), std::string::npos) << "message does not name " << name << ": " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "message is not one line: " << msg;
    EXPECT_NE(msg.find(fragment), std::string::npos) << "expected '" << fragment << "' in: " << msg;
  }
}

void expectLoadError(const fs::path& path, const std::vector<std::string>& fragments) {
  try {
    loadSceneFile(path.string());
    ADD_FAILURE() << path << " loaded but should have failed";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(path.string() + ": ", 0), 0u)
        << "message does not start with the path: " << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    for (const std::string& f : fragments)
      EXPECT_NE(msg.find(f), std::string::npos) << "expected '" << f << "' in: " << msg;
  }
}

bool hasWarning(const Scene& scene, const std::string& fragment) {
  for (const std::string& w : scene.report.warnings)
    if (w.find(fragment) != std::string::npos) return true;
  return false;
}

// ---------------------------------------------------------------------------------------------
// PNG bytes written by hand, for inputs OpenImageIO would never write: the deflate stream uses
// stored (uncompressed) blocks, so every byte is known.

uint32_t crc32(const std::string& bytes) {
  uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    crc ^= b;
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

std::string be32(uint32_t v) { return {char(v >> 24), char(v >> 16), char(v >> 8), char(v)}; }

std::string pngChunk(const std::string& type, const std::string& data) {
  return be32(uint32_t(data.size())) + type + data + be32(crc32(type + data));
}

// colour_type: 0 grey, 2 RGB, 4 grey+alpha, 6 RGBA. `rows` are the raw scanlines (filter byte 0
// is prepended here).
std::string handMadePng(uint32_t w, uint32_t h, int bit_depth, int colour_type,
                        const std::vector<std::string>& rows) {
  std::string raw;
  for (const std::string& row : rows) raw += '\0' + row;
  std::string z = "\x78\x01";  // zlib header, no dictionary
  size_t at = 0;
  do {
    const size_t n = std::min<size_t>(raw.size() - at, 65535);
    const bool last = at + n == raw.size();
    z += char(last ? 1 : 0);
    z += char(n & 0xFF);
    z += char(n >> 8);
    z += char(~n & 0xFF);
    z += char((~n >> 8) & 0xFF);
    z += raw.substr(at, n);
    at += n;
  } while (at < raw.size());
  uint32_t a = 1, b = 0;
  for (unsigned char c : raw) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  z += be32(b << 16 | a);
  const std::string ihdr =
      be32(w) + be32(h) + char(bit_depth) + char(colour_type) + std::string("\0\0\0", 3);
  return "\x89PNG\r\n\x1a\n" + pngChunk("IHDR", ihdr) + pngChunk("IDAT", z) + pngChunk("IEND", "");
}

// ---------------------------------------------------------------------------------------------
// Decoding

TEST(TextureDecode, PngRgbaExactTexelsFromFileAndMemory) {
  const fs::path dir = outDir();
  writeRgbaPng(dir / "rgba.png");
  std::vector<glm::vec4> expected;
  for (size_t i = 0; i < 6; ++i) expected.push_back(rgba8(kRgba3x2 + 4 * i));

  const auto file = loadTextureFile((dir / "rgba.png").string());
  ASSERT_EQ(file->width, 3);
  ASSERT_EQ(file->height, 2);
  // Exact: 8-bit values scaled to 0..1, straight alpha (not premultiplied), row 0 on top.
  expectTexelsNear(*file, expected, 0.0f);

  const std::string bytes = readBytes(dir / "rgba.png");
  const auto memory = loadTextureMemory(reinterpret_cast<const unsigned char*>(bytes.data()),
                                        bytes.size(), "embedded image");
  ASSERT_EQ(memory->width, 3);
  expectTexelsNear(*memory, expected, 0.0f);
}

TEST(TextureDecode, JpegFromFileAndMemory) {
  const fs::path dir = outDir();
  // Flat 8x8 blocks survive JPEG (quality 100) to within a step of the 8-bit value: a grey JPEG
  // of two blocks, and an RGB JPEG of one colour (chroma is subsampled, so one colour only).
  std::vector<uint8_t> grey(16 * 8);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 16; ++x) grey[size_t(y * 16 + x)] = x < 8 ? 40 : 200;
  writeOiio(dir / "grey.jpg", 16, 8, 1, OIIO::TypeDesc::UINT8, grey.data());
  std::vector<uint8_t> rgb(16 * 16 * 3);
  for (size_t i = 0; i < rgb.size(); i += 3) {
    rgb[i] = 200;
    rgb[i + 1] = 120;
    rgb[i + 2] = 30;
  }
  writeOiio(dir / "colour.jpeg", 16, 16, 3, OIIO::TypeDesc::UINT8, rgb.data());

  for (bool memory : {false, true}) {
    SCOPED_TRACE(memory ? "memory" : "file");
    auto load = [&](const fs::path& p) {
      if (!memory) return loadTextureFile(p.string());
      const std::string b = readBytes(p);
      return loadTextureMemory(reinterpret_cast<const unsigned char*>(b.data()), b.size(),
                               "no extension");
    };
    const auto g = load(dir / "grey.jpg");
    ASSERT_EQ(g->width, 16);
    ASSERT_EQ(g->height, 8);
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 16; ++x) {
        const glm::vec4 t = g->texels[size_t(y * 16 + x)];
        const float v = (x < 8 ? 40 : 200) / 255.0f;
        EXPECT_NEAR(t.r, v, 1.01f / 255) << x << "," << y;
        EXPECT_EQ(t.r, t.g);
        EXPECT_EQ(t.r, t.b);
        EXPECT_EQ(t.a, 1.0f);
      }
    const auto c = load(dir / "colour.jpeg");
    ASSERT_EQ(c->width, 16);
    for (const glm::vec4& t : c->texels) {
      EXPECT_NEAR(t.r, 200 / 255.0f, 2.01f / 255);
      EXPECT_NEAR(t.g, 120 / 255.0f, 2.01f / 255);
      EXPECT_NEAR(t.b, 30 / 255.0f, 2.01f / 255);
      EXPECT_EQ(t.a, 1.0f);
    }
  }
}

TEST(TextureDecode, GreyAndGreyAlphaExpandToRgba) {
  const fs::path dir = outDir();
  const uint8_t grey[] = {0, 64, 255, 7};
  writeOiio(dir / "grey.png", 2, 2, 1, OIIO::TypeDesc::UINT8, grey);
  const auto g = loadTextureFile((dir / "grey.png").string());
  std::vector<glm::vec4> expected;
  for (uint8_t v : grey) expected.emplace_back(glm::vec3(v / 255.0f), 1.0f);
  expectTexelsNear(*g, expected, 0.0f);

  const uint8_t grey_alpha[] = {10, 255, 20, 0, 30, 128, 40, 1};
  writeOiio(dir / "grey_alpha.png", 2, 2, 2, OIIO::TypeDesc::UINT8, grey_alpha);
  const auto ga = loadTextureFile((dir / "grey_alpha.png").string());
  expected.clear();
  for (int i = 0; i < 4; ++i)
    expected.emplace_back(glm::vec3(grey_alpha[2 * i] / 255.0f), grey_alpha[2 * i + 1] / 255.0f);
  expectTexelsNear(*ga, expected, 0.0f);  // alpha kept straight, grey not premultiplied

  // The same inputs byte for byte (colour types 0 and 4), and RGB (2): alpha 1.
  const std::string hand = handMadePng(2, 1, 8, 4, {std::string("\x50\x80\xA0\x00", 4)});
  const auto h = loadTextureMemory(reinterpret_cast<const unsigned char*>(hand.data()), hand.size(),
                                   "hand-made grey+alpha");
  expectTexelsNear(*h,
                   {glm::vec4(glm::vec3(0x50 / 255.0f), 0x80 / 255.0f),
                    glm::vec4(glm::vec3(0xA0 / 255.0f), 0.0f)},
                   0.0f);
  const std::string rgb =
      handMadePng(1, 2, 8, 2, {std::string("\x01\x02\x03", 3), std::string("\xFF\x00\x7F", 3)});
  writeBytes(dir / "rgb.png", rgb);
  const auto r = loadTextureFile((dir / "rgb.png").string());
  expectTexelsNear(*r, {glm::vec4(1, 2, 3, 255) / 255.0f, glm::vec4(255, 0, 127, 255) / 255.0f},
                   0.0f);
}

TEST(TextureDecode, SixteenBitIsScaledToUnitRange) {
  const fs::path dir = outDir();
  const uint16_t rgba[] = {0, 65535, 1000, 65535, 32768, 12345, 65534, 0};
  writeOiio(dir / "rgba16.png", 2, 1, 4, OIIO::TypeDesc::UINT16, rgba);
  const auto t = loadTextureFile((dir / "rgba16.png").string());
  std::vector<glm::vec4> expected;
  for (int i = 0; i < 2; ++i)
    expected.push_back(glm::vec4(rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2], rgba[4 * i + 3]) /
                       65535.0f);
  expectTexelsNear(*t, expected, 1e-7f);
  EXPECT_NE(t->texels[0].b, 0.0f);  // 1000 / 65535: not rounded to 8 bits
  EXPECT_NEAR(t->texels[0].b, 1000 / 65535.0f, 1e-7f);

  // A 16-bit grey PNG written byte for byte (big-endian samples).
  const std::string grey16 = handMadePng(2, 1, 16, 0, {std::string("\x12\x34\xFF\xFF", 4)});
  const auto g = loadTextureMemory(reinterpret_cast<const unsigned char*>(grey16.data()),
                                   grey16.size(), "grey16");
  expectTexelsNear(*g, {glm::vec4(glm::vec3(0x1234 / 65535.0f), 1.0f), glm::vec4(1.0f)}, 1e-7f);
}

TEST(TextureDecode, CorruptTruncatedEmptyAndMissingFilesAreNamedErrors) {
  const fs::path dir = outDir();
  // Random bytes with a .png name.
  std::mt19937 rng(6);
  std::string junk(4096, '\0');
  for (char& c : junk) c = char(rng());
  writeBytes(dir / "random.png", junk);
  expectTextureError([&] { loadTextureFile((dir / "random.png").string()); }, "random.png",
                     "cannot read as an image");

  // A PNG cut inside its pixel data (a noisy image, so the compressed data is long).
  std::vector<uint8_t> noise(64 * 64 * 3);
  for (uint8_t& v : noise) v = uint8_t(rng());
  writeOiio(dir / "noise.png", 64, 64, 3, OIIO::TypeDesc::UINT8, noise.data());
  const std::string whole = readBytes(dir / "noise.png");
  writeBytes(dir / "truncated.png", whole.substr(0, whole.size() / 2));
  expectTextureError([&] { loadTextureFile((dir / "truncated.png").string()); }, "truncated.png",
                     "truncated");
  // ... and cut inside its header.
  writeBytes(dir / "header_only.png", whole.substr(0, 20));
  expectTextureError([&] { loadTextureFile((dir / "header_only.png").string()); },
                     "header_only.png", "image");
  // A flipped byte in the pixel data fails the chunk's CRC.
  std::string flipped = whole;
  flipped[flipped.size() / 2] = char(flipped[flipped.size() / 2] ^ 0x5A);
  writeBytes(dir / "flipped.png", flipped);
  expectTextureError([&] { loadTextureFile((dir / "flipped.png").string()); }, "flipped.png",
                     "corrupt");
  // A truncated JPEG.
  writeOiio(dir / "noise.jpg", 64, 64, 3, OIIO::TypeDesc::UINT8, noise.data(), 90);
  const std::string jpeg = readBytes(dir / "noise.jpg");
  writeBytes(dir / "truncated.jpg", jpeg.substr(0, jpeg.size() / 2));
  expectTextureError([&] { loadTextureFile((dir / "truncated.jpg").string()); }, "truncated.jpg",
                     "truncated");

  writeBytes(dir / "empty.png", "");
  expectTextureError([&] { loadTextureFile((dir / "empty.png").string()); }, "empty.png", "empty");
  expectTextureError([&] { loadTextureFile((dir / "missing.png").string()); }, "missing.png",
                     "no such file");
  expectTextureError([&] { loadTextureFile(dir.string()); }, dir.string(), "folder");

  // The same from memory: the message names the given name.
  expectTextureError(
      [&] {
        loadTextureMemory(reinterpret_cast<const unsigned char*>(junk.data()), junk.size(),
                          "image 3 'junk'");
      },
      "image 3 'junk'", "cannot read as an image");
  const std::string cut = whole.substr(0, whole.size() / 2);
  expectTextureError(
      [&] {
        loadTextureMemory(reinterpret_cast<const unsigned char*>(cut.data()), cut.size(), "cut");
      },
      "cut", "truncated");
  expectTextureError([&] { loadTextureMemory(nullptr, 0, "nothing"); }, "nothing", "empty");
}

TEST(TextureDecode, AbsurdSizesAreRefusedFromTheHeader) {
  const fs::path dir = outDir();
  // IHDR claims 100000 x 100000 RGB (30 GB of pixels); the data is a few bytes. The size check
  // runs on the header, so the refusal is immediate and allocates nothing.
  struct Case {
    uint32_t w, h;
    const char* name;
    const char* fragment;
  } cases[] = {
      {100000, 100000, "huge.png", "100000x100000"},
      {16385, 1, "wide.png", "16385x1"},
      {1, 16385, "tall.png", "1x16385"},
      {1, 2000000, "taller.png", "1x2000000"},  // past libpng's own limit: no "libpng error" line
      {0, 10, "zero_width.png", "image"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const std::string png = handMadePng(c.w, c.h, 8, 2, {std::string(3, '\0')});
    writeBytes(dir / c.name, png);
    const auto start = std::chrono::steady_clock::now();
    expectTextureError([&] { loadTextureFile((dir / c.name).string()); }, c.name, c.fragment);
    expectTextureError(
        [&] {
          loadTextureMemory(reinterpret_cast<const unsigned char*>(png.data()), png.size(), c.name);
        },
        c.name, c.fragment);
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  }
  // 16384^2 is exactly kMaxTextureTexels: with today's limits the per-side rule is the binding
  // one (the texel budget is checked too, for when the limits change).
  static_assert(int64_t(strata::kMaxTextureSize) * strata::kMaxTextureSize <=
                strata::kMaxTextureTexels);
}

// ---------------------------------------------------------------------------------------------
// glTF: decoded base colour textures and samplers

TEST(GltfTextures, BoxTexturedVariantsGiveTheSameTexelsAndSampler) {
  // The three files' samplers agree on the filters (magFilter LINEAR, minFilter
  // NEAREST_MIPMAP_LINEAR: trilinear) but not on wrapping: the .gltf with the external PNG says
  // wrapS MIRRORED_REPEAT, wrapT CLAMP_TO_EDGE, the GLB and the embedded one REPEAT on both.
  struct Case {
    const char* rel;
    Wrap s, t;
  } cases[] = {{"glTF2/BoxTextured-glTF/BoxTextured.gltf", Wrap::MirroredRepeat, Wrap::Clamp},
               {"glTF2/BoxTextured-glTF-Binary/BoxTextured.glb", Wrap::Repeat, Wrap::Repeat},
               {"glTF2/BoxTextured-glTF-Embedded/BoxTextured.gltf", Wrap::Repeat, Wrap::Repeat}};
  // The reference: the PNG beside the .gltf, decoded directly.
  const auto reference = loadTextureFile(assimpPath("glTF2/BoxTextured-glTF/CesiumLogoFlat.png"));
  ASSERT_EQ(reference->width, 211);
  ASSERT_EQ(reference->height, 211);
  for (const Case& c : cases) {
    SCOPED_TRACE(c.rel);
    const Scene scene = loadSceneFile(assimpPath(c.rel));
    ASSERT_EQ(scene.textures.size(), 1u);
    ASSERT_TRUE(scene.textures[0].image);
    EXPECT_EQ(scene.textures[0].image->width, 211);
    EXPECT_EQ(scene.textures[0].image->height, 211);
    EXPECT_TRUE(scene.textures[0].image->texels == reference->texels);
    const strata::Material& m = scene.materials.at(scene.meshes.at(0).material);
    EXPECT_EQ(m.texture, 0);
    EXPECT_EQ(m.sampler.wrap_s, c.s);
    EXPECT_EQ(m.sampler.wrap_t, c.t);
    EXPECT_EQ(m.sampler.filter, Filter::Trilinear);
    EXPECT_EQ(scene.meshes[0].texcoords.size(), scene.meshes[0].positions.size());
  }
}

std::string base64(const std::string& bytes) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = uint32_t(uint8_t(bytes[i])) << 16;
    if (i + 1 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 1])) << 8;
    if (i + 2 < bytes.size()) v |= uint32_t(uint8_t(bytes[i + 2]));
    out += k[(v >> 18) & 63];
    out += k[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? k[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? k[v & 63] : '=';
  }
  return out;
}

// A glTF of `materials.size()` triangles, one mesh and node each, triangle i drawn with material
// i; every triangle has TEXCOORD_0 unless `with_uv` is false. `images`, `samplers` and
// `textures` are JSON array bodies.
std::string gltfWith(const std::vector<std::string>& materials, const std::string& textures,
                     const std::string& samplers, const std::string& images, bool with_uv = true) {
  std::string buffer;
  auto put = [&](float f) { buffer.append(reinterpret_cast<const char*>(&f), 4); };
  for (float f : {0.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.0f, 1.0f, 0.0f}) put(f);
  for (float f : {0.0f, 1.0f, 1.0f, 1.0f, 0.0f, 0.0f}) put(f);
  std::string meshes, nodes, node_list;
  for (size_t i = 0; i < materials.size(); ++i) {
    const std::string n = std::to_string(i);
    meshes += std::string(i ? "," : "") + "{\"primitives\":[{\"attributes\":{\"POSITION\":0" +
              (with_uv ? ",\"TEXCOORD_0\":1" : "") + "},\"material\":" + n + "}]}";
    nodes += std::string(i ? "," : "") + "{\"mesh\":" + n + ",\"translation\":[" + n + ",0,0]}";
    node_list += std::string(i ? "," : "") + n;
  }
  std::string mats;
  for (size_t i = 0; i < materials.size(); ++i) mats += (i ? "," : "") + materials[i];
  return "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[" + node_list +
         "]}],\"nodes\":[" + nodes + "],\"meshes\":[" + meshes + "],\"materials\":[" + mats +
         "],\"textures\":[" + textures + "],\"samplers\":[" + samplers + "],\"images\":[" + images +
         "],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":3,\"type\":\"VEC3\","
         "\"min\":[0,0,0],\"max\":[1,1,0]},{\"bufferView\":1,\"componentType\":5126,\"count\":3,"
         "\"type\":\"VEC2\"}],\"bufferViews\":[{\"buffer\":0,\"byteLength\":36},{\"buffer\":0,"
         "\"byteOffset\":36,\"byteLength\":24}],\"buffers\":[{\"byteLength\":60,\"uri\":\"data:"
         "application/octet-stream;base64," +
         base64(buffer) + "\"}]}";
}

std::string materialUsing(int texture, const std::string& extra = "") {
  return "{\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":" + std::to_string(texture) +
         extra + "}}}";
}

TEST(GltfTextures, SamplerWrapModesAndFiltersAndOneDecodePerImage) {
  const fs::path dir = outDir();
  writeRgbaPng(dir / "tex.png");
  // Texture i uses sampler i (the last one none); all show image 0.
  const std::string samplers =
      "{\"wrapS\":33071,\"wrapT\":33648,\"magFilter\":9728,\"minFilter\":9987},"  // nearest wins
      "{\"wrapS\":33648,\"wrapT\":10497,\"magFilter\":9729,\"minFilter\":9987},"  // trilinear
      "{\"wrapS\":10497,\"wrapT\":33071,\"minFilter\":9986},"                     // trilinear
      "{\"minFilter\":9985},"  // LINEAR_MIPMAP_NEAREST: bilinear
      "{\"magFilter\":9729,\"minFilter\":9729},"
      "{}";
  const std::string textures =
      "{\"sampler\":0,\"source\":0},{\"sampler\":1,\"source\":0},{\"sampler\":2,\"source\":0},"
      "{\"sampler\":3,\"source\":0},{\"sampler\":4,\"source\":0},{\"sampler\":5,\"source\":0},"
      "{\"source\":0}";
  std::vector<std::string> materials;
  for (int i = 0; i < 7; ++i) materials.push_back(materialUsing(i));
  writeBytes(dir / "samplers.gltf",
             gltfWith(materials, textures, samplers, "{\"uri\":\"tex.png\"}"));
  const Scene scene = loadSceneFile((dir / "samplers.gltf").string());

  ASSERT_EQ(scene.textures.size(), 1u);  // one image, decoded once for seven textures
  EXPECT_EQ(scene.textures[0].name, "tex.png");
  std::vector<glm::vec4> expected;
  for (size_t i = 0; i < 6; ++i) expected.push_back(rgba8(kRgba3x2 + 4 * i));
  expectTexelsNear(*scene.textures[0].image, expected, 0.0f);

  struct Expect {
    Wrap s, t;
    Filter f;
  } want[] = {
      {Wrap::Clamp, Wrap::MirroredRepeat, Filter::Nearest},
      {Wrap::MirroredRepeat, Wrap::Repeat, Filter::Trilinear},
      {Wrap::Repeat, Wrap::Clamp, Filter::Trilinear},
      {Wrap::Repeat, Wrap::Repeat, Filter::Bilinear},
      {Wrap::Repeat, Wrap::Repeat, Filter::Bilinear},
      {Wrap::Repeat, Wrap::Repeat, Filter::Bilinear},
      {Wrap::Repeat, Wrap::Repeat, Filter::Bilinear},  // no sampler: glTF's defaults
  };
  ASSERT_EQ(scene.meshes.size(), 7u);
  for (size_t i = 0; i < 7; ++i) {
    SCOPED_TRACE(i);
    const strata::Material& m = scene.materials.at(scene.meshes[i].material);
    EXPECT_EQ(m.texture, 0);
    EXPECT_EQ(m.base_color_texture, "tex.png");
    EXPECT_EQ(m.sampler.wrap_s, want[i].s);
    EXPECT_EQ(m.sampler.wrap_t, want[i].t);
    EXPECT_EQ(m.sampler.filter, want[i].f);
  }
}

TEST(GltfTextures, OtherTexcoordSetsTransformsAndMissingUvs) {
  const fs::path dir = outDir();
  writeRgbaPng(dir / "tex.png");
  const std::vector<std::string> materials = {
      materialUsing(0, ",\"texCoord\":1"),
      materialUsing(0, ",\"extensions\":{\"KHR_texture_transform\":{\"scale\":[2,2]}}"),
      materialUsing(0)};
  writeBytes(dir / "sets.gltf", gltfWith(materials, "{\"source\":0}", "", "{\"uri\":\"tex.png\"}"));
  const Scene scene = loadSceneFile((dir / "sets.gltf").string());
  ASSERT_EQ(scene.meshes.size(), 3u);
  EXPECT_EQ(scene.materials.at(scene.meshes[0].material).texture, -1);
  EXPECT_TRUE(hasWarning(scene, "TEXCOORD_1")) << "no warning for texCoord 1";
  EXPECT_EQ(scene.materials.at(scene.meshes[1].material).texture, 0);
  EXPECT_TRUE(hasWarning(scene, "KHR_texture_transform"));
  EXPECT_EQ(scene.materials.at(scene.meshes[2].material).texture, 0);

  // A textured material on primitives without TEXCOORD_0: untextured there, with a warning.
  writeBytes(dir / "no_uv.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "", "{\"uri\":\"tex.png\"}", false));
  const Scene no_uv = loadSceneFile((dir / "no_uv.gltf").string());
  const strata::Material& m = no_uv.materials.at(no_uv.meshes.at(0).material);
  EXPECT_EQ(m.texture, -1);
  EXPECT_EQ(m.base_color_texture, "tex.png");
  EXPECT_TRUE(hasWarning(no_uv, "TEXCOORD_0"));
}

TEST(GltfTextures, EmbeddedImagesDecode) {
  const fs::path dir = outDir();
  writeRgbaPng(dir / "tex.png");
  const std::string png = readBytes(dir / "tex.png");
  writeBytes(dir / "data_uri.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "",
                      "{\"uri\":\"data:image/png;base64," + base64(png) + "\"}"));
  const Scene scene = loadSceneFile((dir / "data_uri.gltf").string());
  ASSERT_EQ(scene.textures.size(), 1u);
  EXPECT_EQ(scene.textures[0].image->width, 3);
  EXPECT_EQ(scene.materials.at(0).base_color_texture, "embedded:0");
  EXPECT_EQ(scene.materials.at(0).texture, 0);
}

TEST(GltfTextures, BadImagesFailTheLoadNamingAssetAndImage) {
  const fs::path dir = outDir();
  // Missing image file.
  writeBytes(dir / "missing.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "", "{\"uri\":\"not_there.png\"}"));
  expectLoadError(dir / "missing.gltf", {"image 0", "not_there.png", "no such file"});

  // Random bytes under a .png name.
  std::mt19937 rng(7);
  std::string junk(2000, '\0');
  for (char& c : junk) c = char(rng());
  writeBytes(dir / "junk.png", junk);
  writeBytes(dir / "junk.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "", "{\"uri\":\"junk.png\"}"));
  expectLoadError(dir / "junk.gltf", {"image 0", "junk.png", "cannot read as an image"});

  // A truncated PNG, through a data: URI.
  std::vector<uint8_t> noise(32 * 32 * 4);
  for (uint8_t& v : noise) v = uint8_t(rng());
  writeOiio(dir / "noise.png", 32, 32, 4, OIIO::TypeDesc::UINT8, noise.data());
  const std::string whole = readBytes(dir / "noise.png");
  writeBytes(dir / "truncated.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "",
                      "{\"uri\":\"data:image/png;base64," +
                          base64(whole.substr(0, whole.size() / 2)) + "\"}"));
  expectLoadError(dir / "truncated.gltf", {"image 0", "truncated"});

  // An absurd size in a header.
  writeBytes(dir / "huge.png", handMadePng(100000, 100000, 8, 6, {std::string(4, '\0')}));
  writeBytes(dir / "huge.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "", "{\"uri\":\"huge.png\"}"));
  expectLoadError(dir / "huge.gltf", {"huge.png", "100000x100000"});

  // An image outside the asset's folder stays refused.
  writeBytes(dir / "escape.gltf",
             gltfWith({materialUsing(0)}, "{\"source\":0}", "", "{\"uri\":\"../outside.png\"}"));
  writeRgbaPng(dir.parent_path() / "outside.png");
  expectLoadError(dir / "escape.gltf", {"../outside.png"});
}

TEST(GltfTextures, GlbBufferViewImageOutsideItsBufferIsAnError) {
  // BoxTextured.glb with the image's bufferView made longer than the buffer: tinygltf does not
  // check image views, the loader must (the JSON chunk is edited in place, same length).
  std::string glb = readBytes(assimpPath("glTF2/BoxTextured-glTF-Binary/BoxTextured.glb"));
  const fs::path dir = outDir();
  // The image uses the last bufferView in BoxTextured.glb (byteLength 2433 of a 3273-byte
  // buffer from offset 840); its byteLength's digits become 9s.
  ASSERT_NE(glb.find("\"images\":[{\"bufferView\":3"), std::string::npos);
  const size_t views = glb.find("\"bufferViews\"");
  ASSERT_NE(views, std::string::npos);
  const size_t last_len = glb.rfind("\"byteLength\"", glb.find(']', views));
  ASSERT_NE(last_len, std::string::npos);
  size_t digit = glb.find_first_of("0123456789", last_len);
  while (digit < glb.size() && std::isdigit(static_cast<unsigned char>(glb[digit])))
    glb[digit++] = '9';
  writeBytes(dir / "bad_view.glb", glb);
  try {
    const Scene scene = loadSceneFile((dir / "bad_view.glb").string());
    ADD_FAILURE() << "loaded a GLB whose image view leaves its buffer";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind((dir / "bad_view.glb").string() + ": ", 0), 0u) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
}

TEST(GltfTextures, Gltf1CesiumMilkTruckIsTextured) {
  // glTF 1.0 goes to its own reader (preprocess/gltf1_loader.cpp); its diffuse texture is decoded
  // like a 2.0 base colour texture. assimp-testmodels is installed by scripts/install-deps.sh.
  const std::string path = assimpPath("glTF/CesiumMilkTruck/CesiumMilkTruck.gltf");
  const Scene scene = loadSceneFile(path);
  EXPECT_GT(scene.triangleCount(), 0u);
  ASSERT_EQ(scene.textures.size(), 1u);
  EXPECT_EQ(scene.textures[0].image->width, 2048);
  bool textured = false;
  for (const auto& m : scene.materials) textured |= m.texture == 0;
  EXPECT_TRUE(textured);
}

// ---------------------------------------------------------------------------------------------
// OBJ + MTL

// A unit square in two triangles of material A (textured) and one of B between them, so the
// faces switch materials A, B, A.
void writeSquareObj(const fs::path& dir, const std::string& obj_name, const std::string& mtllib,
                    const std::string& mtl_name, const std::string& mtl) {
  writeBytes(dir / obj_name, "# test\nmtllib " + mtllib +
                                 "\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                                 "vt 0 0\nvt 1 0\nvt 1 1\nvt 0.25 0.75\n"
                                 "usemtl A\nf 1/1 2/2 3/3\n"
                                 "usemtl B\nf 2 5 3\n"
                                 "usemtl A\nf 1/1 3/3 4/4\n");
  if (!mtl_name.empty()) writeBytes(dir / mtl_name, mtl);
}

TEST(ObjMaterials, MapKdTexturesUsemtlSplitsAndFlippedV) {
  const fs::path dir = outDir();
  fs::create_directories(dir / "maps");
  writeRgbaPng(dir / "maps" / "my texture.png");
  writeSquareObj(dir, "square.obj", "square.mtl", "square.mtl",
                 "newmtl A\nKd 1 0.5 0.25\nd 0.75\n"
                 "map_Kd -clamp on -s 1 1 1 -o 0 0 0 -bm 1 maps\\my texture.png  \n"
                 "newmtl B\nKd 0.2 0.4 0.6\nTr 0.25\n");
  const Scene scene = loadSceneFile((dir / "square.obj").string());
  ASSERT_EQ(scene.materials.size(), 2u);
  ASSERT_EQ(scene.meshes.size(), 2u);
  ASSERT_EQ(scene.instances.size(), 2u);
  for (const strata::Instance& inst : scene.instances) {
    EXPECT_EQ(inst.object_id, 0u);
    EXPECT_EQ(inst.name, "square");
  }
  EXPECT_EQ(scene.triangleCount(), 3u);

  const strata::Mesh& a = scene.meshes[0];
  const strata::Mesh& b = scene.meshes[1];
  const strata::Material& ma = scene.materials[a.material];
  const strata::Material& mb = scene.materials[b.material];
  EXPECT_EQ(ma.name, "A");
  EXPECT_EQ(mb.name, "B");
  EXPECT_EQ(a.triangleCount(), 2u);
  EXPECT_EQ(b.triangleCount(), 1u);
  EXPECT_EQ(a.positions.size(), 4u);  // only the vertices its triangles use
  EXPECT_EQ(b.positions.size(), 3u);
  EXPECT_TRUE(b.texcoords.empty());

  // Kd and d in the colour; opacity stays the scene default.
  EXPECT_EQ(ma.color, glm::vec4(1.0f, 0.5f, 0.25f, 0.75f));
  EXPECT_EQ(mb.color, glm::vec4(0.2f, 0.4f, 0.6f, 0.75f));  // Tr 0.25 -> alpha 0.75
  EXPECT_EQ(ma.opacity, strata::kDefaultOpacity);

  ASSERT_EQ(scene.textures.size(), 1u);
  EXPECT_EQ(ma.texture, 0);
  EXPECT_EQ(ma.base_color_texture, "maps/my texture.png");
  EXPECT_EQ(ma.sampler.wrap_s, Wrap::Clamp);
  EXPECT_EQ(ma.sampler.wrap_t, Wrap::Clamp);
  EXPECT_EQ(mb.texture, -1);
  std::vector<glm::vec4> expected;
  for (size_t i = 0; i < 6; ++i) expected.push_back(rgba8(kRgba3x2 + 4 * i));
  expectTexelsNear(*scene.textures[0].image, expected, 0.0f);

  // v is flipped: the file's (u, v) is stored as (u, 1 - v).
  ASSERT_EQ(a.texcoords.size(), a.positions.size());
  bool saw_corner4 = false;
  for (size_t i = 0; i < a.positions.size(); ++i) {
    const glm::vec3 p = a.positions[i];
    const glm::vec2 uv = a.texcoords[i];
    if (p == glm::vec3(0, 0, 0)) {
      EXPECT_EQ(uv, glm::vec2(0.0f, 1.0f));
    } else if (p == glm::vec3(1, 0, 0)) {
      EXPECT_EQ(uv, glm::vec2(1.0f, 1.0f));
    } else if (p == glm::vec3(1, 1, 0)) {
      EXPECT_EQ(uv, glm::vec2(1.0f, 0.0f));
    } else if (p == glm::vec3(0, 1, 0)) {
      EXPECT_EQ(uv, glm::vec2(0.25f, 0.25f));
      saw_corner4 = true;
    }
  }
  EXPECT_TRUE(saw_corner4);
}

TEST(ObjMaterials, MissingLibraryIsAWarningMissingImageAnError) {
  const fs::path dir = outDir();
  // No MTL file: the faces keep their materials' names with the default colour, and a warning.
  writeSquareObj(dir, "no_mtl.obj", "absent.mtl", "", "");
  const Scene scene = loadSceneFile((dir / "no_mtl.obj").string());
  EXPECT_EQ(scene.triangleCount(), 3u);
  EXPECT_TRUE(hasWarning(scene, "absent.mtl"));
  for (const strata::Material& m : scene.materials) {
    EXPECT_EQ(m.color, glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
    EXPECT_EQ(m.texture, -1);
  }

  // A map_Kd naming a file that is not there: the load fails naming the OBJ, material and image.
  writeSquareObj(dir, "no_image.obj", "no_image.mtl", "no_image.mtl",
                 "newmtl A\nmap_Kd gone.png\nnewmtl B\n");
  expectLoadError(dir / "no_image.obj", {"material 'A'", "gone.png", "no such file"});

  // A corrupt image likewise.
  writeBytes(dir / "bad.png", "this is not a png at all");
  writeSquareObj(dir, "bad_image.obj", "bad_image.mtl", "bad_image.mtl",
                 "newmtl A\nmap_Kd bad.png\nnewmtl B\n");
  expectLoadError(dir / "bad_image.obj", {"material 'A'", "bad.png", "cannot read as an image"});

  // Images and libraries outside the model's folder, or absolute, are refused.
  writeRgbaPng(dir.parent_path() / "outside.png");
  writeSquareObj(dir, "escape.obj", "escape.mtl", "escape.mtl",
                 "newmtl A\nmap_Kd ../outside.png\nnewmtl B\n");
  expectLoadError(dir / "escape.obj", {"../outside.png", "outside the model's folder"});
  writeSquareObj(dir, "absolute.obj", "absolute.mtl", "absolute.mtl",
                 "newmtl A\nmap_Kd " + (dir.parent_path() / "outside.png").string() + "\n");
  expectLoadError(dir / "absolute.obj", {"outside.png", "absolute"});
  writeSquareObj(dir, "escape_lib.obj", "../escape.mtl", "", "");
  expectLoadError(dir / "escape_lib.obj", {"../escape.mtl", "outside the model's folder"});

  // A material that no library defines: default colour, warning.
  writeSquareObj(dir, "undefined.obj", "undefined.mtl", "undefined.mtl", "newmtl A\nKd 1 0 0\n");
  const Scene undefined = loadSceneFile((dir / "undefined.obj").string());
  EXPECT_TRUE(hasWarning(undefined, "usemtl 'B'"));
}

TEST(ObjMaterials, LibraryNamesWithSpacesAndSeveralLibraries) {
  const fs::path dir = outDir();
  writeRgbaPng(dir / "t.png");
  // One library whose name has a space, then two libraries on one line.
  writeSquareObj(dir, "spaced.obj", "my materials.mtl", "my materials.mtl",
                 "newmtl A\nmap_Kd t.png\nnewmtl B\nKd 0 1 0\n");
  const Scene spaced = loadSceneFile((dir / "spaced.obj").string());
  EXPECT_EQ(spaced.materials.at(spaced.meshes.at(0).material).texture, 0);
  EXPECT_EQ(spaced.materials.at(spaced.meshes.at(1).material).color, glm::vec4(0, 1, 0, 1));

  writeBytes(dir / "a.mtl", "newmtl A\nmap_kd t.png\n");  // lower-case keyword
  writeBytes(dir / "b.mtl", "newmtl B\nKd 0 0 1\n");
  writeSquareObj(dir, "two.obj", "a.mtl b.mtl", "", "");
  const Scene two = loadSceneFile((dir / "two.obj").string());
  EXPECT_EQ(two.materials.at(two.meshes.at(0).material).texture, 0);
  EXPECT_EQ(two.materials.at(two.meshes.at(1).material).color, glm::vec4(0, 0, 1, 1));
  EXPECT_TRUE(two.report.warnings.empty()) << two.report.warnings.front();
}

TEST(ObjMaterials, SpiderIsTextured) {
  const Scene scene = loadSceneFile(assimpPath("OBJ/spider.obj"));
  // spider.mtl's map_Kd names are written `.\name.jpg`; its materials use four of the five.
  EXPECT_GE(scene.textures.size(), 3u);
  EXPECT_GT(scene.meshes.size(), 1u);
  size_t textured_meshes = 0;
  for (const strata::Mesh& mesh : scene.meshes) {
    const strata::Material& m = scene.materials.at(mesh.material);
    if (m.texture < 0) continue;
    ++textured_meshes;
    EXPECT_EQ(mesh.texcoords.size(), mesh.positions.size());
    const auto& image = scene.textures.at(size_t(m.texture)).image;
    ASSERT_TRUE(image);
    EXPECT_GT(image->width, 0);
    EXPECT_EQ(image->texels.size(), size_t(image->width) * size_t(image->height));
  }
  EXPECT_GT(textured_meshes, 0u);
  for (const strata::Instance& inst : scene.instances) EXPECT_EQ(inst.object_id, 0u);
  // Each image decoded once, however many materials use it.
  for (size_t i = 0; i < scene.textures.size(); ++i)
    for (size_t j = i + 1; j < scene.textures.size(); ++j)
      EXPECT_NE(scene.textures[i].name, scene.textures[j].name);
}

TEST(ObjMaterials, AssimpMaterialFilesResolve) {
  {  // names with spaces, trailing spaces trimmed on both sides
    const Scene s = loadSceneFile(assimpPath("OBJ/space_in_material_name.obj"));
    ASSERT_EQ(s.materials.size(), 1u);
    EXPECT_EQ(s.materials[0].name, "Hard Shiny Plastic White");
    EXPECT_NEAR(s.materials[0].color.b, 0.411765f, 1e-6f);
    EXPECT_TRUE(s.report.warnings.empty()) << s.report.warnings.front();
  }
  {
    const Scene s = loadSceneFile(assimpPath("OBJ/box_mat_with_spaces.obj"));
    EXPECT_EQ(s.materials.at(0).name, "Material name with many, many spaces");
    EXPECT_EQ(s.materials.at(0).color, glm::vec4(0.2f, 0.2f, 0.2f, 1.0f));
  }
  {  // an empty material name, defined by an empty newmtl
    const Scene s = loadSceneFile(assimpPath("OBJ/empty_mat.obj"));
    ASSERT_EQ(s.materials.size(), 1u);
    EXPECT_EQ(s.materials[0].name, "");
    EXPECT_TRUE(s.report.warnings.empty()) << s.report.warnings.front();
  }
  {  // mtl3 is not in cube_usemtl.mtl: three materials, one of them undefined
    const Scene s = loadSceneFile(assimpPath("OBJ/cube_usemtl.obj"));
    EXPECT_EQ(s.materials.size(), 3u);
    EXPECT_EQ(s.meshes.size(), 3u);
    EXPECT_EQ(s.triangleCount(), 12u);
    EXPECT_TRUE(hasWarning(s, "usemtl 'mtl3'"));
  }
  {  // names a library that does not exist (cube_mtllib_after_g.mat)
    const Scene s = loadSceneFile(assimpPath("OBJ/cube_mtllib_after_g.obj"));
    EXPECT_TRUE(hasWarning(s, "cube_mtllib_after_g.mat"));
    EXPECT_EQ(s.triangleCount(), 12u);
  }
  {  // usemtl without any mtllib: a default-coloured material of that name
    const Scene s = loadSceneFile(assimpPath("OBJ/box.obj"));
    ASSERT_EQ(s.materials.size(), 1u);
    EXPECT_EQ(s.materials[0].name, "Default");
    EXPECT_EQ(s.materials[0].color, glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
  }
}

TEST(ObjMaterials, EveryAssimpObjKeepsItsGeometry) {
  // Materials must not change geometry: each OBJ gives the same triangles (count and dropped
  // counts) with its usemtl / mtllib lines as without them (a copy with those lines removed).
  const fs::path dir = outDir();
  for (const auto& entry : fs::directory_iterator(assimpPath("OBJ"))) {
    if (entry.path().extension() != ".obj") continue;
    SCOPED_TRACE(entry.path().string());
    std::string text = readBytes(entry.path()), stripped;
    size_t pos = 0;
    while (pos < text.size()) {
      size_t end = text.find('\n', pos);
      if (end == std::string::npos) end = text.size();
      const std::string line = text.substr(pos, end - pos + 1);
      const size_t b = line.find_first_not_of(" \t");
      const bool material = b != std::string::npos && (line.compare(b, 7, "usemtl ") == 0 ||
                                                       line.compare(b, 7, "mtllib ") == 0 ||
                                                       line.compare(b, 7, "usemtl\r") == 0);
      if (!material) stripped += line;
      pos = end + 1;
    }
    const fs::path plain = dir / entry.path().filename();
    writeBytes(plain, stripped);
    std::string with_error, without_error;
    Scene with, without;
    try {
      with = loadSceneFile(entry.path().string());
    } catch (const Error& e) {
      with_error = e.what();
    }
    try {
      without = loadSceneFile(plain.string());
    } catch (const Error& e) {
      without_error = e.what();
    }
    EXPECT_EQ(with_error.empty(), without_error.empty()) << with_error << " | " << without_error;
    EXPECT_EQ(with.triangleCount(), without.triangleCount());
    EXPECT_EQ(with.report.triangles_loaded, without.report.triangles_loaded);
    EXPECT_EQ(with.report.dropped_degenerate, without.report.dropped_degenerate);
    EXPECT_EQ(with.report.dropped_out_of_range, without.report.dropped_out_of_range);
    EXPECT_EQ(with.report.dropped_nonfinite, without.report.dropped_nonfinite);
    EXPECT_EQ(with.report.polygons_triangulated, without.report.polygons_triangulated);
  }
}

}  // namespace

// Images decode band by band (about a million texels each, whole rows of tiles for a tiled
// image): a scanline image of several bands and a tiled TIFF whose tiles straddle the image's
// edges come out texel for texel, and a few bytes claiming a huge image are refused at their
// first band.
TEST(TextureDecode, BandsOfScanlinesAndTilesGiveEveryTexel) {
  const fs::path dir = outDir();
  const int w = 1500, h = 1700;  // 3 bands of 699 rows; tiles of 64 cover 24 x 27, cut at edges
  std::vector<uint8_t> rgb(size_t(w) * h * 3);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = uint8_t((i * 2654435761u) >> 24);
  std::vector<glm::vec4> expected(size_t(w) * h);
  for (size_t i = 0; i < expected.size(); ++i)
    expected[i] = glm::vec4(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2], 255.0f) / 255.0f;

  writeOiio(dir / "scanlines.png", w, h, 3, OIIO::TypeDesc::UINT8, rgb.data());
  const auto scanlines = loadTextureFile((dir / "scanlines.png").string());
  ASSERT_EQ(scanlines->height, h);
  expectTexelsNear(*scanlines, expected, 0.0f);

  {
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create("tif");
    ASSERT_TRUE(out) << OIIO::geterror();
    ASSERT_TRUE(out->supports("tiles"));
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
    spec.tile_width = spec.tile_height = 64;
    const std::string path = (dir / "tiled.tif").string();
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, rgb.data())) << out->geterror();
    ASSERT_TRUE(out->close());
  }
  const auto tiled = loadTextureFile((dir / "tiled.tif").string());
  ASSERT_EQ(tiled->width, w);
  ASSERT_EQ(tiled->height, h);
  expectTexelsNear(*tiled, expected, 0.0f);

  // A 58-byte BMP claiming 13569 x 15616 pixels, within the size limits (the fuzzer's, also in
  // fuzz/regressions/fuzz_texture): refused as truncated at its first band of rows, not after
  // filling 3.4 GB of texels.
  const unsigned char kTinyBmp[] = {
      0x42, 0x4d, 0x3a, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x36, 0x00, 0x00, 0x00, 0x28,
      0x00, 0x00, 0x00, 0x01, 0x35, 0x00, 0x00, 0x00, 0x3d, 0x00, 0x00, 0x00, 0x00, 0x18, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00, 0x13, 0x0b, 0x00, 0x00, 0x13, 0x0b, 0x00,
      0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff, 0xff, 0xff, 0x00};
  const std::string bmp(reinterpret_cast<const char*>(kTinyBmp), sizeof kTinyBmp);
  ASSERT_EQ(bmp.size(), 58u);
  rusage before{}, after{};
  getrusage(RUSAGE_SELF, &before);
  try {
    loadTextureMemory(reinterpret_cast<const unsigned char*>(bmp.data()), bmp.size(), "tiny.bmp");
    FAIL() << "a 58-byte image claiming a huge size was accepted";
  } catch (const strata::Error& e) {
    EXPECT_NE(std::string(e.what()).find("tiny.bmp"), std::string::npos) << e.what();
  }
  getrusage(RUSAGE_SELF, &after);
  // The peak resident size grew by far less than the 3.4 GB the image claims (kilobytes).
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 1024L * 1024L);
}
