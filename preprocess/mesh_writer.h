// Writes triangles as a mesh file other tools read: binary little-endian PLY (.ply) or OBJ
// (.obj), chosen by the extension. Written by hand rather than through OpenMesh, whose writer
// needs a half-edge mesh and so refuses non-manifold soup (faces on an edge shared by three).
#pragma once

#include <string>

#include "preprocess/mesh_view.h"

namespace strata {

// Throws Error naming the file for an unknown extension or a failed write; the file is written
// through a temporary name, so a failure leaves an existing file as it was.
void writeMeshFile(const std::string& path, const MeshView& mesh);

}  // namespace strata
