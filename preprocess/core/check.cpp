#include "preprocess/core/check.h"

#include <cstring>

namespace strata {

std::string oneLine(std::string message) {
  for (char& c : message)
    if (c == '\n' || c == '\r') c = ' ';
  while (!message.empty() && message.back() == ' ') message.pop_back();
  return message.empty() ? std::string("no reason given by the image library") : message;
}

std::string printableMessage(std::string_view text, size_t max_bytes) {
  std::string out;
  auto escaped = [&](unsigned char c) {
    static const char* hex = "0123456789abcdef";
    out += "\\x";
    out += hex[c >> 4];
    out += hex[c & 15];
  };
  size_t i = 0;
  for (; i < text.size() && out.size() < max_bytes;) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7f) {
      out += char(c);
      ++i;
      continue;
    }
    if (c < 0x80) {  // C0 controls and DEL
      escaped(c);
      ++i;
      continue;
    }
    // A well-formed UTF-8 sequence is kept, unless it encodes a C1 control (U+0080..U+009F).
    const int length = c >= 0xf0 && c < 0xf5 ? 4 : c >= 0xe0 ? 3 : c >= 0xc2 && c < 0xe0 ? 2 : 0;
    bool valid = length > 0 && i + size_t(length) <= text.size();
    for (int k = 1; valid && k < length; ++k)
      valid = (static_cast<unsigned char>(text[i + size_t(k)]) & 0xc0) == 0x80;
    if (valid && length == 3 && c == 0xe0) valid = static_cast<unsigned char>(text[i + 1]) >= 0xa0;
    if (valid && length == 3 && c == 0xed) valid = static_cast<unsigned char>(text[i + 1]) < 0xa0;
    if (valid && length == 4 && c == 0xf0) valid = static_cast<unsigned char>(text[i + 1]) >= 0x90;
    if (valid && length == 4 && c == 0xf4) valid = static_cast<unsigned char>(text[i + 1]) < 0x90;
    if (valid && length == 2 && c == 0xc2) valid = static_cast<unsigned char>(text[i + 1]) >= 0xa0;
    if (!valid) {
      escaped(c);
      ++i;
      continue;
    }
    out.append(text.substr(i, size_t(length)));
    i += size_t(length);
  }
  if (i < text.size()) out += "... (" + std::to_string(text.size() - i) + " more bytes)";
  return out;
}

}  // namespace strata

namespace strata::detail {

void throwInternalError(const char* file, int line, const char* condition) {
  const char* base = std::strrchr(file, '/');
  throw Error(std::string("internal error: ") + (base ? base + 1 : file) + ":" +
              std::to_string(line) + ": " + condition);
}

}  // namespace strata::detail
