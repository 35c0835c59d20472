// The STL reader, ascii and binary (loadStl).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>
#include <cstdint>
#include <map>
#include "preprocess/loader_internal.h"

namespace strata::loader {

// ---------------------------------------------------------------------------------------------
// STL

// STL stores each facet's three corners by value. Corners with identical coordinates are
// merged into one vertex so the mesh has its connectivity; a corner with a non-finite
// coordinate is never merged, so its facet is dropped and counted by validation rather than
// attached to some other vertex.
class VertexWelder {
 public:
  explicit VertexWelder(std::vector<glm::vec3>& positions) : positions_(positions) {}

  int64_t index(glm::vec3 p) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      positions_.push_back(p);
      return static_cast<int64_t>(positions_.size() - 1);
    }
    Key key;
    for (int c = 0; c < 3; ++c) {
      const float v = p[c] == 0.0f ? 0.0f : p[c];  // -0 and +0 are the same point
      std::memcpy(&key.bits[c], &v, 4);
    }
    auto [it, inserted] = map_.try_emplace(key, static_cast<int64_t>(positions_.size()));
    if (inserted) positions_.push_back(p);
    return it->second;
  }

 private:
  struct Key {
    uint32_t bits[3];
    bool operator==(const Key& o) const {
      return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
    }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const {
      uint64_t h = k.bits[0];
      h = h * 0x9E3779B97F4A7C15ull ^ k.bits[1];
      h = h * 0x9E3779B97F4A7C15ull ^ k.bits[2];
      return std::hash<uint64_t>()(h);
    }
  };
  std::vector<glm::vec3>& positions_;
  std::unordered_map<Key, int64_t, KeyHash> map_;
};

namespace {

uint32_t littleEndian32(const unsigned char* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

float littleEndianFloat(const unsigned char* p) {
  const uint32_t bits = littleEndian32(p);
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

}  // namespace

// Binary STL: an 80-byte header, a facet count, then 50 bytes per facet (normal, three corners,
// attribute word). Ascii STL: "solid", then facets "facet normal .. outer loop vertex x y z (x3)
// endloop endfacet", then "endsolid". A file is binary exactly when its size matches the count
// (ascii files can start with anything, binary headers often with "solid"). OpenMesh's STL reader
// is not used: it merges a NaN corner with whatever vertex the comparison lands on, and skips
// facets with coincident corners without a trace.
Scene loadStl(const std::string& path, uintmax_t file_size) {
  const std::string text = readWholeFile(path);
  const auto* bytes = reinterpret_cast<const unsigned char*>(text.data());
  PolygonSoup soup;
  LoadReport report;
  VertexWelder welder(soup.positions);

  const uint32_t declared = text.size() >= 84 ? littleEndian32(bytes + 80) : 0;
  if (text.size() >= 84 && text.size() == 84 + uint64_t(50) * declared) {
    for (uint32_t f = 0; f < declared; ++f) {
      const unsigned char* facet = bytes + 84 + size_t(50) * f + 12;  // skip the normal
      int64_t corners[3];
      for (int k = 0; k < 3; ++k) {
        const unsigned char* c = facet + 12 * k;
        corners[k] = welder.index(
            glm::vec3(littleEndianFloat(c), littleEndianFloat(c + 4), littleEndianFloat(c + 8)));
      }
      soup.addFace(corners, 3);
    }
    return sceneFromSoup(path, soup, std::move(report));
  }

  std::string_view rest(text);
  if (trimmed(rest.substr(0, std::min<size_t>(rest.size(), 80))).substr(0, 5) != "solid") {
    if (text.size() < 84)
      fail(path, "truncated binary STL: " + std::to_string(file_size) +
                     " bytes, shorter than the 84-byte header");
    fail(path, "truncated or corrupt binary STL: header declares " + std::to_string(declared) +
                   " facets (" + std::to_string(84 + uint64_t(50) * declared) +
                   " bytes), file has " + std::to_string(file_size) + " bytes");
  }

  std::vector<int64_t> loop;
  size_t unterminated = 0, stray = 0, unreadable = 0;
  bool open = false, ended = false;  // open: inside a 'facet' not yet ended
  for (std::string_view word = nextWord(rest); !word.empty(); word = nextWord(rest)) {
    if (word == "facet") {
      if (open) ++unterminated;  // its corners are dropped
      open = true;
      loop.clear();
    } else if (word == "vertex") {
      glm::vec3 p;
      bool readable = true;
      for (int k = 0; k < 3; ++k) readable = parseFloat(nextWord(rest), p[k]) && readable;
      if (!readable) {
        ++unreadable;
        p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
      }
      loop.push_back(welder.index(p));
    } else if (word == "endfacet") {
      // A facet is meant to have three corners; whatever it has is kept as a polygon (fewer
      // than three count as degenerate). Corners after an 'endfacet' without its 'facet' are
      // kept too.
      if (!open) ++stray;
      if (open || !loop.empty()) soup.addFace(loop.data(), loop.size());
      loop.clear();
      open = false;
    } else if (word == "endsolid") {
      ended = true;
    }
  }
  if (open) ++unterminated;
  if (unterminated > 0) {
    report.warnings.push_back(std::to_string(unterminated) +
                              " facets without 'endfacet' (file cut short?) dropped");
    report.dropped_degenerate += unterminated;
  }
  if (stray > 0)
    report.warnings.push_back(std::to_string(stray) + " 'endfacet' without its 'facet'");
  if (!ended) report.warnings.push_back("ascii STL without 'endsolid': the file may be truncated");
  if (unreadable > 0)
    report.warnings.push_back(std::to_string(unreadable) +
                              " vertices without readable coordinates (kept as non-finite)");
  return sceneFromSoup(path, soup, std::move(report));
}

}  // namespace strata::loader
