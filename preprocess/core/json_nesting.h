// A bound on the nesting of JSON text, checked before it is parsed: nlohmann::json destroys (and
// tinygltf walks) a document recursively, so arrays nested a hundred thousand deep in a 60 KB
// file would run the stack out. No glTF or strata document comes near the bound.
#pragma once

#include <cstddef>
#include <string_view>

namespace strata {

inline constexpr size_t kMaxJsonNesting = 256;

// The deepest nesting of arrays and objects in `text` (strings and their escapes skipped), or
// kMaxJsonNesting + 1 as soon as it goes past kMaxJsonNesting. Not a validator: malformed text
// gets a number too, and the parser then says what is wrong.
inline size_t jsonNestingDepth(std::string_view text) {
  size_t depth = 0, deepest = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\')
        ++i;
      else if (c == '"')
        in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > deepest && (deepest = depth) > kMaxJsonNesting) return deepest;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

}  // namespace strata
