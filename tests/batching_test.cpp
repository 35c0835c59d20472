// Draw units in the OpenCL front end: builtin:crowd:N; the batch plans (none, static,
// instanced, auto) cover every triangle once and keep the world triangle ids; --batch and --sort
// never change the image of any method (crowd and a multi-part glTF); the counters (launches,
// upload bytes, state changes) move the way batching and sorting promise; crowd matches Embree.
#include <algorithm>
#include <filesystem>
#include <numeric>
#include <set>

#include "engine/features/batching.h"
#include "engine/features/draw_sort.h"
#include "test_support.h"

namespace strata {
namespace {

const char* const kClMethods[] = {"opaque", "ppll", "abuffer", "mdts", "mdts32",
                                  "dp",     "ddp",  "bdp",     "bdp2", "cells"};

std::string engineGlb() {
  return std::string(STRATA_ASSIMP_MODELS_DIR) +
         "/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
}

FrameSettings frameFor(const Scene& scene, int size, Batch batch, DrawSort sort) {
  FrameSettings s = test::settingsFor(scene, size, 30.0f, 35.0f);
  s.batch = batch;
  s.sort = sort;
  // Above every depth here (the engine reaches 34): a fixed budget that overflows keeps the
  // fragments that arrive first, which depends on thread timing, not on batching.
  s.k = 64;
  s.cell_cache_dir = std::string(STRATA_TEST_OUTPUT_DIR) + "/cell-cache";
  return s;
}

struct Variant {
  Batch batch;
  DrawSort sort;
};

std::string variantName(const Variant& v) {
  return batchName(v.batch) + "-" + drawSortName(v.sort);
}

// Every variant's image against the first one's, for every OpenCL method.
void expectVariantsAgree(const std::string& spec, const std::string& label, int size,
                         const std::vector<Variant>& variants) {
  const Scene scene = loadScene(spec);
  const WorldGeometry geo = WorldGeometry::fromScene(scene);
  for (const char* name : kClMethods) {
    SCOPED_TRACE(name);
    std::unique_ptr<MethodRenderer> r = makeRenderer(parseMethod(name));
    const RenderResult ref =
        r->render(geo, frameFor(scene, size, variants[0].batch, variants[0].sort));
    for (size_t i = 1; i < variants.size(); ++i) {
      const Variant& v = variants[i];
      const RenderResult res = r->render(geo, frameFor(scene, size, v.batch, v.sort));
      const ImageDiff d = compareImages(res.image, ref.image);
      EXPECT_LE(d.max_abs, 1) << label << " " << name << " " << variantName(v) << " vs "
                              << variantName(variants[0]) << ": " << 100.0 * d.within_1
                              << "% within 1/255";
      if (std::string(name) != "cells") {
        if (v.batch == Batch::Auto)
          EXPECT_TRUE(res.stats.batch == "static" || res.stats.batch == "instanced")
              << res.stats.batch;
        else
          EXPECT_EQ(res.stats.batch, batchName(v.batch));
        EXPECT_EQ(res.stats.sort, drawSortName(v.sort));
        EXPECT_EQ(res.stats.fragments, ref.stats.fragments) << name << " " << variantName(v);
      } else {
        EXPECT_TRUE(res.stats.batch.empty()) << "cells orders by visibility: no draw units";
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// The scene

TEST(BatchingScene, CrowdHasInstancesOfFewMeshes) {
  const Scene s = loadScene("builtin:crowd:500");
  EXPECT_EQ(s.instances.size(), 500u);
  EXPECT_EQ(s.meshes.size(), 32u);  // 4 shapes x 8 materials
  EXPECT_EQ(s.materials.size(), 8u);
  std::set<uint32_t> ids, meshes;
  std::set<std::string> names;
  for (const Instance& inst : s.instances) {
    ids.insert(inst.object_id);
    names.insert(inst.name);
    meshes.insert(inst.mesh);
  }
  EXPECT_EQ(ids.size(), 500u);
  EXPECT_EQ(names.size(), 500u);
  EXPECT_GT(meshes.size(), 24u);
  for (const Material& m : s.materials) {
    EXPECT_LT(m.opacity, 1.0f);  // transparent
    EXPECT_GT(m.opacity, 0.0f);
  }
  // Consecutive instances mostly differ in material (so the input order switches state).
  int switches = 0;
  for (size_t i = 1; i < s.instances.size(); ++i)
    switches +=
        s.meshes[s.instances[i].mesh].material != s.meshes[s.instances[i - 1].mesh].material;
  EXPECT_GT(switches, 400);
  EXPECT_TRUE(s.default_view.has_value());
  EXPECT_EQ(loadScene("builtin:crowd").instances.size(), 1000u);
}

TEST(BatchingScene, CrowdSpecErrors) {
  for (const char* bad : {"builtin:crowd:0", "builtin:crowd:-3", "builtin:crowd:x",
                          "builtin:crowd:12a", "builtin:crowd:100001"}) {
    try {
      loadScene(bad);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
    }
  }
  try {
    loadScene("builtin:nothing");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("builtin:crowd:N"), std::string::npos) << e.what();
  }
}

TEST(BatchingScene, BatchNames) {
  for (const std::string& n : batchNames()) EXPECT_EQ(batchName(parseBatch(n)), n);
  try {
    parseBatch("dynamic");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("dynamic"), std::string::npos);
  }
}

// ---------------------------------------------------------------------------------------------
// Plans (host only)

// Every record slot owned by exactly one unit, and the world ids of the slots a permutation.
void expectPlanCovers(const BatchPlan& plan, const WorldGeometry& geo) {
  const uint32_t T = geo.triangleCount();
  EXPECT_EQ(plan.triangle_count, T);
  std::vector<int> owned(T, 0);
  ASSERT_EQ(plan.units.size(), plan.draws.size());
  for (size_t u = 0; u < plan.units.size(); ++u) {
    const DrawUnit& unit = plan.units[u];
    const StDraw& d = plan.draws[u];
    EXPECT_EQ(unit.first_triangle, d.dst_first_triangle);
    EXPECT_EQ(unit.triangle_count, d.triangle_count * d.instance_count);
    ASSERT_LE(uint64_t(unit.first_triangle) + unit.triangle_count, T);
    for (uint32_t t = 0; t < unit.triangle_count; ++t) ++owned[unit.first_triangle + t];
    EXPECT_LE(uint64_t(d.dst_first_vertex) + uint64_t(d.vertex_count) * d.instance_count,
              plan.vertex_count);
  }
  EXPECT_TRUE(std::all_of(owned.begin(), owned.end(), [](int n) { return n == 1; }));
  // The world id each slot's record will carry.
  std::vector<uint32_t> world(T, 0xFFFFFFFFu);
  for (const StDraw& d : plan.draws)
    for (uint32_t i = 0; i < d.instance_count; ++i)
      for (uint32_t k = 0; k < d.triangle_count; ++k) {
        const uint32_t src = d.src_first_triangle + k;
        uint32_t id = src;
        if (plan.source_mode == ST_SOURCE_ID_MAP) id = plan.triangle_ids[src];
        if (plan.source_mode == ST_SOURCE_INSTANCE)
          id = plan.instances[d.first_instance + i].world_first_triangle + k;
        world[d.dst_first_triangle + i * d.triangle_count + k] = id;
      }
  std::vector<uint32_t> sorted = world;
  std::sort(sorted.begin(), sorted.end());
  std::vector<uint32_t> iota(T);
  std::iota(iota.begin(), iota.end(), 0u);
  EXPECT_EQ(sorted, iota);
  // Each slot's triangle is the world triangle's: same corners after the unit's transform.
  const std::vector<glm::vec3>& src = plan.sourcePositions(geo);
  const std::vector<uint32_t>& idx = plan.sourceIndices(geo);
  size_t checked = 0;
  for (const StDraw& d : plan.draws)
    for (uint32_t i = 0; i < d.instance_count; ++i)
      for (uint32_t k = 0; k < d.triangle_count; k += 7, ++checked) {
        const uint32_t w = world[d.dst_first_triangle + i * d.triangle_count + k];
        for (int c = 0; c < 3; ++c) {
          glm::vec3 p = src[d.src_first_vertex + idx[3 * size_t(d.src_first_triangle + k) + c]];
          if (plan.apply_instances) {
            const StInstance& inst = plan.instances[d.first_instance + i];
            glm::mat4 m(1.0f);
            for (int col = 0; col < 4; ++col)
              for (int row = 0; row < 3; ++row) m[col][row] = inst.m[3 * col + row];
            p = glm::vec3(m * glm::vec4(p, 1.0f));
          }
          ASSERT_EQ(p, geo.positions[geo.indices[3 * size_t(w) + c]])
              << "slot of world triangle " << w;
        }
      }
  EXPECT_GT(checked, 0u);
}

TEST(BatchingPlan, CrowdPlansCoverEveryTriangleOnce) {
  const WorldGeometry geo = WorldGeometry::fromScene(loadScene("builtin:crowd:300"));
  const BatchPlan none = buildBatchPlan(geo, Batch::None);
  const BatchPlan stat = buildBatchPlan(geo, Batch::Static);
  const BatchPlan inst = buildBatchPlan(geo, Batch::Instanced);
  const BatchPlan autop = buildBatchPlan(geo, Batch::Auto);
  EXPECT_EQ(none.units.size(), 300u);
  EXPECT_EQ(none.instances.size(), 300u);
  EXPECT_TRUE(none.apply_instances);
  EXPECT_EQ(stat.units.size(), 8u);  // one per material state
  EXPECT_EQ(stat.source_mode, uint32_t(ST_SOURCE_ID_MAP));
  EXPECT_FALSE(stat.apply_instances);
  EXPECT_LE(inst.units.size(), 32u);  // one per mesh
  EXPECT_EQ(inst.instances.size(), 300u);
  EXPECT_EQ(inst.positions.size(), geo.mesh_positions.size());  // each mesh once
  EXPECT_EQ(autop.mode, Batch::Instanced);
  for (const BatchPlan* p : {&none, &stat, &inst}) {
    SCOPED_TRACE(batchName(p->mode));
    expectPlanCovers(*p, geo);
  }
  // Material ids follow the state, not the colour: 8 states, 8 ids.
  std::set<uint32_t> ids;
  for (const DrawUnit& u : none.units) ids.insert(u.material);
  EXPECT_EQ(ids.size(), 8u);
}

TEST(BatchingPlan, StaticKeepsTheFlattenedLayoutForOneState) {
  const WorldGeometry geo = WorldGeometry::fromScene(loadScene("builtin:demo"));
  const BatchPlan plan = buildBatchPlan(geo, Batch::Static);
  EXPECT_EQ(plan.units.size(), 1u);
  EXPECT_TRUE(plan.positions_borrowed && plan.indices_borrowed);
  EXPECT_EQ(plan.source_mode, uint32_t(ST_SOURCE_IDENTITY));
  EXPECT_EQ(buildBatchPlan(geo, Batch::Auto).mode, Batch::Static);  // one instance per mesh
  expectPlanCovers(plan, geo);
  expectPlanCovers(buildBatchPlan(geo, Batch::None), geo);
  expectPlanCovers(buildBatchPlan(geo, Batch::Instanced), geo);
}

TEST(BatchingPlan, GeometryWithoutMeshesOrParts) {
  // Hand-made geometry: no mesh pool (world space only), then no parts either.
  WorldGeometry geo = WorldGeometry::fromScene(loadScene("builtin:crowd:60"));
  geo.mesh_positions.clear();
  geo.mesh_indices.clear();
  geo.mesh_first_vertex.clear();
  geo.mesh_first_triangle.clear();
  for (Batch b : {Batch::None, Batch::Static, Batch::Instanced, Batch::Auto}) {
    const BatchPlan plan = buildBatchPlan(geo, b);
    EXPECT_FALSE(plan.apply_instances);
    expectPlanCovers(plan, geo);
  }
  geo.parts.clear();
  geo.material_state.clear();
  for (Batch b : {Batch::None, Batch::Static, Batch::Instanced}) {
    const BatchPlan plan = buildBatchPlan(geo, b);
    expectPlanCovers(plan, geo);
  }
}

TEST(BatchingPlan, DrawTableRunsAreTheSortsLaunches) {
  const WorldGeometry geo = WorldGeometry::fromScene(loadScene("builtin:crowd:400"));
  const DrawSortView view{{10.0f, 8.0f, 12.0f}, {-1.0f, -0.6f, -1.0f}};
  for (Batch b : {Batch::None, Batch::Static, Batch::Instanced}) {
    const BatchPlan plan = buildBatchPlan(geo, b);
    for (const std::string& name : drawSortNames()) {
      std::vector<uint32_t> order;
      const DrawSortStats st = sortDrawUnits(plan.units, parseDrawSort(name), view, order);
      std::vector<StDraw> table;
      std::vector<DrawLaunch> launches;
      buildDrawTable(plan, order, table, launches);
      EXPECT_EQ(launches.size(), st.launches) << batchName(b) << " " << name;
      EXPECT_EQ(table.size(), plan.units.size());
      uint64_t triangles = 0;
      for (const DrawLaunch& l : launches) {
        uint32_t v = 0, t = 0;
        for (uint32_t d = l.first_draw; d < l.first_draw + l.draw_count; ++d) {
          EXPECT_EQ(table[d].vertex_prefix, v);
          EXPECT_EQ(table[d].triangle_prefix, t);
          v += table[d].vertex_count * table[d].instance_count;
          t += table[d].triangle_count * table[d].instance_count;
        }
        EXPECT_EQ(l.vertex_total, v);
        EXPECT_EQ(l.triangle_total, t);
        triangles += t;
      }
      EXPECT_EQ(triangles, geo.triangleCount());
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Images: batching and sorting never change them

TEST(BatchingImages, EveryMethodAgreesOnCrowd) {
  expectVariantsAgree("builtin:crowd:1000", "crowd", 128,
                      {{Batch::Static, DrawSort::None},
                       {Batch::None, DrawSort::None},
                       {Batch::Instanced, DrawSort::Gray},
                       {Batch::Static, DrawSort::Depth},
                       {Batch::None, DrawSort::Key},
                       {Batch::Auto, DrawSort::Material}});
}

TEST(BatchingImages, EveryMethodAgreesOnMultiPartGltf) {
  ASSERT_TRUE(std::filesystem::exists(engineGlb())) << engineGlb();
  expectVariantsAgree(engineGlb(), "2CylinderEngine", 128,
                      {{Batch::Static, DrawSort::None},
                       {Batch::None, DrawSort::Depth},
                       {Batch::Instanced, DrawSort::Gray},
                       {Batch::Auto, DrawSort::Key}});
}

TEST(BatchingImages, WorldSpaceOnlyGeometryAgrees) {
  // No mesh pool: none / instanced draw world-space parts without transforms.
  const Scene scene = loadScene("builtin:crowd:120");
  const WorldGeometry full = WorldGeometry::fromScene(scene);
  WorldGeometry bare = full;
  bare.mesh_positions.clear();
  bare.mesh_first_vertex.clear();
  std::unique_ptr<MethodRenderer> r = makeRenderer(Method::Ppll);
  const RenderResult ref = r->render(full, frameFor(scene, 128, Batch::Static, DrawSort::None));
  for (Batch b : {Batch::None, Batch::Instanced, Batch::Static}) {
    const RenderResult res = r->render(bare, frameFor(scene, 128, b, DrawSort::Gray));
    EXPECT_LE(compareImages(res.image, ref.image).max_abs, 1) << batchName(b);
  }
}

TEST(BatchingImages, CrowdMatchesEmbree) {
  const Scene scene = loadScene("builtin:crowd:300");
  const WorldGeometry geo = WorldGeometry::fromScene(scene);
  const FrameSettings base = frameFor(scene, 192, Batch::Static, DrawSort::None);
  const RenderResult reference = makeRenderer(Method::Embree)->render(geo, base);
  std::unique_ptr<MethodRenderer> r = makeRenderer(Method::Ppll);
  for (Batch b : {Batch::None, Batch::Static, Batch::Instanced}) {
    const RenderResult res = r->render(geo, frameFor(scene, 192, b, DrawSort::Gray));
    test::expectImagesMatch(res.image, reference.image, "batching-crowd-" + batchName(b));
  }
}

// ---------------------------------------------------------------------------------------------
// Counters

TEST(BatchingCounters, LaunchesUploadsAndStateChanges) {
  const Scene scene = loadScene("builtin:crowd:400");
  const WorldGeometry geo = WorldGeometry::fromScene(scene);
  std::unique_ptr<MethodRenderer> r = makeRenderer(Method::Ppll);
  auto stats = [&](Batch b, DrawSort s) {
    FrameSettings f = frameFor(scene, 128, b, s);
    f.frames = 2;
    return r->render(geo, f).stats;
  };
  const FrameStats none = stats(Batch::None, DrawSort::None);
  const FrameStats stat = stats(Batch::Static, DrawSort::None);
  const FrameStats inst = stats(Batch::Instanced, DrawSort::None);
  EXPECT_EQ(none.draw_units, 400u);
  EXPECT_EQ(stat.draw_units, 8u);
  EXPECT_LT(stat.launches, none.launches);
  EXPECT_LT(inst.launches, none.launches);
  EXPECT_LT(inst.upload_bytes, none.upload_bytes);
  EXPECT_LT(inst.scene_upload_bytes, stat.scene_upload_bytes);  // meshes once, not flattened
  EXPECT_LE(stat.upload_bytes, inst.upload_bytes);
  EXPECT_GT(none.launches, 300u);  // consecutive instances differ in state
  // Kernel launches: one transform and one setup per run, plus the fixed rest of the frame.
  EXPECT_EQ(none.kernel_launches - stat.kernel_launches, 2 * (none.launches - stat.launches));

  const FrameStats gray = stats(Batch::None, DrawSort::Gray);
  const FrameStats material = stats(Batch::None, DrawSort::Material);
  const FrameStats key = stats(Batch::None, DrawSort::Key);
  const FrameStats depth = stats(Batch::None, DrawSort::Depth);
  EXPECT_LE(gray.state_changes, none.state_changes);
  EXPECT_EQ(gray.launches, 8u);  // one run per state
  EXPECT_EQ(material.launches, 8u);
  EXPECT_EQ(key.launches, 8u);
  EXPECT_GT(depth.launches, gray.launches);
  EXPECT_EQ(gray.state_changes, 7u);  // 8 states on a complete 3-bit Gray sequence
  EXPECT_LE(gray.state_changes, material.state_changes);
  EXPECT_GE(gray.sort_ms, 0.0);
  EXPECT_EQ(gray.batch, "none");
  EXPECT_EQ(gray.sort, "gray");

  // Cells orders by visibility and has no draw units; embree neither.
  FrameSettings f = frameFor(scene, 96, Batch::None, DrawSort::Gray);
  EXPECT_TRUE(makeRenderer(Method::Cells)->render(geo, f).stats.batch.empty());
  EXPECT_TRUE(makeRenderer(Method::Embree)->render(geo, f).stats.batch.empty());
}

}  // namespace
}  // namespace strata
