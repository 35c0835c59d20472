// Export of convex cells as a coloured PLY through OpenMesh (preprocess/cell_export.h).
#include "preprocess/cell_export.h"

#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

// MeshIO before the mesh types, as OpenMesh requires. OpenMesh's properties append
// default-constructed (uninitialised) vectors, which GCC 12 warns about inside its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include "preprocess/core/files.h"
#include "preprocess/openmesh_quiet.h"
#pragma GCC diagnostic pop

#include "strata/error.h"

namespace strata {

namespace {

using ExportMesh = OpenMesh::TriMesh_ArrayKernelT<>;  // Vec3f points, Vec3uc colours

// Colours are the base-192 digits of (c + 1) * A mod 192^3, A odd, not a multiple of 3 and near
// 192^3 / golden ratio: a bijection on 0 .. 192^3 - 1 that sends consecutive cells far apart.
constexpr uint64_t kColorLevels = 192, kColorCount = kColorLevels * kColorLevels * kColorLevels;
constexpr uint64_t kColorStep = 4374371;
static_assert(kColorStep % 2 == 1 && kColorStep % 3 != 0, "the step must be coprime with 192^3");

}  // namespace

glm::u8vec3 cellColor(uint32_t c) {
  const uint64_t v = ((uint64_t(c) + 1) % kColorCount) * kColorStep % kColorCount;
  return {uint8_t(64 + v % kColorLevels), uint8_t(64 + v / kColorLevels % kColorLevels),
          uint8_t(64 + v / (kColorLevels * kColorLevels))};
}

void checkCellExportPath(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  if (ext != ".ply") throw Error(path + ": the cell export is written as PLY: name the file *.ply");
}

void exportCellsPly(const std::string& path, const MeshView& mesh, const uint32_t* cell_first,
                    size_t cell_count, const uint32_t* cell_triangles) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  checkCellExportPath(path);
  if (cell_count > 0 && !cell_first) throw Error(path + ": cell export: no cell offsets");
  const size_t listed = cell_count > 0 ? cell_first[cell_count] : 0;
  for (size_t c = 0; c < cell_count; ++c)
    if (cell_first[c] > cell_first[c + 1])
      throw Error(path + ": cell export: cell offsets decrease at cell " + std::to_string(c));
  for (size_t i = 0; i < listed; ++i)
    if (cell_triangles[i] >= mesh.triangle_count)
      throw Error(path + ": cell export: triangle " + std::to_string(cell_triangles[i]) +
                  " past the mesh's " + std::to_string(mesh.triangle_count));
  for (size_t i = 0; i < 3 * mesh.triangle_count; ++i)
    if (mesh.indices[i] >= mesh.vertex_count)
      throw Error(path + ": cell export: vertex index " + std::to_string(mesh.indices[i]) +
                  " past the mesh's " + std::to_string(mesh.vertex_count));

  // The mesh: per cell, its own copies of its corners (shared within the cell), coloured.
  ExportMesh out;
  out.request_vertex_colors();
  out.request_face_colors();
  out.reserve(listed, 3 * listed / 2, listed);  // a hint: corners are shared within cells
  std::vector<uint32_t> stamp(mesh.vertex_count, 0);
  std::vector<OpenMesh::VertexHandle> local(mesh.vertex_count);
  {
    const QuietOmerr quiet;  // a refused add_face is handled below, not reported
    for (size_t c = 0; c < cell_count; ++c) {
      const glm::u8vec3 rgb = cellColor(uint32_t(c));
      const ExportMesh::Color color(rgb.r, rgb.g, rgb.b);
      auto fresh = [&](uint32_t v) {
        const glm::vec3& p = mesh.positions[v];
        const OpenMesh::VertexHandle h = out.add_vertex(ExportMesh::Point(p.x, p.y, p.z));
        out.set_color(h, color);
        return h;
      };
      for (uint32_t i = cell_first[c]; i < cell_first[c + 1]; ++i) {
        const uint32_t* idx = &mesh.indices[3 * size_t(cell_triangles[i])];
        OpenMesh::FaceHandle f;
        if (idx[0] != idx[1] && idx[1] != idx[2] && idx[0] != idx[2]) {
          OpenMesh::VertexHandle h[3];
          for (int k = 0; k < 3; ++k) {
            if (stamp[idx[k]] != c + 1) {
              stamp[idx[k]] = uint32_t(c + 1);
              local[idx[k]] = fresh(idx[k]);
            }
            h[k] = local[idx[k]];
          }
          f = out.add_face(h[0], h[1], h[2]);
        }
        // Not representable with shared corners: an isolated copy is always accepted.
        if (!f.is_valid()) f = out.add_face(fresh(idx[0]), fresh(idx[1]), fresh(idx[2]));
        if (!f.is_valid())
          throw Error(path + ": cell export: OpenMesh refused an isolated triangle");
        out.set_color(f, color);
      }
    }
  }

  writeFileAtomically(target, "cell export", [&](const fs::path& tmp) {
    std::ofstream file(tmp, std::ios::binary | std::ios::trunc);
    if (!file) throw Error(path + ": cannot write the cell export (" + std::strerror(errno) + ")");
    const OpenMesh::IO::Options options =
        OpenMesh::IO::Options::Binary | OpenMesh::IO::Options::LSB |
        OpenMesh::IO::Options::VertexColor | OpenMesh::IO::Options::FaceColor;
    bool ok;
    {
      const QuietOmerr quiet;
      ok = OpenMesh::IO::write_mesh(out, file, ".ply", options);
    }
    file.close();
    if (!ok || !file)
      throw Error(path + ": writing the cell export failed" +
                  (ok ? std::string(" (disk full?)")
                      : std::string(" (OpenMesh's PLY writer refused the mesh)")));
  });
}

void exportCellsPly(const std::string& path, const MeshView& mesh, const CellDecomposition& cells) {
  exportCellsPly(path, mesh, cells.cell_begin.data(), cells.cellCount(),
                 cells.triangle_order.data());
}

}  // namespace strata
