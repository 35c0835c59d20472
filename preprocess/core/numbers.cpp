#include "preprocess/core/numbers.h"

#include <exception>

namespace strata {

namespace {

template <class Parse>
auto whole(const std::string& text, Parse parse) -> std::optional<decltype(parse(text, nullptr))> {
  size_t used = 0;
  try {
    const auto v = parse(text, &used);
    if (used != 0 && used == text.size()) return v;
  } catch (const std::exception&) {  // no number, or out of range
  }
  return std::nullopt;
}

}  // namespace

std::optional<double> wholeDouble(const std::string& text) {
  return whole(text, [](const std::string& s, size_t* used) { return std::stod(s, used); });
}

std::optional<long long> wholeInteger(const std::string& text) {
  return whole(text, [](const std::string& s, size_t* used) { return std::stoll(s, used); });
}

}  // namespace strata
