// What several commands of the `strata` program share (tools/cli/cli.h).
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>
#include <optional>
#include <vector>

#include "preprocess/core/numbers.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace fs = std::filesystem;

std::string deviceSpec(const std::string& option) {
  if (!option.empty()) return option;
  const char* env = std::getenv("STRATA_DEVICE");
  return env ? env : "";
}

void addDeviceOptions(CLI::App* command, std::string& device, std::string& atomics) {
  command->add_option("--device", device,
                      "OpenCL device index or name substring (also STRATA_DEVICE; default: a "
                      "GPU, else the first device)");
  command->add_option("--atomics", atomics,
                      "auto: 64-bit atomics where the device has them; 64; or 32: the path "
                      "without 64-bit atomics (serial tile kernels, same images; also "
                      "STRATA_ATOMICS)");
}

DeviceOptions deviceOptions(const std::string& device, const std::string& atomics) {
  DeviceOptions o;
  o.device = deviceSpec(device);
  const char* env = std::getenv("STRATA_ATOMICS");
  o.atomics = !atomics.empty() ? atomics : env && *env ? env : "auto";
  if (o.atomics != "auto" && o.atomics != "64" && o.atomics != "32")
    throw Error(std::string(atomics.empty() ? "STRATA_ATOMICS" : "--atomics") + " '" + o.atomics +
                "': expected auto, 64 or 32");
  return o;
}

std::vector<float> parseFloatList(const std::string& text, const std::string& option) {
  std::vector<float> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const std::optional<double> v = wholeDouble(item);
    if (!v || !std::isfinite(float(*v)))
      throw Error(option + " '" + text + "': '" + item + "' is not a number");
    out.push_back(float(*v));
  }
  return out;
}

void parseSize(const std::string& text, int& w, int& h) {
  const size_t x = text.find_first_of("xX");
  try {
    size_t a = 0, b = 0;
    if (x == std::string::npos) throw std::invalid_argument("");
    const std::string ws = text.substr(0, x), hs = text.substr(x + 1);
    w = std::stoi(ws, &a);
    h = std::stoi(hs, &b);
    if (a != ws.size() || b != hs.size()) throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw Error("--size '" + text + "': expected WIDTHxHEIGHT, e.g. 512x512");
  }
}

Background parseBackground(const std::string& text) {
  Background bg;
  if (text == "checker") return bg;
  bg.checker = false;
  const std::string expected =
      "--background '" + text + "': expected checker, #rrggbb or r,g,b in 0..1";
  if (!text.empty() && text[0] == '#') {
    if (text.size() != 7 || !std::all_of(text.begin() + 1, text.end(), [](char c) {
          return std::isxdigit(static_cast<unsigned char>(c)) != 0;
        }))
      throw Error(expected);
    const unsigned v = unsigned(std::stoul(text.substr(1), nullptr, 16));
    bg.color = glm::vec3((v >> 16) & 255, (v >> 8) & 255, v & 255) / 255.0f;
    return bg;
  }
  const std::vector<float> c = parseFloatList(text, "--background");
  if (c.size() != 3 ||
      !std::all_of(c.begin(), c.end(), [](float v) { return v >= 0.0f && v <= 1.0f; }))
    throw Error(expected);
  bg.color = {c[0], c[1], c[2]};
  return bg;
}

// Fails early, before a long render, if an output file could not be written.
void checkWritable(const std::string& path, const std::string& what) {
  if (path.empty()) return;
  fs::path dir = fs::path(path).parent_path();
  if (dir.empty()) dir = ".";
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw Error(path + ": cannot write " + what + ": folder " + dir.string() + " does not exist");
  if (access(dir.c_str(), W_OK) != 0)
    throw Error(path + ": cannot write " + what + ": folder " + dir.string() + " is not writable");
  if (fs::is_directory(path, ec)) throw Error(path + ": cannot write " + what + ": it is a folder");
}

std::string withSuffix(const std::string& path, const std::string& suffix) {
  const fs::path p(path);
  return (p.parent_path() / (p.stem().string() + "-" + suffix + p.extension().string())).string();
}

// The camera of `render` and `pick`: the scene's own view, or --view AZ,EL[,DIST], framed
// afresh; --ortho / --perspective override the scene's projection.
Camera sceneCamera(const Scene& scene, const std::string& view_text, bool ortho, bool perspective,
                   float fov) {
  OrbitView view = scene.default_view.value_or(OrbitView{});
  if (!view_text.empty()) {
    const std::vector<float> v = parseFloatList(view_text, "--view");
    if (v.size() < 2 || v.size() > 3)
      throw Error("--view '" + view_text + "': expected AZ,EL[,DIST]");
    view.azimuth_deg = v[0];
    view.elevation_deg = v[1];
    view.distance_radii.reset();
    view.ortho_height.reset();  // a chosen view is framed afresh
    if (v.size() == 3) {
      if (v[2] <= 0.0f) throw Error("--view: DIST must be positive (in bounding-sphere radii)");
      view.distance_radii = v[2];
    }
  }
  if (ortho && perspective) throw Error("--ortho and --perspective exclude each other");
  const Projection projection = ortho ? Projection::Orthographic
                                : perspective
                                    ? Projection::Perspective
                                    : scene.default_projection.value_or(Projection::Perspective);
  return Camera::orbit(scene.boundingSphere(), view, projection, fov);
}

std::vector<int> parseIntList(const std::string& text, size_t count, const std::string& option,
                              const std::string& form) {
  std::vector<int> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) {
    const std::optional<long long> v = wholeInteger(item);
    if (!v || *v < -1000000000LL || *v > 1000000000LL)
      throw Error(option + " '" + text + "': expected " + form);
    out.push_back(int(*v));
  }
  if ((count ? out.size() != count : out.empty()) || (!text.empty() && text.back() == ','))
    throw Error(option + " '" + text + "': expected " + form);
  return out;
}

MeshView worldMesh(const WorldGeometry& g) {
  return {g.positions.data(), g.positions.size(), g.indices.data(), g.triangleCount()};
}

std::function<void(double)> progressBar(const std::string& what) {
  if (!isatty(STDERR_FILENO)) return {};
  return [what, last = -1](double f) mutable {
    const int percent = int(f * 100.0);
    if (percent == last) return;
    last = percent;
    const int width = 30, filled = percent * width / 100;
    std::fprintf(stderr, "\r%s [%s%s] %3d%%", what.c_str(), std::string(filled, '#').c_str(),
                 std::string(width - filled, '.').c_str(), percent);
    if (percent >= 100) std::fprintf(stderr, "\r%*s\r", int(what.size()) + 40, "");
    std::fflush(stderr);
  };
}

}  // namespace strata::cli
