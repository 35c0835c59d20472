#include "engine/batching.h"

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
    if (!(p.x == p.x && p.y == p.y && p.z == p.z) || glm::any(glm::greaterThan(glm::abs(p), glm::vec3(1e30f))))
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
    for (size_t i = size_t(p.first_triangle) * 3; i < size_t(p.first_triangle + p.triangle_count) * 3; ++i) {
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
    if (geo.mesh_first_vertex[p.mesh + 1] - geo.mesh_first_vertex[p.mesh] != p.vertex_count) return false;
    if (geo.mesh_first_triangle[p.mesh + 1] - geo.mesh_first_triangle[p.mesh] != p.triangle_count)
      return false;
  }
  // Mesh-local indices must be those of the flattened triangles (fromScene's invariant).
  for (const GeometryPart& p : parts) {
    const size_t src = size_t(geo.mesh_first_triangle[p.mesh]) * 3, dst = size_t(p.first_triangle) * 3;
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

std::string batchName(Batch batch) {
  for (const BatchEntry& b : kBatches)
    if (b.batch == batch) return b.name;
  return "?";
}

std::vector<std::string> batchNames() {
  std::vector<std::string> out;
  for (const BatchEntry& b : kBatches) out.push_back(b.name);
  return out;
}

uint64_t effectStateBit(Effect effect) {
  return 1ull << (draw_state::kEffectShift + (effect == Effect::Translucency ? 1 : 0));
}

BatchPlan buildBatchPlan(const WorldGeometry& geo, Batch mode, Effect effect,
                         const std::vector<uint32_t>* texture_binding) {
  BatchPlan plan;
  const uint32_t T = geo.triangleCount(), V = uint32_t(geo.positions.size());
  plan.triangle_count = T;
  const std::vector<GeometryPart> parts = usableParts(geo);
  const bool pool = meshPoolUsable(geo, parts);

  // Per material: render state (plus the frame's effect) and its registered material id.
  const size_t materials = std::max<size_t>(geo.material_colors.size(), 1);
  std::vector<uint64_t> state(materials);
  std::vector<uint32_t> material_id(materials);
  for (size_t m = 0; m < materials; ++m) {
    uint64_t s;
    if (m < geo.material_state.size()) {
      s = geo.material_state[m];
    } else {
      const float a = m < geo.material_colors.size() ? geo.material_colors[m].a : kDefaultOpacity;
      s = draw_state::kTwoSided | (a < 1.0f ? draw_state::kAlphaBlend | draw_state::kTransparent : 0);
    }
    state[m] = s | effectStateBit(effect);
    if (texture_binding && m < texture_binding->size() && (*texture_binding)[m] != ST_NO_TEXTURE)
      state[m] |= uint64_t((*texture_binding)[m] + 1) << draw_state::kTextureBindingShift;
    // What selects the program is the state; per-material parameters (colour) are left out.
    material_id[m] = plan.registry.registerMaterial(mix64(state[m]));
  }
  auto materialOf = [&](uint32_t t) -> uint32_t {
    const uint32_t m = t < geo.triangle_material.size() ? geo.triangle_material[t] : 0;
    return m < materials ? m : 0;
  };
  auto colorOf = [&](uint32_t m) {
    return m < geo.material_colors.size() ? geo.material_colors[m]
                                          : glm::vec4(0.8f, 0.8f, 0.8f, kDefaultOpacity);
  };

  // (instance, material) units and the world boxes of the parts.
  std::vector<BaseUnit> base;
  std::vector<Box> part_box(parts.size());
  for (uint32_t p = 0; p < parts.size(); ++p) {
    const GeometryPart& part = parts[p];
    for (uint32_t v = 0; v < part.vertex_count; ++v) part_box[p].add(geo.positions[part.first_vertex + v]);
    for (uint32_t k = 0; k < part.triangle_count;) {
      const uint32_t m = materialOf(part.first_triangle + k);
      uint32_t e = k + 1;
      while (e < part.triangle_count && materialOf(part.first_triangle + e) == m) ++e;
      base.push_back({p, k, e - k, m});
      k = e;
    }
  }
  // Source range of a base unit: the mesh pool (object space) or the part's world triangles.
  auto srcFirstVertex = [&](const BaseUnit& b) {
    const GeometryPart& part = parts[b.part];
    return pool ? geo.mesh_first_vertex[part.mesh] : part.first_vertex;
  };
  auto srcFirstTriangle = [&](const BaseUnit& b) {
    const GeometryPart& part = parts[b.part];
    return (pool ? geo.mesh_first_triangle[part.mesh] : part.first_triangle) + b.k0;
  };
  auto objectOf = [&](uint32_t t) {
    return t < geo.triangle_object.size() ? geo.triangle_object[t] : 0u;
  };

  // Instances per mesh (auto's choice; only the mesh pool can be instanced).
  if (pool) {
    std::unordered_map<uint32_t, uint32_t> per_mesh;
    for (const GeometryPart& part : parts) plan.max_instances = std::max(plan.max_instances, ++per_mesh[part.mesh]);
  } else {
    plan.max_instances = 1;
  }
  if (mode == Batch::Auto)
    mode = pool && plan.max_instances >= kAutoInstancingThreshold ? Batch::Instanced : Batch::Static;
  plan.mode = mode;

  auto makeUnit = [&](uint32_t first_slot, uint32_t count, uint32_t material, const Box& box,
                      uint32_t object_id) {
    DrawUnit u;
    u.first_triangle = first_slot;
    u.triangle_count = count;
    u.material = material_id[material];
    u.state = state[material];
    u.center = box.center();
    u.transparent = (u.state & draw_state::kTransparent) != 0;
    u.object_id = object_id;
    return u;
  };

  if (mode == Batch::None || mode == Batch::Instanced) {
    plan.apply_instances = pool;
    plan.source_mode = ST_SOURCE_INSTANCE;
    if (pool) {
      plan.positions = geo.mesh_positions;
      plan.indices = geo.mesh_indices;
    } else {
      // World-space source: each part's own triangles with part-local indices.
      plan.positions_borrowed = true;
      plan.indices.resize(geo.indices.size(), 0xFFFFFFFFu);
      for (const GeometryPart& part : parts)
        for (size_t i = size_t(part.first_triangle) * 3; i < size_t(part.first_triangle + part.triangle_count) * 3; ++i)
          plan.indices[i] = geo.indices[i] < V ? geo.indices[i] - part.first_vertex : 0xFFFFFFFFu;
    }
    auto instanceOf = [&](const BaseUnit& b) {
      const GeometryPart& part = parts[b.part];
      const uint32_t first = part.first_triangle + b.k0;
      return makeInstance(pool ? part.transform : glm::mat4(1.0f), colorOf(b.material), objectOf(first), first);
    };
    if (mode == Batch::None || !pool) {
      // One unit per base unit, in the flattened layout (instanced without a mesh pool: every
      // part is its own mesh, so this is also what instancing gives, one instance each).
      plan.vertex_count = V;
      for (uint32_t i = 0; i < base.size(); ++i) {
        const BaseUnit& b = base[i];
        const GeometryPart& part = parts[b.part];
        StDraw d{};
        d.src_first_vertex = srcFirstVertex(b);
        d.src_first_triangle = srcFirstTriangle(b);
        d.dst_first_vertex = part.first_vertex;
        d.dst_first_triangle = part.first_triangle + b.k0;
        d.vertex_count = part.vertex_count;
        d.triangle_count = b.count;
        d.first_instance = uint32_t(plan.instances.size());
        d.instance_count = 1;
        plan.instances.push_back(instanceOf(b));
        plan.draws.push_back(d);
        plan.units.push_back(makeUnit(d.dst_first_triangle, b.count, b.material, part_box[b.part],
                                      objectOf(d.dst_first_triangle)));
      }
    } else {
      // Instanced: base units sharing a source range and state become one unit, their
      // instances consecutive; device ranges follow the units.
      std::map<std::tuple<uint32_t, uint32_t, uint32_t>, uint32_t> group_of;
      std::vector<std::vector<uint32_t>> groups;
      for (uint32_t i = 0; i < base.size(); ++i) {
        const auto key = std::make_tuple(srcFirstTriangle(base[i]), base[i].count, material_id[base[i].material]);
        auto [it, fresh] = group_of.emplace(key, uint32_t(groups.size()));
        if (fresh) groups.emplace_back();
        groups[it->second].push_back(i);
      }
      uint32_t cursor_v = 0, cursor_t = 0;
      for (const std::vector<uint32_t>& g : groups) {
        const BaseUnit& b0 = base[g.front()];
        const GeometryPart& p0 = parts[b0.part];
        StDraw d{};
        d.src_first_vertex = srcFirstVertex(b0);
        d.src_first_triangle = srcFirstTriangle(b0);
        d.dst_first_vertex = cursor_v;
        d.dst_first_triangle = cursor_t;
        d.vertex_count = p0.vertex_count;
        d.triangle_count = b0.count;
        d.first_instance = uint32_t(plan.instances.size());
        d.instance_count = uint32_t(g.size());
        Box box;
        for (uint32_t i : g) {
          plan.instances.push_back(instanceOf(base[i]));
          box.add(part_box[base[i].part]);
        }
        cursor_v += d.vertex_count * d.instance_count;
        cursor_t += d.triangle_count * d.instance_count;
        plan.draws.push_back(d);
        plan.units.push_back(makeUnit(d.dst_first_triangle, d.triangle_count * d.instance_count,
                                      b0.material, box, objectOf(p0.first_triangle + b0.k0)));
      }
      plan.vertex_count = cursor_v;
    }
  } else {
    // Static: base units of equal material id merged, in first-appearance order, into one
    // world-space range each (a part's vertices copied once per range).
    std::vector<std::vector<uint32_t>> groups;
    std::unordered_map<uint32_t, uint32_t> group_of;
    for (uint32_t i = 0; i < base.size(); ++i) {
      auto [it, fresh] = group_of.emplace(material_id[base[i].material], uint32_t(groups.size()));
      if (fresh) groups.emplace_back();
      groups[it->second].push_back(i);
    }
    // The merged layout is the flattened one when there is one range holding every part, in
    // order, whole: then the geometry's arrays are used as they are.
    bool identity = groups.size() <= 1;
    uint32_t next_t = 0, next_v = 0;
    for (const BaseUnit& b : base) {
      const GeometryPart& part = parts[b.part];
      if (part.first_triangle + b.k0 != next_t) identity = false;
      if (b.k0 == 0) {
        if (part.first_vertex != next_v) identity = false;
        next_v += part.vertex_count;
      }
      next_t += b.count;
    }
    if (next_v != V) identity = false;
    if (identity) {
      plan.positions_borrowed = plan.indices_borrowed = true;
      plan.source_mode = ST_SOURCE_IDENTITY;
      plan.vertex_count = V;
      if (!groups.empty()) {
        StDraw d{};
        d.vertex_count = V;
        d.triangle_count = T;
        d.instance_count = 1;
        Box box;
        for (const Box& b : part_box) box.add(b);
        plan.draws.push_back(d);
        plan.units.push_back(makeUnit(0, T, base.front().material, box, objectOf(0)));
      }
    } else {
      plan.source_mode = ST_SOURCE_ID_MAP;
      plan.positions.reserve(V);
      plan.indices.reserve(size_t(T) * 3);
      plan.triangle_ids.reserve(T);
      for (const std::vector<uint32_t>& g : groups) {
        StDraw d{};
        d.src_first_vertex = d.dst_first_vertex = uint32_t(plan.positions.size());
        d.src_first_triangle = d.dst_first_triangle = uint32_t(plan.triangle_ids.size());
        d.instance_count = 1;
        Box box;
        std::unordered_map<uint32_t, uint32_t> part_offset;  // part -> its vertices in the range
        for (uint32_t i : g) {
          const BaseUnit& b = base[i];
          const GeometryPart& part = parts[b.part];
          auto [it, fresh] = part_offset.emplace(b.part, uint32_t(plan.positions.size()) - d.dst_first_vertex);
          if (fresh) {
            plan.positions.insert(plan.positions.end(), geo.positions.begin() + part.first_vertex,
                                  geo.positions.begin() + part.first_vertex + part.vertex_count);
            box.add(part_box[b.part]);
          }
          for (uint32_t k = 0; k < b.count; ++k) {
            const uint32_t t = part.first_triangle + b.k0 + k;
            for (int c = 0; c < 3; ++c) {
              const uint32_t x = geo.indices[size_t(t) * 3 + c];
              plan.indices.push_back(x < V ? x - part.first_vertex + it->second : 0xFFFFFFFFu);
            }
            plan.triangle_ids.push_back(t);
          }
        }
        d.vertex_count = uint32_t(plan.positions.size()) - d.dst_first_vertex;
        d.triangle_count = uint32_t(plan.triangle_ids.size()) - d.dst_first_triangle;
        const BaseUnit& b0 = base[g.front()];
        plan.draws.push_back(d);
        plan.units.push_back(makeUnit(d.dst_first_triangle, d.triangle_count, b0.material, box,
                                      objectOf(parts[b0.part].first_triangle + b0.k0)));
      }
      plan.vertex_count = uint32_t(plan.positions.size());
    }
  }
  return plan;
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
