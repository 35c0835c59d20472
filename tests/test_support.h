// Shared helpers of the test suite: scene set-up, and image comparison that writes the rendered,
// reference and difference images when a comparison fails.
#pragma once

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/reference/embree_reference.h"
#include "engine/renderer.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/image_io.h"

namespace strata::test {

// A scratch folder under the test output folder, named after the running test, removed
// afterwards.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::path(STRATA_TEST_OUTPUT_DIR) /
            (std::string(info->test_suite_name()) + "_" + info->name() + "_" +
             std::to_string(long(::getpid())));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::string str() const { return path_.string(); }
  // The names of the folder's entries, sorted.
  std::vector<std::string> entries() const {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(path_))
      out.push_back(e.path().filename().string());
    std::sort(out.begin(), out.end());
    return out;
  }

 private:
  std::filesystem::path path_;
};

inline std::string modelPath(const std::string& name) {
  return std::string(STRATA_MODELS_DIR) + "/" + name;
}

// A file of Debian's assimp-testmodels (the malformed and odd models).
inline std::string assimpPath(const std::string& rel) {
  return std::string(STRATA_ASSIMP_MODELS_DIR) + "/" + rel;
}

// A fresh folder under the test output folder's `group`, named after the running test (kept
// afterwards, unlike ScratchDir, so a failure's files can be looked at).
inline std::filesystem::path freshTestDir(const std::string& group) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::filesystem::path dir = std::filesystem::path(STRATA_TEST_OUTPUT_DIR) / group /
                                    (std::string(info->test_suite_name()) + "_" + info->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// The message of the strata::Error that `load()` throws, or "" when it throws none.
template <class Load>
std::string errorOf(Load load) {
  try {
    load();
    return "";
  } catch (const Error& e) {
    return e.what();
  }
}

// That `action()` throws a strata::Error whose message contains `fragment`.
template <class Action>
void expectErrorContaining(Action action, const std::string& fragment) {
  const std::string message = errorOf(action);
  EXPECT_NE(message.find(fragment), std::string::npos) << (message.empty() ? "no error" : message);
}

// A scene (loadScene: a file or builtin:NAME) with its world geometry:
// `const auto [scene, g] = test::sceneAndGeometry(spec);`.
struct SceneAndGeometry {
  Scene scene;
  WorldGeometry g;
};
inline SceneAndGeometry sceneAndGeometry(const std::string& spec) {
  SceneAndGeometry r{loadScene(spec), {}};
  r.g = WorldGeometry::fromScene(r.scene);
  return r;
}

// A scene of the image tests and its label.
struct SceneCase {
  std::string scene;
  std::string label;
};
inline void PrintTo(const SceneCase& c, std::ostream* os) { *os << c.label; }

// Every shared model (open, closed, with through holes), the depth test scenes (stacked spheres
// at the given depths) and the demo.
inline std::vector<SceneCase> sharedSceneCases(const std::vector<int>& sphere_depths) {
  std::vector<SceneCase> c = {{modelPath("teapot.obj"), "teapot"},
                              {modelPath("stanford-bunny.obj"), "bunny"},
                              {modelPath("horse.ply"), "horse"},
                              {modelPath("fandisk.obj"), "fandisk"},
                              {modelPath("spot.obj"), "spot"},
                              {modelPath("rocker-arm.obj"), "rocker-arm"},
                              {modelPath("cheburashka.obj"), "cheburashka"},
                              {modelPath("homer.obj"), "homer"},
                              {modelPath("cow.obj"), "cow"}};
  for (int d : sphere_depths)
    c.push_back({"builtin:spheres:" + std::to_string(d), "spheres" + std::to_string(d)});
  c.push_back({"builtin:demo", "demo"});
  return c;
}

// A parameterised image test on the scene its case names (Param::scene): the scene, its world
// geometry and the Embree transparency reference every method is compared with.
template <class Param>
class SceneImageTest : public ::testing::TestWithParam<Param> {
 protected:
  void SetUp() override {
    scene = loadScene(this->GetParam().scene);
    g = WorldGeometry::fromScene(scene);
  }
  Scene scene;
  WorldGeometry g;
  std::unique_ptr<MethodRenderer> embree = makeEmbreeRenderer(EmbreeMode::Transparency);
};

inline FrameSettings settingsFor(const Scene& scene, int size, float az, float el) {
  FrameSettings s;
  s.width = s.height = size;
  OrbitView v = scene.default_view.value_or(OrbitView{});
  v.azimuth_deg = az;
  v.elevation_deg = el;
  s.camera = Camera::orbit(scene.boundingSphere(), v);
  return s;
}

// A plain orbit camera (not the scene's own view) `distance_radii` bounding-sphere radii from
// the centre.
inline Camera orbitCamera(const Scene& scene, float az, float el, float distance_radii) {
  OrbitView v;
  v.azimuth_deg = az;
  v.elevation_deg = el;
  v.distance_radii = distance_radii;
  return Camera::orbit(scene.boundingSphere(), v);
}

// Floats in [-1, 1) from a linear congruential generator: generated scenes are the same on
// every machine and standard library.
class SignedUniform {
 public:
  explicit SignedUniform(uint32_t seed) : seed_(seed) {}
  float operator()() {
    seed_ = seed_ * 1664525u + 1013904223u;
    return float(seed_ >> 8) / float(1u << 24) * 2.0f - 1.0f;
  }

 private:
  uint32_t seed_;
};

// Checks that at least `min_within_2` of the pixels are within 2/255; on failure writes
// NAME-rendered.png, NAME-reference.png and NAME-diff.png under the test output folder.
inline void expectImagesMatch(const Image& rendered, const Image& reference,
                              const std::string& name, double min_within_2 = 0.995) {
  const ImageDiff d = compareImages(rendered, reference);
  if (d.within_2 < min_within_2) {
    const std::filesystem::path dir = std::filesystem::path(STRATA_TEST_OUTPUT_DIR) / "images";
    std::filesystem::create_directories(dir);
    writeImage(rendered, (dir / (name + "-rendered.png")).string());
    writeImage(reference, (dir / (name + "-reference.png")).string());
    writeImage(differenceImage(rendered, reference), (dir / (name + "-diff.png")).string());
    ADD_FAILURE() << name << ": only " << 100.0 * d.within_2 << "% of pixels within 2/255 (need "
                  << 100.0 * min_within_2 << "%), max error " << d.max_abs << ", PSNR " << d.psnr
                  << " dB; images written to " << dir.string();
  }
}

// expectImagesMatch against the Embree transparency reference of the same frame.
inline void expectMatchesEmbree(const Image& rendered, const WorldGeometry& g,
                                const FrameSettings& s, const std::string& name) {
  expectImagesMatch(rendered, makeEmbreeRenderer(EmbreeMode::Transparency)->render(g, s).image,
                    name);
}

// A file's bytes, and writing bytes to a file (malformed copies of inputs).
inline std::string readBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

inline void writeBytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out << bytes;
}

// Checks a loader's failure: `message` (empty when `path` loaded) is one line, starts with the
// path and holds `fragment`.
inline void expectLoadError(const std::string& path, const std::string& message,
                            const std::string& fragment) {
  ASSERT_FALSE(message.empty()) << path << " loaded but should have failed";
  EXPECT_EQ(message.rfind(path + ": ", 0), 0u)
      << "message does not start with the path: " << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << "message is not one line: " << message;
  EXPECT_NE(message.find(fragment), std::string::npos)
      << "expected '" << fragment << "' in: " << message;
}

// Looks down -z from z = eye_z at a 2 x 2 world-unit orthographic view on a solid background: pixel
// centre (x, y) is world ((x + 0.5) * 2 / size - 1, 1 - (y + 0.5) * 2 / size).
inline FrameSettings orthoTopDown(int size, glm::vec3 background = {0.1f, 0.2f, 0.3f},
                                  float eye_z = 5.0f) {
  FrameSettings s;
  s.width = s.height = size;
  s.camera = Camera::lookAt({0.0f, 0.0f, eye_z}, {0.0f, 0.0f, 0.0f});
  s.camera.projection = Projection::Orthographic;
  s.camera.ortho_height = 2.0f;
  s.camera.near_distance = 0.1f;
  s.background.checker = false;
  s.background.color = background;
  return s;
}

}  // namespace strata::test
