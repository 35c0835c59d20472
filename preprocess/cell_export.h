// Export of a convex decomposition for viewing (`strata prep SCENE --export FILE.ply`): the cells'
// triangles as a binary PLY mesh, each cell in its own colour, written through OpenMesh's writer
// (preprocess/cell_export.cpp). No OpenMesh in this header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include <glm/glm.hpp>

#include "preprocess/convex_cells.h"  // MeshView

namespace strata {

// The colour of cell c: distinct for the first 7,077,888 cells (every channel in 64..255, so no
// cell is near black), consecutive cells far apart in colour.
glm::u8vec3 cellColor(uint32_t c);

// Writes the triangles of `mesh` grouped into cells (cell c owns the triangles
// cell_triangles[cell_first[c] .. cell_first[c + 1]), indices into the mesh's triangles) to
// `path`, a binary little-endian PLY: faces in cell order, each with its cell's colour as a face
// colour, and every cell its own copy of its corners carrying the same colour as vertex colours
// (so viewers that show only one kind, such as MeshLab, show the cells). Triangles OpenMesh cannot
// hold with shared corners (non-manifold within a cell, repeated corners) get corners of their
// own, so face f of the file is always the f-th triangle listed. The file is written to a
// temporary name in the same folder and renamed into place; failure throws a one-line Error
// naming `path` and leaves neither the temporary file nor a partial `path`.
// The cells are given as plain arrays so scenes of several meshes and instances can be exported
// in world space (tools/strata_main.cpp passes a CellScene over its WorldGeometry).
void exportCellsPly(const std::string& path, const MeshView& mesh, const uint32_t* cell_first,
                    size_t cell_count, const uint32_t* cell_triangles);

// Throws the Error exportCellsPly gives for a file name it does not write (not *.ply), so a
// command can refuse it before the decomposition.
void checkCellExportPath(const std::string& path);

// The same for one mesh's decomposition.
void exportCellsPly(const std::string& path, const MeshView& mesh, const CellDecomposition& cells);

}  // namespace strata
