// The Geomview OFF reader (loadOff).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "preprocess/loader_internal.h"

namespace strata::loader {

// ---------------------------------------------------------------------------------------------
// OFF

// Geomview OFF, ascii: an optional [ST][C][N][4]OFF keyword, counts "vertices faces [edges]"
// (on the keyword's line or the next), one vertex per line (x y z [w], then optional normal,
// colour and, for ST, the texture coordinate last) and one face per line (corner count, corner
// indices, optional colour). `#` starts a comment. Binary and n-dimensional OFF are refused.
//
// OpenMesh's OFF reader is not used: it reads coordinates with iostreams (a "nan" stops the
// stream and every later vertex and face is garbage), still yields the declared number of faces
// when the file is cut short (repeating the last one read), and trusts corner counts, so one
// corrupt count makes it read billions of indices from a failed stream.
Scene loadOff(const std::string& path) {
  const std::string text = readWholeFile(path);
  std::vector<std::string_view> lines;
  size_t pos = 0;
  while (pos < text.size()) {
    std::string_view line = nextLine(text, pos);
    line = trimmed(line.substr(0, line.find('#')));
    if (!line.empty()) lines.push_back(line);
  }
  if (lines.empty()) fail(path, "cannot parse as OFF: no header");

  std::vector<std::string_view> words;
  auto split = [&words](std::string_view line) {
    words.clear();
    for (std::string_view w = nextWord(line); !w.empty(); w = nextWord(line)) words.push_back(w);
  };
  split(lines[0]);
  const std::string keyword(words.empty() ? std::string_view() : words[0]);
  if (keyword.size() < 3 || keyword.compare(keyword.size() - 3, 3, "OFF") != 0)
    fail(path, "cannot parse as OFF: first line is not an OFF header");
  const std::string prefix = keyword.substr(0, keyword.size() - 3);
  if (std::find(words.begin(), words.end(), "BINARY") != words.end())
    fail(path, "binary OFF is not supported");
  if (prefix.find('n') != std::string::npos)
    fail(path, "n-dimensional OFF (" + keyword + ") is not supported");
  const bool homogeneous = prefix.find('4') != std::string::npos;
  const bool has_texcoords = prefix.find("ST") != std::string::npos;

  // Counts follow the keyword on its own line, or (rarely) on the same line.
  size_t body = 1;
  if (words.size() < 3) {
    if (lines.size() < 2) fail(path, "cannot parse as OFF: no element counts");
    split(lines[1]);
    body = 2;
  } else {
    words.erase(words.begin());
  }
  int64_t vertices = -1, faces = -1;
  if (words.size() < 2 || !parseInteger(words[0], vertices) || !parseInteger(words[1], faces) ||
      vertices < 0 || faces < 0)
    fail(path, "cannot parse as OFF: malformed element counts");
  const uint64_t needed = static_cast<uint64_t>(vertices) + static_cast<uint64_t>(faces);
  if (lines.size() - body < needed) {
    fail(path, "truncated OFF: header declares " + std::to_string(vertices) + " vertices and " +
                   std::to_string(faces) + " faces, the file has " +
                   std::to_string(lines.size() - body) + " element lines");
  }

  PolygonSoup soup;
  LoadReport report;
  soup.positions.reserve(static_cast<size_t>(vertices));
  if (has_texcoords) soup.vertex_texcoords.reserve(static_cast<size_t>(vertices));
  const size_t coordinates = homogeneous ? 4 : 3;
  size_t unreadable_vertices = 0;
  for (size_t v = 0; v < static_cast<size_t>(vertices); ++v) {
    split(lines[body + v]);
    float c[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    bool readable = words.size() >= coordinates;
    for (size_t k = 0; readable && k < coordinates; ++k) readable = parseFloat(words[k], c[k]);
    glm::vec3 p(c[0], c[1], c[2]);
    if (homogeneous) p /= c[3];
    if (!readable) {
      ++unreadable_vertices;
      p = glm::vec3(std::numeric_limits<float>::quiet_NaN());
    }
    soup.positions.push_back(p);
    if (has_texcoords) {
      glm::vec2 st(0.0f);
      if (words.size() < coordinates + 2 || !parseFloat(words[words.size() - 2], st.x) ||
          !parseFloat(words.back(), st.y))
        st = glm::vec2(0.0f);
      soup.vertex_texcoords.push_back(st);
    }
  }

  std::vector<int64_t> face;
  size_t malformed_corners = 0;
  for (size_t f = 0; f < static_cast<size_t>(faces); ++f) {
    split(lines[body + static_cast<size_t>(vertices) + f]);
    int64_t corners = -1;
    // A line of separators only (vertical tabs, form feeds) has no words.
    if (words.empty() || !parseInteger(words[0], corners) || corners < 0 ||
        static_cast<uint64_t>(corners) > words.size() - 1) {
      // The problem first, then the line, quoted short: a long line must not push it out of
      // the one-line message.
      const std::string_view line = lines[body + static_cast<size_t>(vertices) + f];
      fail(path, "cannot parse as OFF: face " + std::to_string(f) +
                     " does not list the corners it declares (line '" +
                     std::string(line.substr(0, 60)) + (line.size() > 60 ? "...'" : "'") + ")");
    }
    face.clear();
    for (size_t k = 1; k <= static_cast<size_t>(corners); ++k) {
      int64_t index = -1;
      if (!parseInteger(words[k], index)) ++malformed_corners;
      face.push_back(index);  // -1 when unreadable: validation counts it out of range
    }
    soup.addFace(face.data(), face.size());
  }

  if (unreadable_vertices > 0)
    report.warnings.push_back(std::to_string(unreadable_vertices) +
                              " vertex lines without readable coordinates (kept as non-finite)");
  if (malformed_corners > 0)
    report.warnings.push_back(std::to_string(malformed_corners) +
                              " face corners without a readable vertex index");
  return sceneFromSoup(path, soup, std::move(report));
}

}  // namespace strata::loader
