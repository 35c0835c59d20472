// data: URIs (RFC 2397): base64 (standard or URL-safe) or percent-encoded payloads, as glTF 1.0
// files embed their buffers and images.
#include <string>
#include <string_view>
#include <vector>

#include "preprocess/loader_internal.h"

namespace strata::loader {

bool isDataUri(const std::string& uri) { return uri.compare(0, 5, "data:") == 0; }

namespace {

int base64Value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+' || c == '-') return 62;
  if (c == '/' || c == '_') return 63;
  return -1;
}

}  // namespace

// Standard or URL-safe base64, padding optional; false on any other character.
bool base64Decode(std::string_view s, std::vector<unsigned char>& out) {
  while (!s.empty() && s.back() == '=') s.remove_suffix(1);
  if (s.size() % 4 == 1) return false;
  out.clear();
  out.reserve(s.size() / 4 * 3 + 2);
  uint32_t bits = 0;
  int held = 0;
  for (char c : s) {
    const int v = base64Value(c);
    if (v < 0) return false;
    bits = (bits << 6) | uint32_t(v);
    held += 6;
    if (held >= 8) {
      held -= 8;
      out.push_back(static_cast<unsigned char>((bits >> held) & 0xFF));
    }
  }
  return true;
}

// The bytes of a data: URI ("data:[<mediatype>][;base64],<data>").
std::vector<unsigned char> decodeDataUri(const std::string& uri, const std::string& what) {
  const size_t comma = uri.find(',');
  if (comma == std::string::npos) problem(what + ": data URI without a ','");
  const std::string_view header = std::string_view(uri).substr(5, comma - 5);
  const std::string_view payload = std::string_view(uri).substr(comma + 1);
  std::vector<unsigned char> bytes;
  const bool base64 = header.size() >= 7 && header.substr(header.size() - 7) == ";base64";
  if (base64) {
    if (!base64Decode(payload, bytes)) problem(what + ": data URI holds invalid base64");
  } else {
    const std::string text = percentDecode(payload);
    bytes.assign(text.begin(), text.end());
  }
  return bytes;
}

}  // namespace strata::loader
