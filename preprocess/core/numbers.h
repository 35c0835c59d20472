// Numbers read from text (command-line values, scene names): the whole text must be the number.
#pragma once

#include <optional>
#include <string>

namespace strata {

// `text` as a number in std::stod's syntax (leading blanks allowed), or nothing when it is not
// one or something follows it.
std::optional<double> wholeDouble(const std::string& text);
// `text` as an integer in std::stoll's syntax, or nothing when it is not one, something follows
// it or it is out of range.
std::optional<long long> wholeInteger(const std::string& text);

}  // namespace strata
