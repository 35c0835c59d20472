#include "engine/features/batching.h"

#include <algorithm>
#include <map>
#include <tuple>
#include <unordered_map>

namespace strata {

namespace {

struct BatchEntry {
  Batch batch;
  const char* name;
};
const BatchEntry kBatches[] = {
    {Batch::None, "none"},
    {Batch::Static, "static"},
    {Batch::Instanced, "instanced"},
    {Batch::Auto, "auto"},
};

// One (instance, material) pair: a run of equal-material triangles of one part.
struct BaseUnit {
  uint32_t part = 0;
  uint32_t k0 = 0, count = 0;  // triangles [part.first_triangle + k0, + count)
  uint32_t material = 0;       // index into material_colors
};

struct Box {
  glm::vec3 lo{1e30f}, hi{-1e30f};
  void add(const glm::vec3& p) {
    if (!(p.x == p.x && p.y == p.y && p.z == p.z) ||
        glm::any(glm::greaterThan(glm::abs(p), glm::vec3(1e30f))))
      return;  // non-finite or huge vertices do not move a centre
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  void add(const Box& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  glm::vec3 center() const { return lo.x > hi.x ? glm::vec3(0.0f) : (lo + hi) * 0.5f; }
};

StInstance makeInstance(const glm::mat4& m, const glm::vec4& color, uint32_t object_id,
                        uint32_t world_first_triangle) {
  StInstance inst{};
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 3; ++r) inst.m[3 * c + r] = m[c][r];
  for (int i = 0; i < 4; ++i) inst.color[i] = color[i];
  inst.object_id = object_id;
  inst.world_first_triangle = world_first_triangle;
  return inst;
}

// The parts to batch: the geometry's own when they are consistent (in range, every index inside
// its part's vertices), else one part holding everything.
std::vector<GeometryPart> usableParts(const WorldGeometry& geo) {
  const uint32_t T = geo.triangleCount(), V = uint32_t(geo.positions.size());
  GeometryPart whole;
  whole.triangle_count = T;
  whole.vertex_count = V;
  if (geo.parts.empty()) return {whole};
  uint64_t covered = 0;
  for (const GeometryPart& p : geo.parts) {
    if (uint64_t(p.first_triangle) + p.triangle_count > T ||
        uint64_t(p.first_vertex) + p.vertex_count > V)
      return {whole};
    for (size_t i = size_t(p.first_triangle) * 3;
         i < size_t(p.first_triangle + p.triangle_count) * 3; ++i) {
      const uint32_t x = geo.indices[i];
      if (x < V && (x < p.first_vertex || x >= p.first_vertex + p.vertex_count)) return {whole};
    }
    covered += p.triangle_count;
  }
  // Every triangle in exactly one part: parts must not overlap and must cover all triangles.
  std::vector<GeometryPart> sorted = geo.parts;
  std::sort(sorted.begin(), sorted.end(), [](const GeometryPart& a, const GeometryPart& b) {
    return a.first_triangle < b.first_triangle;
  });
  uint32_t next = 0;
  for (const GeometryPart& p : sorted) {
    if (p.first_triangle != next) return {whole};
    next += p.triangle_count;
  }
  if (covered != T) return {whole};
  return geo.parts;
}

// Whether the mesh pool matches every part (same vertex and triangle counts).
bool meshPoolUsable(const WorldGeometry& geo, const std::vector<GeometryPart>& parts) {
  if (geo.mesh_positions.empty() || geo.mesh_first_vertex.size() < 2 || geo.parts.empty() ||
      parts.size() != geo.parts.size())
    return false;
  const size_t meshes = geo.mesh_first_vertex.size() - 1;
  if (geo.mesh_first_triangle.size() != meshes + 1) return false;
  if (geo.mesh_first_vertex.back() != geo.mesh_positions.size() ||
      size_t(geo.mesh_first_triangle.back()) * 3 != geo.mesh_indices.size())
    return false;
  for (const GeometryPart& p : parts) {
    if (p.mesh >= meshes) return false;
    if (geo.mesh_first_vertex[p.mesh + 1] - geo.mesh_first_vertex[p.mesh] != p.vertex_count)
      return false;
    if (geo.mesh_first_triangle[p.mesh + 1] - geo.mesh_first_triangle[p.mesh] != p.triangle_count)
      return false;
  }
  // Mesh-local indices must be those of the flattened triangles (fromScene's invariant).
  for (const GeometryPart& p : parts) {
    const size_t src = size_t(geo.mesh_first_triangle[p.mesh]) * 3,
                 dst = size_t(p.first_triangle) * 3;
    for (size_t i = 0; i < size_t(p.triangle_count) * 3; ++i)
      if (geo.mesh_indices[src + i] + p.first_vertex != geo.indices[dst + i]) return false;
  }
  return true;
}

uint64_t mix64(uint64_t x) {
  x ^= x >> 33;
  x *= 0xff51afd7ed558ccdull;
  x ^= x >> 33;
  x *= 0xc4ceb9fe1a85ec53ull;
  return x ^ (x >> 33);
}

}  // namespace

Batch parseBatch(const std::string& name) {
  for (const BatchEntry& b : kBatches)
    if (name == b.name) return b.batch;
  throw Error("unknown batching '" + name + "' (known: none, static, instanced, auto)");
}

const char* optionName(Batch value) {
  for (const BatchEntry& b : kBatches)
    if (b.batch == value) return b.name;
  return "?";
}

std::string batchName(Batch batch) { return optionName(batch); }

std::vector<std::string> batchNames() {
  std::vector<std::string> out;
  for (const BatchEntry& b : kBatches) out.push_back(b.name);
  return out;
}

uint64_t effectStateBit(Effect effect) {
  return 1ull << (draw_state::kEffectShift + (effect == Effect::Translucency ? 1 : 0));
}

namespace {

// Builds one BatchPlan: the (part, material) base units, then the draws and units of the mode.
class BatchPlanBuilder {
 public:
  BatchPlanBuilder(const WorldGeometry& geo, Effect effect,
                   const std::vector<uint32_t>* texture_binding)
      : geo_(geo),
        T_(geo.triangleCount()),
        V_(uint32_t(geo.positions.size())),
        parts_(usableParts(geo)),
        pool_(meshPoolUsable(geo, parts_)),
        materials_(std::max<size_t>(geo.material_colors.size(), 1)) {
    plan_.triangle_count = T_;
    registerMaterials(effect, texture_binding);
    collectBaseUnits();
  }

  BatchPlan build(Batch mode) {
    // Instances per mesh (auto's choice; only the mesh pool can be instanced).
    if (pool_) {
      std::unordered_map<uint32_t, uint32_t> per_mesh;
      for (const GeometryPart& part : parts_)
        plan_.max_instances = std::max(plan_.max_instances, ++per_mesh[part.mesh]);
    } else {
      plan_.max_instances = 1;
    }
    if (mode == Batch::Auto)
      mode = pool_ && plan_.max_instances >= kAutoInstancingThreshold ? Batch::Instanced
                                                                      : Batch::Static;
    plan_.mode = mode;
    if (mode == Batch::None || mode == Batch::Instanced) {
      setInstanceSource();
      if (mode == Batch::None || !pool_)
        planOneUnitPerBaseUnit();
      else
        planInstanced();
    } else {
      planStatic();
    }
    return std::move(plan_);
  }

 private:
  // Per material: render state (plus the frame's effect) and its registered material id.
  void registerMaterials(Effect effect, const std::vector<uint32_t>* texture_binding) {
    state_.resize(materials_);
    material_id_.resize(materials_);
    for (size_t m = 0; m < materials_; ++m) {
      uint64_t s;
      if (m < geo_.material_state.size()) {
        s = geo_.material_state[m];
      } else {
        const float a =
            m < geo_.material_colors.size() ? geo_.material_colors[m].a : kDefaultOpacity;
        s = draw_state::kTwoSided |
            (a < 1.0f ? draw_state::kAlphaBlend | draw_state::kTransparent : 0);
      }
      state_[m] = s | effectStateBit(effect);
      if (texture_binding && m < texture_binding->size() && (*texture_binding)[m] != ST_NO_TEXTURE)
        state_[m] |= uint64_t((*texture_binding)[m] + 1) << draw_state::kTextureBindingShift;
      // What selects the program is the state; per-material parameters (colour) are left out.
      material_id_[m] = plan_.registry.registerMaterial(mix64(state_[m]));
    }
  }

  // (instance, material) units and the world boxes of the parts.
  void collectBaseUnits() {
    part_box_.resize(parts_.size());
    for (uint32_t p = 0; p < parts_.size(); ++p) {
      const GeometryPart& part = parts_[p];
      for (uint32_t v = 0; v < part.vertex_count; ++v)
        part_box_[p].add(geo_.positions[part.first_vertex + v]);
      for (uint32_t k = 0; k < part.triangle_count;) {
        const uint32_t m = materialOf(part.first_triangle + k);
        uint32_t e = k + 1;
        while (e < part.triangle_count && materialOf(part.first_triangle + e) == m) ++e;
        base_.push_back({p, k, e - k, m});
        k = e;
      }
    }
  }

  uint32_t materialOf(uint32_t t) const {
    const uint32_t m = t < geo_.triangle_material.size() ? geo_.triangle_material[t] : 0;
    return m < materials_ ? m : 0;
  }
  glm::vec4 colorOf(uint32_t m) const {
    return m < geo_.material_colors.size() ? geo_.material_colors[m]
                                           : glm::vec4(0.8f, 0.8f, 0.8f, kDefaultOpacity);
  }
  uint32_t objectOf(uint32_t t) const {
    return t < geo_.triangle_object.size() ? geo_.triangle_object[t] : 0u;
  }
  // Source range of a base unit: the mesh pool (object space) or the part's world triangles.
  uint32_t srcFirstVertex(const BaseUnit& b) const {
    const GeometryPart& part = parts_[b.part];
    return pool_ ? geo_.mesh_first_vertex[part.mesh] : part.first_vertex;
  }
  uint32_t srcFirstTriangle(const BaseUnit& b) const {
    const GeometryPart& part = parts_[b.part];
    return (pool_ ? geo_.mesh_first_triangle[part.mesh] : part.first_triangle) + b.k0;
  }
  StInstance instanceOf(const BaseUnit& b) const {
    const GeometryPart& part = parts_[b.part];
    const uint32_t first = part.first_triangle + b.k0;
    return makeInstance(pool_ ? part.transform : glm::mat4(1.0f), colorOf(b.material),
                        objectOf(first), first);
  }
  DrawUnit makeUnit(uint32_t first_slot, uint32_t count, uint32_t material, const Box& box,
                    uint32_t object_id) const {
    DrawUnit u;
    u.first_triangle = first_slot;
    u.triangle_count = count;
    u.material = material_id_[material];
    u.state = state_[material];
    u.center = box.center();
    u.transparent = (u.state & draw_state::kTransparent) != 0;
    u.object_id = object_id;
    return u;
  }

  // None and instanced read per-draw source ranges and apply instance transforms.
  void setInstanceSource() {
    plan_.apply_instances = pool_;
    plan_.source_mode = ST_SOURCE_INSTANCE;
    if (pool_) {
      plan_.positions = geo_.mesh_positions;
      plan_.indices = geo_.mesh_indices;
      return;
    }
    // World-space source: each part's own triangles with part-local indices.
    plan_.positions_borrowed = true;
    plan_.indices.resize(geo_.indices.size(), 0xFFFFFFFFu);
    for (const GeometryPart& part : parts_)
      for (size_t i = size_t(part.first_triangle) * 3;
           i < size_t(part.first_triangle + part.triangle_count) * 3; ++i)
        plan_.indices[i] = geo_.indices[i] < V_ ? geo_.indices[i] - part.first_vertex : 0xFFFFFFFFu;
  }

  // One unit per base unit, in the flattened layout (instanced without a mesh pool: every part
  // is its own mesh, so this is also what instancing gives, one instance each).
  void planOneUnitPerBaseUnit() {
    plan_.vertex_count = V_;
    for (const BaseUnit& b : base_) {
      const GeometryPart& part = parts_[b.part];
      StDraw d{};
      d.src_first_vertex = srcFirstVertex(b);
      d.src_first_triangle = srcFirstTriangle(b);
      d.dst_first_vertex = part.first_vertex;
      d.dst_first_triangle = part.first_triangle + b.k0;
      d.vertex_count = part.vertex_count;
      d.triangle_count = b.count;
      d.first_instance = uint32_t(plan_.instances.size());
      d.instance_count = 1;
      plan_.instances.push_back(instanceOf(b));
      plan_.draws.push_back(d);
      plan_.units.push_back(makeUnit(d.dst_first_triangle, b.count, b.material, part_box_[b.part],
                                     objectOf(d.dst_first_triangle)));
    }
  }

  // Instanced: base units sharing a source range and state become one unit, their instances
  // consecutive; device ranges follow the units.
  void planInstanced() {
    std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint32_t> group_of;
    std::vector<std::vector<uint32_t>> groups;
    for (uint32_t i = 0; i < base_.size(); ++i) {
      const auto key = std::make_tuple(srcFirstTriangle(base_[i]), base_[i].count,
                                       material_id_[base_[i].material]);
      auto [it, fresh] = group_of.emplace(key, uint32_t(groups.size()));
      if (fresh) groups.emplace_back();
      groups[it->second].push_back(i);
    }
    uint32_t cursor_v = 0, cursor_t = 0;
    for (const std::vector<uint32_t>& g : groups) {
      const BaseUnit& b0 = base_[g.front()];
      const GeometryPart& p0 = parts_[b0.part];
      StDraw d{};
      d.src_first_vertex = srcFirstVertex(b0);
      d.src_first_triangle = srcFirstTriangle(b0);
      d.dst_first_vertex = cursor_v;
      d.dst_first_triangle = cursor_t;
      d.vertex_count = p0.vertex_count;
      d.triangle_count = b0.count;
      d.first_instance = uint32_t(plan_.instances.size());
      d.instance_count = uint32_t(g.size());
      Box box;
      for (uint32_t i : g) {
        plan_.instances.push_back(instanceOf(base_[i]));
        box.add(part_box_[base_[i].part]);
      }
      cursor_v += d.vertex_count * d.instance_count;
      cursor_t += d.triangle_count * d.instance_count;
      plan_.draws.push_back(d);
      plan_.units.push_back(makeUnit(d.dst_first_triangle, d.triangle_count * d.instance_count,
                                     b0.material, box, objectOf(p0.first_triangle + b0.k0)));
    }
    plan_.vertex_count = cursor_v;
  }

  // Static: base units of equal material id merged, in first-appearance order, into one
  // world-space range each (a part's vertices copied once per range).
  void planStatic() {
    std::vector<std::vector<uint32_t>> groups;
    std::unordered_map<uint32_t, uint32_t> group_of;
    for (uint32_t i = 0; i < base_.size(); ++i) {
      auto [it, fresh] = group_of.emplace(material_id_[base_[i].material], uint32_t(groups.size()));
      if (fresh) groups.emplace_back();
      groups[it->second].push_back(i);
    }
    if (staticLayoutIsFlattened(groups.size()))
      planStaticIdentity(!groups.empty());
    else
      planStaticMerged(groups);
  }

  // The merged layout is the flattened one when there is one range holding every part, in
  // order, whole: then the geometry's arrays are used as they are.
  bool staticLayoutIsFlattened(size_t groups) const {
    bool identity = groups <= 1;
    uint32_t next_t = 0, next_v = 0;
    for (const BaseUnit& b : base_) {
      const GeometryPart& part = parts_[b.part];
      if (part.first_triangle + b.k0 != next_t) identity = false;
      if (b.k0 == 0) {
        if (part.first_vertex != next_v) identity = false;
        next_v += part.vertex_count;
      }
      next_t += b.count;
    }
    return identity && next_v == V_;
  }

  void planStaticIdentity(bool any) {
    plan_.positions_borrowed = plan_.indices_borrowed = true;
    plan_.source_mode = ST_SOURCE_IDENTITY;
    plan_.vertex_count = V_;
    if (!any) return;
    StDraw d{};
    d.vertex_count = V_;
    d.triangle_count = T_;
    d.instance_count = 1;
    Box box;
    for (const Box& b : part_box_) box.add(b);
    plan_.draws.push_back(d);
    plan_.units.push_back(makeUnit(0, T_, base_.front().material, box, objectOf(0)));
  }

  void planStaticMerged(const std::vector<std::vector<uint32_t>>& groups) {
    plan_.source_mode = ST_SOURCE_ID_MAP;
    plan_.positions.reserve(V_);
    plan_.indices.reserve(size_t(T_) * 3);
    plan_.triangle_ids.reserve(T_);
    for (const std::vector<uint32_t>& g : groups) {
      StDraw d{};
      d.src_first_vertex = d.dst_first_vertex = uint32_t(plan_.positions.size());
      d.src_first_triangle = d.dst_first_triangle = uint32_t(plan_.triangle_ids.size());
      d.instance_count = 1;
      Box box;
      std::unordered_map<uint32_t, uint32_t> part_offset;  // part -> its vertices in the range
      for (uint32_t i : g) {
        const BaseUnit& b = base_[i];
        const GeometryPart& part = parts_[b.part];
        auto [it, fresh] =
            part_offset.emplace(b.part, uint32_t(plan_.positions.size()) - d.dst_first_vertex);
        if (fresh) {
          plan_.positions.insert(plan_.positions.end(), geo_.positions.begin() + part.first_vertex,
                                 geo_.positions.begin() + part.first_vertex + part.vertex_count);
          box.add(part_box_[b.part]);
        }
        for (uint32_t k = 0; k < b.count; ++k) {
          const uint32_t t = part.first_triangle + b.k0 + k;
          for (int c = 0; c < 3; ++c) {
            const uint32_t x = geo_.indices[size_t(t) * 3 + c];
            plan_.indices.push_back(x < V_ ? x - part.first_vertex + it->second : 0xFFFFFFFFu);
          }
          plan_.triangle_ids.push_back(t);
        }
      }
      d.vertex_count = uint32_t(plan_.positions.size()) - d.dst_first_vertex;
      d.triangle_count = uint32_t(plan_.triangle_ids.size()) - d.dst_first_triangle;
      const BaseUnit& b0 = base_[g.front()];
      plan_.draws.push_back(d);
      plan_.units.push_back(makeUnit(d.dst_first_triangle, d.triangle_count, b0.material, box,
                                     objectOf(parts_[b0.part].first_triangle + b0.k0)));
    }
    plan_.vertex_count = uint32_t(plan_.positions.size());
  }

  const WorldGeometry& geo_;
  const uint32_t T_, V_;
  const std::vector<GeometryPart> parts_;
  const bool pool_;
  const size_t materials_;
  std::vector<uint64_t> state_;
  std::vector<uint32_t> material_id_;
  std::vector<BaseUnit> base_;
  std::vector<Box> part_box_;
  BatchPlan plan_;
};

}  // namespace

BatchPlan buildBatchPlan(const WorldGeometry& geo, Batch mode, Effect effect,
                         const std::vector<uint32_t>* texture_binding) {
  return BatchPlanBuilder(geo, effect, texture_binding).build(mode);
}

void buildDrawTable(const BatchPlan& plan, const std::vector<uint32_t>& order,
                    std::vector<StDraw>& table, std::vector<DrawLaunch>& launches) {
  table.clear();
  launches.clear();
  table.reserve(order.size());
  uint64_t state = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    const uint32_t u = order[i];
    const DrawUnit& unit = plan.units[u];
    if (i == 0 || unit.state != state) {
      DrawLaunch l;
      l.first_draw = uint32_t(table.size());
      launches.push_back(l);
      state = unit.state;
    }
    DrawLaunch& l = launches.back();
    StDraw d = plan.draws[u];
    d.vertex_prefix = l.vertex_total;
    d.triangle_prefix = l.triangle_total;
    l.vertex_total += d.vertex_count * d.instance_count;
    l.triangle_total += d.triangle_count * d.instance_count;
    ++l.draw_count;
    table.push_back(d);
  }
}

}  // namespace strata
