// strata export: a scene's triangles in world space, every instance, as one PLY or OBJ mesh.
#include <cstdio>
#include <memory>
#include <string>
#include <utility>

#include "preprocess/builtin_scenes.h"
#include "preprocess/mesh_writer.h"
#include "preprocess/octree_scene.h"
#include "tools/cli/cli.h"

namespace strata::cli {

namespace {

int runExport(const std::string& scene_spec, const std::string& output) {
  checkWritable(output, "the mesh");
  const Scene scene = loadScene(scene_spec);
  const WorldGeometry geometry = inCore(WorldGeometry::fromScene(scene));
  const MeshView world = worldMesh(geometry);
  writeMeshFile(output, world);
  std::printf("%s: %u triangles, %zu vertices written to %s\n", scene_spec.c_str(),
              geometry.triangleCount(), geometry.positions.size(), output.c_str());
  return 0;
}

}  // namespace

Command addExportCommand(CLI::App& app) {
  auto args = std::make_shared<std::pair<std::string, std::string>>();
  std::string& export_scene = args->first;
  std::string& export_output = args->second;
  CLI::App* export_cmd = app.add_subcommand(
      "export", "write a scene's triangles (every instance, world space) as one .ply or .obj mesh");
  export_cmd->add_option("scene", export_scene, "a mesh file or builtin:NAME")->required();
  export_cmd->add_option("-o,--output", export_output, "the mesh file (.ply: binary; .obj: text)")
      ->required();
  Command c;
  c.app = export_cmd;
  c.run = [args] { return runExport(args->first, args->second); };
  c.subject = [args] { return args->first; };
  return c;
}

}  // namespace strata::cli
