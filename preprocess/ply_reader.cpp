// PLY reader (ascii, binary_little_endian, binary_big_endian): vertices, `face` polygons and
// `tristrips` triangle strips (the Stanford scanning repository's `element tristrips` /
// `property list int int vertex_indices`, strips separated by -1).
// OpenMesh's PLY reader is not used: it skips `tristrips`, loops forever on a header cut short,
// and trusts list counts, so one corrupt count (`-1` read as 4294967295) makes it read billions
// of indices from a failed stream. Here every count is checked against the bytes left.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "preprocess/loader_internal.h"

namespace strata::loader {

namespace {

enum class Encoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

enum class ScalarType { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

struct Property {
  std::string name;
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;  // lists only
  ScalarType value_type = ScalarType::kFloat32;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> properties;
};

struct Header {
  Encoding encoding = Encoding::kAscii;
  std::vector<Element> elements;
  size_t data_offset = 0;  // first byte after end_header's line
};

bool parseScalarType(const std::string& name, ScalarType& type) {
  static const struct {
    const char* name;
    ScalarType type;
  } kTypes[] = {{"char", ScalarType::kInt8},      {"int8", ScalarType::kInt8},
                {"uchar", ScalarType::kUint8},    {"uint8", ScalarType::kUint8},
                {"short", ScalarType::kInt16},    {"int16", ScalarType::kInt16},
                {"ushort", ScalarType::kUint16},  {"uint16", ScalarType::kUint16},
                {"int", ScalarType::kInt32},      {"int32", ScalarType::kInt32},
                {"uint", ScalarType::kUint32},    {"uint32", ScalarType::kUint32},
                {"float", ScalarType::kFloat32},  {"float32", ScalarType::kFloat32},
                {"double", ScalarType::kFloat64}, {"float64", ScalarType::kFloat64}};
  for (const auto& t : kTypes) {
    if (name == t.name) {
      type = t.type;
      return true;
    }
  }
  return false;
}

size_t scalarSize(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8:
    case ScalarType::kUint8:
      return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16:
      return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32:
      return 4;
    case ScalarType::kFloat64:
      return 8;
  }
  return 1;
}

// Reads the header from the start of `data`; an empty `error` means success.
Header parseHeader(const std::string& data, std::string& error) {
  Header header;
  size_t pos = 0;
  bool saw_format = false;
  bool first = true;
  while (true) {
    const size_t end = data.find('\n', pos);
    if (end == std::string::npos) {
      error = "PLY header has no end_header line";
      return header;
    }
    std::string line = data.substr(pos, end - pos);
    pos = end + 1;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string keyword;
    words >> keyword;
    if (first) {
      if (keyword != "ply") {
        error = "not a PLY file (no 'ply' magic)";
        return header;
      }
      first = false;
      continue;
    }
    if (keyword.empty() || keyword == "comment" || keyword == "obj_info") continue;
    if (keyword == "format") {
      std::string encoding;
      words >> encoding;
      if (encoding == "ascii") {
        header.encoding = Encoding::kAscii;
      } else if (encoding == "binary_little_endian") {
        header.encoding = Encoding::kBinaryLittleEndian;
      } else if (encoding == "binary_big_endian") {
        header.encoding = Encoding::kBinaryBigEndian;
      } else {
        error = "unknown PLY format '" + encoding + "'";
        return header;
      }
      saw_format = true;
    } else if (keyword == "element") {
      Element element;
      long long count = -1;
      if (!(words >> element.name >> count) || count < 0) {
        error = "malformed PLY element line '" + line + "'";
        return header;
      }
      element.count = static_cast<uint64_t>(count);
      header.elements.push_back(element);
    } else if (keyword == "property") {
      if (header.elements.empty()) {
        error = "PLY property before any element";
        return header;
      }
      Property property;
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type, value_type;
        words >> count_type >> value_type >> property.name;
        property.is_list = true;
        if (!parseScalarType(count_type, property.count_type) ||
            !parseScalarType(value_type, property.value_type) || property.name.empty()) {
          error = "malformed PLY list property '" + line + "'";
          return header;
        }
      } else {
        words >> property.name;
        if (!parseScalarType(type, property.value_type) || property.name.empty()) {
          error = "malformed PLY property '" + line + "'";
          return header;
        }
      }
      header.elements.back().properties.push_back(property);
    } else if (keyword == "end_header") {
      if (!saw_format) {
        error = "PLY header has no format line";
        return header;
      }
      header.data_offset = pos;
      return header;
    }
    // Other lines are ignored: some exporters write free text into the header (Blender 2.47's
    // "Created by ..." line in assimp's PLY/Wuson.ply), and other readers accept it too.
  }
}

// Sequential access to the element data in either encoding. Every read is bounds checked; a
// failed read sets `truncated` and yields zero.
class PlyDataReader {
 public:
  PlyDataReader(const std::string& data, size_t offset, Encoding encoding)
      : data_(data), pos_(offset), encoding_(encoding) {}

  bool truncated = false;
  bool malformed = false;  // an ascii token that is not a number

  double readDouble(ScalarType type) {
    if (encoding_ == Encoding::kAscii) return asciiNumber();
    switch (type) {
      case ScalarType::kInt8:
        return static_cast<int8_t>(binary<uint8_t>());
      case ScalarType::kUint8:
        return binary<uint8_t>();
      case ScalarType::kInt16:
        return static_cast<int16_t>(binary<uint16_t>());
      case ScalarType::kUint16:
        return binary<uint16_t>();
      case ScalarType::kInt32:
        return static_cast<int32_t>(binary<uint32_t>());
      case ScalarType::kUint32:
        return binary<uint32_t>();
      case ScalarType::kFloat32: {
        const uint32_t bits = binary<uint32_t>();
        float f;
        std::memcpy(&f, &bits, 4);
        return f;
      }
      case ScalarType::kFloat64: {
        const uint64_t bits = binary<uint64_t>();
        double d;
        std::memcpy(&d, &bits, 8);
        return d;
      }
    }
    return 0.0;
  }

  // Integers (counts, indices) read as doubles are exact up to 2^53, well past any index.
  int64_t readInteger(ScalarType type) {
    const double v = readDouble(type);
    if (!std::isfinite(v) || v != std::floor(v) || std::fabs(v) > 9.0e15) {
      malformed = true;
      return 0;
    }
    return static_cast<int64_t>(v);
  }

  size_t remaining() const { return pos_ < data_.size() ? data_.size() - pos_ : 0; }

 private:
  template <typename T>
  T binary() {
    if (remaining() < sizeof(T)) {
      truncated = true;
      pos_ = data_.size();
      return 0;
    }
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    T value = 0;
    for (size_t i = 0; i < sizeof(T); ++i) {
      const size_t shift = encoding_ == Encoding::kBinaryLittleEndian ? i : sizeof(T) - 1 - i;
      value |= static_cast<T>(static_cast<T>(bytes[i]) << (8 * shift));
    }
    return value;
  }

  double asciiNumber() {
    while (pos_ < data_.size() && std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
    if (pos_ >= data_.size()) {
      truncated = true;
      return 0.0;
    }
    const size_t begin = pos_;
    while (pos_ < data_.size() && !std::isspace(static_cast<unsigned char>(data_[pos_]))) ++pos_;
    double value = 0.0;
    if (!parseNumber(std::string_view(data_).substr(begin, pos_ - begin), value)) malformed = true;
    return value;
  }

  const std::string& data_;
  size_t pos_;
  Encoding encoding_;
};

bool isAnyOf(const std::string& name, std::initializer_list<const char*> names) {
  for (const char* n : names)
    if (name == n) return true;
  return false;
}

// Smallest number of bytes one entry of `element` can take: fixed-size properties in binary
// (lists at least their count), and a digit plus a separator per property in ascii.
uint64_t minimumEntryBytes(const Element& element, Encoding encoding) {
  uint64_t bytes = 0;
  for (const Property& p : element.properties) {
    if (encoding == Encoding::kAscii)
      bytes += 2;
    else
      bytes += p.is_list ? scalarSize(p.count_type) : scalarSize(p.value_type);
  }
  return bytes;
}

uint32_t toVertexIndex(int64_t v) {
  return v < 0 || v >= static_cast<int64_t>(UINT32_MAX) ? UINT32_MAX : static_cast<uint32_t>(v);
}

}  // namespace

Scene loadPly(const std::string& path) {
  std::string data;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, "cannot open file");
    std::ostringstream buffer;
    buffer << in.rdbuf();
    data = buffer.str();
  }
  std::string error;
  const Header header = parseHeader(data, error);
  if (!error.empty()) fail(path, "cannot parse as PLY: " + error);

  PlyDataReader reader(data, header.data_offset, header.encoding);
  Mesh mesh;
  LoadReport report;
  bool has_texcoords = false;
  std::vector<uint32_t> polygon;

  for (const Element& element : header.elements) {
    // A count beyond what the remaining bytes can hold is a corrupt header, not a reason to
    // allocate.
    const uint64_t min_bytes = minimumEntryBytes(element, header.encoding);
    if (min_bytes > 0 && element.count > reader.remaining() / min_bytes) {
      fail(path, "truncated PLY: element '" + element.name + "' declares " +
                     std::to_string(element.count) + " entries, more than the file holds");
    }

    const bool is_vertex = element.name == "vertex";
    // Entries without properties hold no data, so their count is bounded by nothing in the
    // file: walking them would take as long as the header claims. Vertices need a position.
    if (min_bytes == 0) {
      if (is_vertex && element.count > 0) {
        fail(path, "cannot parse as PLY: element 'vertex' declares " +
                       std::to_string(element.count) + " entries but no properties");
      }
      continue;
    }
    const bool is_strips = element.name == "tristrips";
    const bool is_face = element.name == "face";
    if (is_vertex) mesh.positions.reserve(element.count);

    for (uint64_t i = 0; i < element.count; ++i) {
      glm::vec3 position(0.0f);
      glm::vec2 uv(0.0f);
      for (const Property& property : element.properties) {
        if (property.is_list) {
          const int64_t n = reader.readInteger(property.count_type);
          if (n < 0 || static_cast<uint64_t>(n) > reader.remaining()) {
            fail(path, "truncated PLY: list of " + std::to_string(n) + " entries in element '" +
                           element.name + "'");
          }
          const bool indices = isAnyOf(property.name, {"vertex_indices", "vertex_index"});
          polygon.clear();
          for (int64_t k = 0; k < n; ++k) {
            const int64_t value = reader.readInteger(property.value_type);
            if (!indices) continue;
            if (is_strips) {
              if (value == -1) {  // strip separator: restart parity
                polygon.clear();
                continue;
              }
              polygon.push_back(toVertexIndex(value));
              const size_t m = polygon.size();
              if (m >= 3) {
                // Every second triangle of a strip is traversed backwards; swapping its first
                // two corners gives all triangles the strip's orientation.
                const bool odd = (m - 3) % 2 == 1;
                mesh.indices.push_back(polygon[odd ? m - 2 : m - 3]);
                mesh.indices.push_back(polygon[odd ? m - 3 : m - 2]);
                mesh.indices.push_back(polygon[m - 1]);
              }
            } else if (is_face) {
              polygon.push_back(toVertexIndex(value));
            }
          }
          if (is_face && indices) {
            if (polygon.size() < 3) {
              ++report.dropped_degenerate;
            } else {
              if (polygon.size() > 3) ++report.polygons_triangulated;
              triangulatePolygon(mesh.positions, polygon.data(), polygon.size(), mesh.indices);
            }
          }
        } else {
          const double value = reader.readDouble(property.value_type);
          if (!is_vertex) continue;
          const std::string& name = property.name;
          if (name == "x")
            position.x = toFloat(value);
          else if (name == "y")
            position.y = toFloat(value);
          else if (name == "z")
            position.z = toFloat(value);
          else if (isAnyOf(name, {"u", "s", "texture_u", "texture_s"})) {
            uv.x = toFloat(value);
            has_texcoords = true;
          } else if (isAnyOf(name, {"v", "t", "texture_v", "texture_t"})) {
            uv.y = toFloat(value);
            has_texcoords = true;
          }
        }
        if (reader.truncated) {
          fail(path, "truncated PLY: data ends inside element '" + element.name + "' entry " +
                         std::to_string(i) + " of " + std::to_string(element.count));
        }
        if (reader.malformed) {
          fail(path, "cannot parse as PLY: malformed value in element '" + element.name +
                         "' entry " + std::to_string(i));
        }
      }
      if (is_vertex) {
        mesh.positions.push_back(position);
        if (has_texcoords) {
          mesh.texcoords.resize(mesh.positions.size() - 1);
          mesh.texcoords.push_back(uv);
        }
      }
    }
  }
  if (!mesh.texcoords.empty()) mesh.texcoords.resize(mesh.positions.size());
  return singleMeshScene(path, std::move(mesh), std::move(report));
}

}  // namespace strata::loader
