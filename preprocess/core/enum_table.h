// An enum's names or other values as a table in the order of its values (0, 1, ...): the
// names the command line, JSON and messages use, and back, without a switch per enum.
#pragma once

#include <cstddef>
#include <optional>
#include <string_view>

namespace strata {

// table[value], or `otherwise` for a value past the table's end.
template <class Enum, class T, size_t N>
T enumLookup(Enum value, const T (&table)[N], T otherwise) {
  const auto i = static_cast<size_t>(value);
  return i < N ? table[i] : otherwise;
}

// The value whose name is `name`, if any.
template <class Enum, size_t N>
std::optional<Enum> enumFromName(std::string_view name, const char* const (&names)[N]) {
  for (size_t i = 0; i < N; ++i)
    if (name == names[i]) return static_cast<Enum>(i);
  return std::nullopt;
}

}  // namespace strata
