#include "preprocess/mesh_writer.h"

#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "preprocess/core/files.h"
#include "strata/error.h"

namespace strata {

namespace {

namespace fs = std::filesystem;

std::string lowerExtension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

void writePly(std::ofstream& out, const MeshView& mesh) {
  out << "ply\nformat binary_little_endian 1.0\ncomment written by strata\n"
      << "element vertex " << mesh.vertex_count << "\nproperty float x\nproperty float y\n"
      << "property float z\nelement face " << mesh.triangle_count
      << "\nproperty list uchar uint vertex_indices\nend_header\n";
  static_assert(sizeof(glm::vec3) == 12, "positions are three packed floats");
  out.write(reinterpret_cast<const char*>(mesh.positions), std::streamsize(mesh.vertex_count * 12));
  std::vector<char> faces(mesh.triangle_count * 13);
  for (size_t t = 0; t < mesh.triangle_count; ++t) {
    faces[t * 13] = 3;
    std::memcpy(&faces[t * 13 + 1], mesh.indices + t * 3, 12);
  }
  out.write(faces.data(), std::streamsize(faces.size()));
}

void writeObj(std::ofstream& out, const MeshView& mesh) {
  out << "# written by strata: " << mesh.vertex_count << " vertices, " << mesh.triangle_count
      << " triangles\n";
  char line[128];
  for (size_t v = 0; v < mesh.vertex_count; ++v) {
    const glm::vec3& p = mesh.positions[v];
    const int n = std::snprintf(line, sizeof(line), "v %.9g %.9g %.9g\n", p.x, p.y, p.z);
    out.write(line, n);
  }
  for (size_t t = 0; t < mesh.triangle_count; ++t) {
    const uint32_t* i = mesh.indices + t * 3;
    const int n = std::snprintf(line, sizeof(line), "f %u %u %u\n", i[0] + 1, i[1] + 1, i[2] + 1);
    out.write(line, n);
  }
}

}  // namespace

void writeMeshFile(const std::string& path, const MeshView& mesh) {
  const std::string ext = lowerExtension(path);
  if (ext != ".ply" && ext != ".obj")
    throw Error(path + ": can write .ply or .obj meshes, not \"" + ext + "\"");
  for (size_t i = 0; i < mesh.triangle_count * 3; ++i)
    if (mesh.indices[i] >= mesh.vertex_count)
      throw Error(path + ": triangle " + std::to_string(i / 3) + " has a corner past the vertices");
  writeFileAtomically(path, "mesh", [&](const fs::path& temp) {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out) throw Error(path + ": cannot write the mesh (" + std::strerror(errno) + ")");
    if (ext == ".ply")
      writePly(out, mesh);
    else
      writeObj(out, mesh);
    out.close();
    if (!out) throw Error(path + ": writing the mesh failed (disk full?)");
  });
}

}  // namespace strata
