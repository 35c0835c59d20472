// Mesh and scene file loading: OBJ, PLY (ascii/binary, faces or triangle strips), OFF and STL
// through OpenMesh; glTF 2.0 / GLB through tinygltf. Polygons are triangulated; invalid
// triangles are dropped and counted in Scene::report, or the file is rejected with an Error whose
// message names the file and the problem.
#pragma once

#include <string>

#include "engine/scene.h"

namespace strata {

Scene loadSceneFile(const std::string& path);

}  // namespace strata
