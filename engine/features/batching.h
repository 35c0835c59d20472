// Draw units of the OpenCL front end: how a flattened scene is grouped into units
// (a range of triangles, a material, render-state bits) and, per frame, drawn in runs.
//
// A draw unit is n instances of a source range of triangles: the source is the meshes once each
// in object space (instances apply their transform in the transform kernel) or world-space
// triangles (static batches). Every unit owns a fixed range of device vertices and triangles,
// and setup writes each record at its world triangle id, so neither the batching nor the order
// units are drawn in changes what the binner and the methods see; only the launches change.
// Each frame the units are sorted (engine/features/draw_sort.h) and every run of consecutive units with
// equal state is one transform and one setup launch over a table of the run's units (StDraw).
//
//   none       one unit per (instance, material), each with its own per-frame constants upload
//              (an StInstance written on its own); device layout = the flattened geometry's
//   static     units of one material (equal state) merged once into one world-space range; a
//              per-triangle id map keeps the world triangle ids (picking, tie-breaks)
//   instanced  one unit per (mesh, material) holding all its instances: the mesh once plus a
//              per-instance buffer (transform, colour, object id) uploaded per frame in one write
//   auto       instanced when some mesh has at least kAutoInstancingThreshold instances, else
//              static
//
// Record sources stay the flattened geometry's triangle ids in every mode, and world positions
// are computed exactly as WorldGeometry::fromScene does, so images do not change.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "engine/features/draw_sort.h"
#include "engine/renderer.h"
#include "kernels/strata_shared.h"
#include "preprocess/scene/world_geometry.h"

namespace strata {

// Instances of one mesh from which `auto` batching picks instancing.
inline constexpr uint32_t kAutoInstancingThreshold = 8;

// Render-state bit of an effect (draw_state::kEffectShift + effect).
uint64_t effectStateBit(Effect effect);

struct BatchPlan {
  Batch mode = Batch::Static;  // resolved: never Auto
  // Source positions are object space and every draw applies its instances' transforms (the
  // transform kernel also writes world positions for setup); false: world space, laid out as
  // the device vertices (setup reads them directly).
  bool apply_instances = false;
  // Source positions / indices are the geometry's own arrays (not copied into this plan).
  bool positions_borrowed = false, indices_borrowed = false;
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;       // local to each draw's source range
  std::vector<uint32_t> triangle_ids;  // ST_SOURCE_ID_MAP: world id per source triangle
  uint32_t source_mode = ST_SOURCE_IDENTITY;
  std::vector<StInstance> instances;  // none, instanced: one per (instance, material)
  std::vector<DrawUnit> units;        // first_triangle, triangle_count: its device triangles
  std::vector<StDraw> draws;          // one per unit (prefixes are set per frame)
  uint32_t vertex_count = 0;          // device vertices (clip and world buffers)
  uint32_t triangle_count = 0;        // device triangles = record slots = the geometry's
  uint32_t max_instances = 0;         // most instances of one mesh (what auto looks at)
  MaterialRegistry registry;          // material id of each distinct state

  const std::vector<glm::vec3>& sourcePositions(const WorldGeometry& g) const {
    return positions_borrowed ? g.positions : positions;
  }
  const std::vector<uint32_t>& sourceIndices(const WorldGeometry& g) const {
    return indices_borrowed ? g.indices : indices;
  }
};

// Groups `geo` into draw units. `effect` adds its state bit to every unit (a frame-wide state:
// the sorts leave it out of the code, as the patent's set-once states). `texture_binding`, when
// given (--atlas off), is the texture each material binds (ST_NO_TEXTURE: none); it becomes
// part of the state, so units of different textures are never drawn in one launch.
BatchPlan buildBatchPlan(const WorldGeometry& geo, Batch mode, Effect effect = Effect::Transparency,
                         const std::vector<uint32_t>* texture_binding = nullptr);

// One front-end launch pair (transform + setup): a run of consecutive units with equal state.
struct DrawLaunch {
  uint32_t first_draw = 0, draw_count = 0;  // in the frame's draw table
  uint32_t vertex_total = 0, triangle_total = 0;
};

// The frame's draw table (the units in `order`, prefixes per run) and its launches.
void buildDrawTable(const BatchPlan& plan, const std::vector<uint32_t>& order,
                    std::vector<StDraw>& table, std::vector<DrawLaunch>& launches);

}  // namespace strata
