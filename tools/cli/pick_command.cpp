// strata pick: what is under pixels of a view (the front fragment or every layer), and the
// objects a rectangle shows, as text or JSON.
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/features/picking.h"
#include "preprocess/builtin_scenes.h"
#include "preprocess/octree_scene.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace {

struct PickArgs {
  std::string scene;
  std::vector<std::string> at;
  std::string rect;
  std::string size = "512x512";
  std::string view;
  std::string device, atomics;
  float fov = 40.0f;
  float alpha = -1.0f;
  bool alpha_given = false;
  bool ortho = false;
  bool perspective = false;
  bool all_layers = false;
  bool json = false;
};

// The camera `render` uses for the same scene, --view, --ortho/--perspective and --fov.
Camera pickCamera(const Scene& scene, const PickArgs& a) {
  return sceneCamera(scene, a.view, a.ortho, a.perspective, a.fov);
}

nlohmann::json vecJson(const glm::vec3& v) { return nlohmann::json::array({v.x, v.y, v.z}); }

nlohmann::json fragmentJson(const PickFragment& f, bool layer) {
  nlohmann::json j;
  j["object"] = f.object;
  j["name"] = f.name;
  j["triangle"] = f.triangle;
  j["depth"] = f.depth;
  j["position"] = vecJson(f.position);
  j["normal"] = vecJson(f.normal);
  j["facing"] = f.front_facing ? "front" : "back";
  if (layer) {
    j["opacity"] = f.opacity;
    j["transmittance"] = f.transmittance;
  }
  return j;
}

std::string vecText(const glm::vec3& v) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), "(%.4g, %.4g, %.4g)", v.x, v.y, v.z);
  return buf;
}

int runPick(const PickArgs& a) {
  FrameSettings settings;
  parseSize(a.size, settings.width, settings.height);
  if (!(a.fov > 1.0f && a.fov < 179.0f)) throw Error("--fov must be between 1 and 179 degrees");
  if (a.alpha_given && !(a.alpha >= 0.0f && a.alpha <= 1.0f))
    throw Error("--alpha must be in 0..1");
  if (a.at.empty() && a.rect.empty())
    throw Error("pick: nothing to pick: give --at X,Y (one or more) or --rect X0,Y0,X1,Y1");
  std::vector<glm::ivec2> pixels;
  for (const std::string& text : a.at) {
    const std::vector<int> v = parseIntList(text, 2, "--at", "X,Y (whole pixel numbers)");
    if (v[0] < 0 || v[1] < 0 || v[0] >= settings.width || v[1] >= settings.height)
      throw Error("--at " + text + " is outside the " + std::to_string(settings.width) + "x" +
                  std::to_string(settings.height) + " image (x 0.." +
                  std::to_string(settings.width - 1) + ", y 0.." +
                  std::to_string(settings.height - 1) + ")");
    pixels.emplace_back(v[0], v[1]);
  }
  PickRect rect;
  if (!a.rect.empty()) {
    const std::vector<int> v =
        parseIntList(a.rect, 4, "--rect", "X0,Y0,X1,Y1 (whole pixel numbers)");
    rect = {v[0], v[1], v[2], v[3]};
    try {
      validatePickRect(rect, settings.width, settings.height);
    } catch (const Error& e) {
      throw Error(std::string("--rect: ") + e.what());
    }
  }

  const Scene scene = loadScene(a.scene);
  const WorldGeometry geometry =
      inCore(WorldGeometry::fromScene(scene, a.alpha_given ? a.alpha : -1.0f));
  settings.camera = pickCamera(scene, a);
  const ObjectNames names = objectNames(scene);
  IdPicker picker(deviceOptions(a.device, a.atomics));
  picker.update(geometry, settings, a.all_layers);
  const PickResult picked = picker.pick(pixels, &names);
  std::vector<uint32_t> in_rect;
  if (!a.rect.empty()) in_rect = picker.objectsInRect(rect);
  const auto nameOf = [&](uint32_t id) {
    const auto it = names.find(id);
    return it == names.end() ? std::string() : it->second;
  };

  if (a.json) {
    nlohmann::json j;
    j["scene"] = a.scene;
    j["size"] = {settings.width, settings.height};
    j["device"] = picker.device();
    j["picks"] = nlohmann::json::array();
    for (const PickedPixel& p : picked.pixels) {
      nlohmann::json pj;
      pj["pixel"] = {p.pixel.x, p.pixel.y};
      pj["hit"] = p.status == PickStatus::Hit;
      pj["status"] = pickStatusName(p.status);
      if (p.status == PickStatus::Hit) pj["front"] = fragmentJson(p.front, false);
      if (a.all_layers) {
        pj["layers"] = nlohmann::json::array();
        for (const PickFragment& f : p.layers) pj["layers"].push_back(fragmentJson(f, true));
      }
      j["picks"].push_back(pj);
    }
    if (!a.rect.empty()) {
      nlohmann::json rj;
      rj["rect"] = {rect.x0, rect.y0, rect.x1, rect.y1};
      rj["objects"] = nlohmann::json::array();
      for (uint32_t id : in_rect) rj["objects"].push_back({{"object", id}, {"name", nameOf(id)}});
      j["rect"] = rj;
    }
    std::printf("%s\n", j.dump(2).c_str());
    return 0;
  }

  for (const PickedPixel& p : picked.pixels) {
    const std::string at = std::to_string(p.pixel.x) + "," + std::to_string(p.pixel.y);
    if (p.status != PickStatus::Hit) {
      std::printf("%-11s no object (background)\n", at.c_str());
      continue;
    }
    const PickFragment& f = p.front;
    std::printf(
        "%-11s object %u \"%s\"  triangle %u  depth %.6g  position %s  normal %s  %s-facing\n",
        at.c_str(), f.object, f.name.c_str(), f.triangle, f.depth, vecText(f.position).c_str(),
        vecText(f.normal).c_str(), f.front_facing ? "front" : "back");
    if (!a.all_layers) continue;
    std::printf("  %5s %10s %-20s %10s %12s %6s %8s %13s\n", "layer", "object", "name", "triangle",
                "depth", "facing", "opacity", "transmittance");
    for (size_t k = 0; k < p.layers.size(); ++k) {
      const PickFragment& l = p.layers[k];
      std::printf("  %5zu %10u %-20s %10u %12.6g %6s %8.3f %13.6f\n", k, l.object, l.name.c_str(),
                  l.triangle, l.depth, l.front_facing ? "front" : "back", l.opacity,
                  l.transmittance);
    }
  }
  if (!a.rect.empty()) {
    std::printf("rect %d,%d,%d,%d: %zu object%s\n", rect.x0, rect.y0, rect.x1, rect.y1,
                in_rect.size(), in_rect.size() == 1 ? "" : "s");
    for (uint32_t id : in_rect) std::printf("  object %u \"%s\"\n", id, nameOf(id).c_str());
  }
  return 0;
}

}  // namespace

Command addPickCommand(CLI::App& app) {
  auto args = std::make_shared<PickArgs>();
  PickArgs& pk = *args;
  CLI::App* pick = app.add_subcommand(
      "pick",
      "ID picking: the front-most object at pixels (object id and name, triangle, depth, world "
      "position, normal), every fragment under them, or the objects seen in a rectangle");
  pick->add_option("scene", pk.scene, "a mesh file or builtin:NAME")->required();
  pick->add_option("--at", pk.at, "X,Y: a pixel (0,0 is the top-left); repeat for more")
      ->allow_extra_args(false);
  pick->add_option(
      "--rect", pk.rect,
      "X0,Y0,X1,Y1: also list the objects front-most in this rectangle (corners inclusive)");
  pick->add_flag("--all-layers", pk.all_layers,
                 "every fragment under each pixel, nearest first (object, triangle, depth, facing, "
                 "opacity, transmittance in front)");
  pick->add_flag("--json", pk.json, "print JSON");
  pick->add_option("-s,--size", pk.size, "image size WIDTHxHEIGHT (as for render)")
      ->capture_default_str();
  pick->add_option("--view", pk.view, "AZ,EL[,DIST] (as for render)");
  pick->add_option("--fov", pk.fov, "vertical field of view in degrees")->capture_default_str();
  pick->add_option("--alpha", pk.alpha, "opacity of every material, 0..1 (default: per material)");
  pick->add_flag("--ortho", pk.ortho, "orthographic projection");
  pick->add_flag("--perspective", pk.perspective, "perspective projection");
  addDeviceOptions(pick, pk.device, pk.atomics);
  Command c;
  c.app = pick;
  c.run = [args, pick] {
    args->alpha_given = pick->count("--alpha") > 0;
    return runPick(*args);
  };
  c.subject = [args] { return args->scene; };
  return c;
}

}  // namespace strata::cli
