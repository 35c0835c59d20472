// Mesh and scene file loading: OBJ, PLY (ascii/binary, faces or triangle strips), OFF and STL
// by strata's own validating readers; glTF 2.0 / GLB through tinygltf. Polygons are
// triangulated; invalid triangles are dropped and counted in Scene::report, or the file is
// rejected with an Error whose message names the file and the problem.
//
// Why not OpenMesh's readers (measured with OpenMesh 9): they lose or corrupt geometry without a
// sign on bad input (a `v nan` OBJ line shifts every later vertex; a NaN STL corner is merged into
// a finite vertex; faces with a repeated index vanish) and hang on truncated PLY/OFF headers or
// corrupt list counts. A renderer whose promise is exactness cannot sit on that.
#pragma once

#include <string>

#include "preprocess/scene/scene.h"

namespace strata {

Scene loadSceneFile(const std::string& path);

}  // namespace strata
