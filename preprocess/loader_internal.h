// Pieces shared by the mesh loaders: mesh_loader.cpp (dispatch, OBJ + MTL/OFF/STL, polygon
// triangulation, path confinement), ply_reader.cpp (PLY) and gltf_loader.cpp (glTF).
// Not part of the public interface.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "engine/scene.h"

namespace strata::loader {

// double -> float without undefined behaviour: values beyond float's range become infinities
// (which validation then counts) instead of whatever the conversion happens to produce.
inline float toFloat(double v) {
  if (v > 3.4028234663852886e38) return std::numeric_limits<float>::infinity();
  if (v < -3.4028234663852886e38) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);  // NaN stays NaN
}

// Parses a whole word as a decimal number, independent of the C locale (strtod would stop at
// the '.' of "1.5" under a locale with a decimal comma). Accepts a leading '+', "nan" and "inf";
// magnitudes beyond double's range become infinity or zero. False when the word is not a number.
bool parseNumber(std::string_view word, double& value);

// Throws Error("<path>: <problem>"), flattening `problem` to one line.
[[noreturn]] void fail(const std::string& path, const std::string& problem);

// The first line of a multi-line library message, trimmed; "unknown error" when empty.
std::string firstLine(const std::string& text);

// "model" for "/some/dir/model.obj".
std::string fileStem(const std::string& path);

// Files a model names (glTF URIs, OBJ material libraries and texture maps) must come from the
// model's own folder. A reference with a scheme ("http:", "file:"), a drive letter or a leading
// slash or backslash is absolute, whatever the folder: RFC 3986 forbids a colon in a relative
// reference's first segment, so a colon there means a scheme (or a drive letter).
bool isAbsoluteReference(const std::string& uri);
// True when `target` lies inside `folder` (both normalised, e.g. by fs::weakly_canonical).
bool isInsideFolder(const std::filesystem::path& folder, const std::filesystem::path& target);

// Appends the triangles of one polygon (corner indices into `positions`, in the polygon's
// winding) to `out`, keeping that winding. Convex polygons are fanned; non-convex ones are ear
// clipped in the polygon's best-fit plane. Corners that are out of range or non-finite cannot be
// placed, so such polygons are fanned and validation drops the triangles that touch them.
// Returns the number of triangles appended (corners - 2, or 0 for fewer than 3 corners).
size_t triangulatePolygon(const std::vector<glm::vec3>& positions, const uint32_t* corners,
                          size_t count, std::vector<uint32_t>& out);

// A scene holding one mesh drawn once: the shape of every single-mesh format.
Scene singleMeshScene(const std::string& path, Mesh mesh, LoadReport report);

// PLY, ascii or binary, with `face` polygons and/or `tristrips` triangle strips (strips are
// separated by -1 and alternate their winding).
Scene loadPly(const std::string& path);

// glTF 2.0 (.gltf with external or embedded buffers) and GLB.
Scene loadGltf(const std::string& path, bool binary);

}  // namespace strata::loader
