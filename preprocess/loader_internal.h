// Pieces shared by the mesh loaders: mesh_loader.cpp (dispatch, polygon triangulation and
// soups, text scanning), obj_reader.cpp (OBJ + MTL), off_reader.cpp, stl_reader.cpp,
// ply_reader.cpp (PLY), gltf_loader.cpp (glTF 2.0),
// gltf1_loader.cpp (glTF 1.0) and gltf_common.cpp (what the two glTF readers share).
// Not part of the public interface.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <glm/glm.hpp>

#include "preprocess/scene/scene.h"

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

// ---------------------------------------------------------------------------------------------
// The readers of mesh formats (mesh_loader.cpp dispatches by extension).

// OBJ with its MTL material libraries (obj_reader.cpp).
Scene loadObj(const std::string& path);
// Geomview OFF (off_reader.cpp).
Scene loadOff(const std::string& path);
// STL, ascii or binary (stl_reader.cpp); file_size decides which.
Scene loadStl(const std::string& path, uintmax_t file_size);

// ---------------------------------------------------------------------------------------------
// What the OBJ, OFF and STL readers share (mesh_loader.cpp).

// Faces as read, corner indices as the file gave them (0-based, possibly out of range or
// negative), and optional texture coordinates per corner (OBJ) or per vertex (OFF).
struct PolygonSoup {
  std::vector<glm::vec3> positions;
  std::vector<glm::vec2> vertex_texcoords;  // empty, or sized with positions
  std::vector<int64_t> corners;             // all faces' corners, flattened
  std::vector<size_t> face_begin{0};        // face f spans corners[face_begin[f], face_begin[f+1])
  std::vector<glm::vec2> corner_texcoords;  // empty, or parallel to corners
  std::vector<bool> face_has_texcoords;
  std::vector<uint32_t> face_group;  // empty, or every face's material group (OBJ usemtl)

  size_t faceCount() const { return face_begin.size() - 1; }

  void addFace(const int64_t* first, size_t n) {
    corners.insert(corners.end(), first, first + n);
    face_begin.push_back(corners.size());
    face_has_texcoords.push_back(false);
    if (!corner_texcoords.empty()) corner_texcoords.resize(corners.size());
  }
};

// Triangulates the soup into the scene's meshes and validates them. With at most one material
// (every format but OBJ, and OBJ files without usemtl or with one material) the scene is one mesh
// drawn once, as singleMeshScene makes it. With several (OBJ's usemtl), face group g becomes a
// mesh of material g holding only the vertices its triangles use (texture coordinates only when
// one of its faces had them), each mesh drawn by one instance of the same object (object id 0,
// named after the file), so every mesh keeps one material.
Scene sceneFromSoup(const std::string& path, PolygonSoup& soup, LoadReport report,
                    std::vector<Material> materials = {});

// The whole file as bytes; Error naming the file when it cannot be opened.
std::string readWholeFile(const std::string& path);
// `s` without leading and trailing white space.
std::string_view trimmed(std::string_view s);
// The line of `text` starting at `pos` (without its '\n'); moves `pos` past it.
std::string_view nextLine(const std::string& text, size_t& pos);
// Splits off the next whitespace-separated word of `rest`.
std::string_view nextWord(std::string_view& rest);
// A whole word as a float (parseNumber, then toFloat) or as a 64-bit integer (a leading '+'
// allowed); false when it is not one.
bool parseFloat(std::string_view word, float& value);
bool parseInteger(std::string_view word, int64_t& value);

// PLY, ascii or binary, with `face` polygons and/or `tristrips` triangle strips (strips are
// separated by -1 and alternate their winding).
Scene loadPly(const std::string& path);

// glTF 2.0 (.gltf with external or embedded buffers) and GLB.
Scene loadGltf(const std::string& path, bool binary);

// ---------------------------------------------------------------------------------------------
// Shared by the glTF 2.0 (gltf_loader.cpp) and 1.0 (gltf1_loader.cpp) readers; defined in
// gltf_common.cpp.

// GL enums used by glTF. The numbers are the same in glTF 1.0 and 2.0 (tinygltf's
// TINYGLTF_COMPONENT_TYPE_* and TINYGLTF_MODE_* are these values), so one implementation of what
// depends on them serves both readers.
namespace gl {
constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123,
              kUnsignedInt = 5125, kFloat = 5126;
constexpr int kTriangles = 4, kTriangleStrip = 5, kTriangleFan = 6;
}  // namespace gl

// A problem with a glTF file's structure, thrown from deep inside a reader and turned into
// Error("<file>: <message>") by the reader's entry point (loadGltf, loadGltf1).
struct FormatProblem {
  std::string message;
};
[[noreturn]] inline void problem(const std::string& message) { throw FormatProblem{message}; }

// Bytes per component of an accessor component type; 0 for an unknown type.
size_t gltfComponentSize(int component_type);

// One accessor component at `p` as a double. `normalized` maps unsigned integers to [0, 1] and
// signed ones to [-1, 1] (the most negative value clamped to -1, as the glTF spec says).
double readGltfComponent(const unsigned char* p, int component_type, bool normalized);

// True when `count` elements of `element` bytes, `stride` apart and starting at byte `offset`,
// lie inside a window of `size` bytes; written so that hostile counts and offsets cannot
// overflow. No elements always fit.
bool elementsFit(uint64_t offset, uint64_t count, size_t element, size_t stride, size_t size);
// "<count> elements of <element> bytes (stride <stride>) at offset <offset>", for the message
// of an accessor that does not fit.
std::string describeElements(uint64_t count, size_t element, size_t stride, uint64_t offset);

// A triangle primitive's accessors, read as rows of doubles.
struct PrimitiveRows {
  std::vector<double> positions;                 // POSITION, 3 per vertex
  std::optional<std::vector<double>> texcoords;  // TEXCOORD_0, 2 per vertex
  std::optional<std::vector<double>> indices;    // absent: the vertices in order
};
// Fills `mesh`'s positions, texture coordinates and triangles from `rows` for a TRIANGLES,
// TRIANGLE_STRIP or TRIANGLE_FAN primitive (`mode`). Texture coordinates whose count differs
// from the positions' are ignored, and trailing indices of a TRIANGLES list that form no
// triangle are dropped, each with a warning "<what>: ..." passed to `warn`.
void buildTriangleMesh(int mode, const PrimitiveRows& rows, const std::string& what,
                       const std::function<void(const std::string&)>& warn, Mesh& mesh);

// A node's local transform `m` as it is; problem("<what>: transform is not finite") when a value
// of it is not finite.
glm::dmat4 finiteTransform(const glm::dmat4& m, const std::string& what);

// A node's world transform in float, or false when a value leaves float's range.
bool toFloatTransform(const glm::dmat4& world, glm::mat4& out);

// One instance of each of `meshes` (the strata meshes of one glTF mesh, one per primitive),
// all drawn with a node's world transform and sharing its object id and name.
void addNodeInstances(Scene& scene, const std::vector<uint32_t>& meshes, const glm::mat4& transform,
                      uint32_t object_id, const std::string& name);

// Validation may remove instances whose meshes lost every triangle; renumbers the object ids
// that remain densely (0, 1, 2, ... in order of first appearance).
void compactObjectIds(Scene& scene);

// The folder an asset's URIs are confined to: `folder` (absolute, lexically normal) with its
// symbolic links resolved, or `folder` itself when that fails (never an empty path, which would
// contain everything).
std::filesystem::path confinementFolder(const std::filesystem::path& folder);

// The value of a hexadecimal digit, or -1.
int hexValue(char c);

// A URI's %XX escapes decoded (RFC 3986); a '%' not followed by two hex digits stays as it is,
// and '+' is a plus sign (not a space: that is HTML form encoding).
std::string percentDecode(std::string_view uri);

// Whether `uri` is a data: URI, and its bytes ("data:[<mediatype>][;base64],<data>"; base64
// standard or URL-safe with padding optional, otherwise percent-encoded). A malformed one is a
// FormatProblem naming `what`.
bool isDataUri(const std::string& uri);
std::vector<unsigned char> decodeDataUri(const std::string& uri, const std::string& what);

// Why a glTF reader may not read the file `opened` that a URI names, or "" when it may. `uri` is
// the URI for messages (as written in the file when the reader has it), `decoded` the same with
// its %-escapes decoded, and `opened` the path that will actually be opened (the check must be
// on that very path: decoding again, or normalising differently, could check one file and read
// another). Refused, in this order: `uri` absolute (isAbsoluteReference), a NUL in `decoded` (a
// C path would end there), `decoded` absolute ("%2Fetc"), `opened` outside `canonical_folder`
// once its symbolic links are resolved (fs::weakly_canonical) or when that cannot be decided.
// The message names `uri`, a NUL byte in it written as %00.
std::string uriRefusal(const std::string& uri, const std::string& decoded,
                       const std::filesystem::path& opened,
                       const std::filesystem::path& canonical_folder);

}  // namespace strata::loader
