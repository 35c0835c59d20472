// ID picking: which object and triangle is seen at a pixel, and every fragment under it. No
// OpenCL types here: this header is public, so a viewer can pick without the command line.
//
// A IdPicker rasterizes an ID buffer of a frame with the OpenCL pipeline (the same front end, fill
// rule and depth as every method): a 64-bit visibility buffer per pixel, (view distance bits << 32)
// | triangle id with atom_min, so the nearest fragment wins, ties going to the lower triangle id;
// ids are 32-bit (no 24-bit limit of a float or colour ID buffer). With all layers it also builds
// the per-pixel linked lists of every fragment. The buffers stay on the device: a query gathers
// just the asked pixels (or marks the objects of a rectangle) in a small kernel and reads back
// only its answer. Object ids and everything else about a triangle come from the WorldGeometry.
//
// Use: update() once per frame (view or geometry change), then any number of pick() and
// objectsInRect() queries on that frame; the geometry passed to update() must outlive them. The
// one-call pick(geometry, settings, ...) does both. A IdPicker is not reentrant (one thread at a
// time); Pickers share the process's OpenCL device context like the renderers.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include <glm/glm.hpp>

#include "engine/renderer.h"

namespace strata {

// Object names by object id: Instance::name, else its mesh's name, else "object ID".
using ObjectNames = std::unordered_map<uint32_t, std::string>;
ObjectNames objectNames(const Scene& scene);

// One fragment under a pixel.
struct PickFragment {
  uint32_t object = 0;         // WorldGeometry::triangle_object (Instance::object_id)
  std::string name;            // from the ObjectNames given, else empty
  uint32_t triangle = 0;       // triangle id in the WorldGeometry
  float depth = 0.0f;          // view distance along the camera's forward axis at the pixel centre
  glm::vec3 position{0.0f};    // world position: the pixel centre's ray at that depth
  glm::vec3 normal{0.0f};      // unit geometric normal of the winding, cross(v1 - v0, v2 - v0)
  bool front_facing = false;   // the normal faces the viewer (the rasterizer's facing)
  float opacity = 0.0f;        // the material's opacity (what transparency composites)
  float transmittance = 1.0f;  // transparency: product of (1 - opacity) of the fragments in front
};

enum class PickStatus { Hit, Background, OutsideImage };
const char* pickStatusName(PickStatus s);  // "hit", "background", "outside image"

struct PickedPixel {
  glm::ivec2 pixel{0};
  PickStatus status = PickStatus::Background;
  PickFragment front;                // the front-most fragment (status Hit)
  std::vector<PickFragment> layers;  // all layers: every fragment, nearest first (front first)
};

struct PickResult {
  std::vector<PickedPixel> pixels;  // one per asked pixel, in the order asked
  bool all_layers = false;
};

// An inclusive pixel rectangle [x0, x1] x [y0, y1].
struct PickRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

// Throws Error (one line) if the rectangle is empty, reversed or not inside a width x height image.
void validatePickRect(const PickRect& r, int width, int height);

class IdPicker {
 public:
  explicit IdPicker(const DeviceOptions& device = {});
  ~IdPicker();
  IdPicker(const IdPicker&) = delete;
  IdPicker& operator=(const IdPicker&) = delete;

  // Rasterizes the ID buffer of one frame (settings.frames and the capture flags are ignored);
  // all_layers also keeps every fragment (per-pixel linked lists). `geometry` must outlive the
  // queries of this frame.
  void update(const WorldGeometry& geometry, const FrameSettings& settings, bool all_layers);

  // Queries on the last update(). Pixels outside the image come back as OutsideImage (no error);
  // layers are filled only if that update kept all layers. `names` may be null.
  PickResult pick(const std::vector<glm::ivec2>& pixels, const ObjectNames* names = nullptr);
  // The distinct objects front-most at some pixel of the rectangle, ascending. Throws Error for
  // a rectangle not inside the image.
  std::vector<uint32_t> objectsInRect(const PickRect& rect);

  // update() then pick().
  PickResult pick(const WorldGeometry& geometry, const FrameSettings& settings,
                  const std::vector<glm::ivec2>& pixels, bool all_layers,
                  const ObjectNames* names = nullptr);

  // The OpenCL device's label.
  std::string device() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace strata
