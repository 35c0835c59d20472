// Geometry that the cell decomposition (convex_cells.cpp), its separable pairs (cell_pairs.cpp)
// and the mesh connectivity share: the tolerance, welded corners, the overlap of coplanar
// triangles and the convexity of a whole mesh. Internal to preprocess/.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/mesh_view.h"

namespace strata::cells_detail {

// 1e-6 of the diagonal of the bounding box of the mesh's finite positions (0 for no positions),
// plus the rounding of float coordinates far from the origin; `center` (optional) receives the
// box's centre, on which the decomposition's double-precision arithmetic is centred.
double cellTolerance(const MeshView& mesh, glm::dvec3* center);

// weld[v] = the first vertex with exactly v's position (+0 and -0 equal); non-finite vertices
// weld only to themselves.
void weldVertices(const MeshView& mesh, std::vector<uint32_t>* weld);

// Whether two triangles lying (within tol) in the plane with unit normal n overlap by more than
// tol, judged in the projection along n.
bool coplanarTrianglesOverlap(const glm::dvec3 t1[3], const glm::dvec3 t2[3], const glm::dvec3& n,
                              double tol);

// Whether the whole mesh lies on the boundary of one convex body (the strict test over all of
// it), in O(vertices x faces) with an early exit.
bool wholeMeshIsConvex(const MeshView& mesh);

}  // namespace strata::cells_detail
