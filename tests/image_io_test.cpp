// Image output (atomic write through a temporary file), input of other formats, and the
// comparison metrics of `strata diff`.
#include "preprocess/image_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "preprocess/scene/scene.h"

namespace strata {
namespace {

namespace fs = std::filesystem;

// A fresh, empty folder for one test.
fs::path testFolder(const std::string& name) {
#ifdef STRATA_TEST_OUTPUT_DIR
  fs::path root = fs::path(STRATA_TEST_OUTPUT_DIR) / "image_test";
#else
  fs::path root = fs::temp_directory_path() / ("strata-image-test-" + std::to_string(::getpid()));
#endif
  const fs::path dir = root / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<std::string> filesIn(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string fileBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void writeBytes(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out << bytes;
}

Image gradient(int w, int h) {
  Image img(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      uint8_t* p = img.pixel(x, y);
      p[0] = uint8_t(x * 7 + y);
      p[1] = uint8_t(y * 13);
      p[2] = uint8_t((x * y) & 255);
      p[3] = uint8_t(255 - x);  // alpha survives a PNG round trip
    }
  return img;
}

TEST(Image, PngRoundTripIsExactAndLeavesNoTemporaryFile) {
  const fs::path dir = testFolder("round_trip");
  const Image img = gradient(37, 21);
  const std::string path = (dir / "out.png").string();
  writeImage(img, path);
  EXPECT_EQ(filesIn(dir), std::vector<std::string>{"out.png"});
  const Image back = readImage(path);
  ASSERT_EQ(back.width, 37);
  ASSERT_EQ(back.height, 21);
  EXPECT_EQ(back.rgba, img.rgba);

  // Writing again replaces the file.
  Image other = gradient(37, 21);
  other.pixel(3, 4)[0] ^= 0xFF;
  writeImage(other, path);
  EXPECT_EQ(readImage(path).rgba, other.rgba);
  EXPECT_EQ(filesIn(dir), std::vector<std::string>{"out.png"});
}

TEST(Image, UnwritableFolderThrowsAndCreatesNothing) {
  const fs::path dir = testFolder("unwritable");
  const std::string path = (dir / "missing-folder" / "out.png").string();
  try {
    writeImage(gradient(4, 4), path);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_TRUE(filesIn(dir).empty());

  // A read-only folder (meaningless for root, who may write anyway).
  if (::geteuid() != 0) {
    const fs::path ro = dir / "read-only";
    fs::create_directories(ro);
    fs::permissions(ro, fs::perms::owner_read | fs::perms::owner_exec);
    EXPECT_THROW(writeImage(gradient(4, 4), (ro / "out.png").string()), Error);
    fs::permissions(ro, fs::perms::owner_all);
    EXPECT_TRUE(filesIn(ro).empty());
  }
}

TEST(Image, FailedWriteKeepsTheOldFile) {
  const fs::path dir = testFolder("keep_old");
  // An unknown format: no writer, so the existing file must stay as it was.
  const fs::path unknown = dir / "picture.notaformat";
  writeBytes(unknown, "the old contents");
  try {
    writeImage(gradient(4, 4), unknown.string());
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(unknown.string() + ": ", 0), 0u) << e.what();
  }
  EXPECT_EQ(fileBytes(unknown), "the old contents");

  // A good PNG survives a failed write of an empty image.
  const fs::path good = dir / "good.png";
  writeImage(gradient(5, 3), good.string());
  const std::string before = fileBytes(good);
  EXPECT_THROW(writeImage(Image(), good.string()), Error);
  EXPECT_EQ(fileBytes(good), before);

  // A folder where the file should go: the rename fails and the temporary file is removed.
  const fs::path folder = dir / "folder.png";
  fs::create_directories(folder / "inside");
  EXPECT_THROW(writeImage(gradient(4, 4), folder.string()), Error);
  EXPECT_TRUE(fs::is_directory(folder / "inside"));

  EXPECT_EQ(filesIn(dir),
            (std::vector<std::string>{"folder.png", "good.png", "picture.notaformat"}));
}

TEST(Image, ReadsRgbAndGreyFormats) {
  const fs::path dir = testFolder("formats");
  // Binary PPM (RGB, no alpha) and PGM (grey).
  writeBytes(dir / "rgb.ppm",
             std::string("P6\n2 1\n255\n") + std::string("\x0a\x14\x1e\xc8\xb4\xa0", 6));
  const Image rgb = readImage((dir / "rgb.ppm").string());
  ASSERT_EQ(rgb.width, 2);
  ASSERT_EQ(rgb.height, 1);
  EXPECT_EQ(rgb.rgba, (std::vector<uint8_t>{10, 20, 30, 255, 200, 180, 160, 255}));

  writeBytes(dir / "grey.pgm", std::string("P5\n1 2\n255\n") + std::string("\x07\xf0", 2));
  const Image grey = readImage((dir / "grey.pgm").string());
  ASSERT_EQ(grey.width, 1);
  ASSERT_EQ(grey.height, 2);
  EXPECT_EQ(grey.rgba, (std::vector<uint8_t>{7, 7, 7, 255, 240, 240, 240, 255}));
}

TEST(Image, ReadingMissingOrCorruptFilesThrowsNamingThePath) {
  const fs::path dir = testFolder("bad_input");
  const std::string missing = (dir / "missing.png").string();
  try {
    readImage(missing);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing + ": ", 0), 0u) << e.what();
  }
  const fs::path corrupt = dir / "corrupt.png";
  writeBytes(corrupt, "\x89PNG\r\n\x1a\n this is not really a PNG file");
  try {
    readImage(corrupt.string());
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()).rfind(corrupt.string() + ": ", 0), 0u) << e.what();
  }
  // (A PNG truncated inside its pixel data also throws, but OpenImageIO 2.4 leaks its error
  // string when libpng long-jumps out of the read, which fails a LeakSanitizer run.)
}

TEST(Image, CompareIdenticalImages) {
  const Image a = gradient(16, 8);
  Image b = a;
  for (size_t i = 3; i < b.rgba.size(); i += 4) b.rgba[i] = 0;  // alpha is ignored
  const ImageDiff d = compareImages(a, b);
  EXPECT_EQ(d.pixels, 128u);
  EXPECT_TRUE(std::isinf(d.psnr) && d.psnr > 0);
  EXPECT_EQ(d.max_abs, 0);
  EXPECT_EQ(d.mean_abs, 0.0);
  EXPECT_EQ(d.within_1, 1.0);
  EXPECT_EQ(d.within_2, 1.0);
}

TEST(Image, CompareOnePixelOff) {
  Image a(10, 10);
  for (auto& v : a.rgba) v = 100;
  Image b = a;
  b.pixel(4, 7)[1] = 103;  // one channel of one pixel off by 3
  const ImageDiff d = compareImages(a, b);
  const double n = 100.0;
  EXPECT_EQ(d.pixels, 100u);
  EXPECT_EQ(d.max_abs, 3);
  EXPECT_DOUBLE_EQ(d.within_2, 1.0 - 1.0 / n);
  EXPECT_DOUBLE_EQ(d.within_1, 1.0 - 1.0 / n);
  EXPECT_DOUBLE_EQ(d.mean_abs, 3.0 / (3.0 * n));
  const double mse = 9.0 / (3.0 * n);
  EXPECT_NEAR(d.psnr, 10.0 * std::log10(255.0 * 255.0 / mse), 1e-9);

  // Off by 2 counts as within 2 but not within 1.
  b.pixel(4, 7)[1] = 102;
  const ImageDiff d2 = compareImages(a, b);
  EXPECT_DOUBLE_EQ(d2.within_2, 1.0);
  EXPECT_DOUBLE_EQ(d2.within_1, 1.0 - 1.0 / n);
}

TEST(Image, SizeMismatchThrowsNamingBothSizes) {
  const Image a(4, 3), b(3, 4);
  try {
    compareImages(a, b);
    FAIL() << "expected an Error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("4x3"), std::string::npos) << what;
    EXPECT_NE(what.find("3x4"), std::string::npos) << what;
  }
  EXPECT_THROW(differenceImage(a, b), Error);
}

TEST(Image, DifferenceImageAmplifies) {
  Image a(2, 1), b(2, 1);
  a.pixel(0, 0)[0] = 10;
  b.pixel(0, 0)[0] = 13;  // |3| x 8 = 24
  a.pixel(1, 0)[2] = 200;
  b.pixel(1, 0)[2] = 100;  // |100| x 8 clamps to 255
  const Image d = differenceImage(a, b);
  EXPECT_EQ(d.rgba, (std::vector<uint8_t>{24, 0, 0, 255, 0, 0, 255, 255}));
}

// SSIM: 1 for identical images; for two flat images of values u and v, (2uv + C1) / (u^2 + v^2 +
// C1) everywhere (no variance), C1 = (0.01 x 255)^2; the map's interior mean is the figure; too
// small or mismatched images throw. (Agreement with scikit-image: python/tests.)
TEST(Image, StructuralSimilarity) {
  const Image a = gradient(40, 30);
  EXPECT_DOUBLE_EQ(structuralSimilarity(a, a), 1.0);
  Image flat_u(24, 20), flat_v(24, 20);
  for (size_t i = 0; i < flat_u.rgba.size(); ++i) {
    flat_u.rgba[i] = 100;
    flat_v.rgba[i] = 140;
  }
  const double c1 = (0.01 * 255.0) * (0.01 * 255.0);
  std::vector<float> map;
  const double expected = (2.0 * 100 * 140 + c1) / (100.0 * 100 + 140.0 * 140 + c1);
  EXPECT_NEAR(structuralSimilarity(flat_u, flat_v, &map), expected, 1e-12);
  ASSERT_EQ(map.size(), size_t(24 * 20));
  for (float v : map) EXPECT_NEAR(v, expected, 1e-6);
  Image noisy = a;
  for (size_t i = 0; i < noisy.rgba.size(); i += 7) noisy.rgba[i] = uint8_t(noisy.rgba[i] ^ 0x55);
  const double s = structuralSimilarity(a, noisy, &map);
  EXPECT_LT(s, 0.99);
  EXPECT_GT(s, -1.0);
  double interior = 0.0;
  for (int y = 5; y < 25; ++y)
    for (int x = 5; x < 35; ++x) interior += map[size_t(y) * 40 + size_t(x)];
  EXPECT_NEAR(interior / (20.0 * 30.0), s, 1e-6);
  EXPECT_THROW(structuralSimilarity(Image(10, 30), Image(10, 30)), Error);
  EXPECT_THROW(structuralSimilarity(a, Image(30, 40)), Error);
}

}  // namespace
}  // namespace strata
