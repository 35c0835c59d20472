// Checks that throw strata::Error instead of aborting, so a library caller gets an exception and
// the CLI its one-line message.
//   STRATA_REQUIRE(cond, message)  bad input or a failed operation: the message is the error
//                                  (an expression convertible to std::string, evaluated only on
//                                  failure).
//   STRATA_CHECK(cond)             an internal invariant: "internal error: FILE:LINE: cond".
#pragma once

#include <string>

#include "strata/error.h"

#include <string_view>

namespace strata {

// A message made safe for one terminal line: control characters (newlines and escape sequences
// included, C1 controls too) and bytes that are not UTF-8 shown as \xNN, and anything past
// `max_bytes` cut at a character boundary with the count of what was left out. Error text can
// quote input files, which must not rewrite the user's terminal or flood it.
std::string printableMessage(std::string_view text, size_t max_bytes = 400);

// A library's error message (OpenImageIO's may span lines) on one line: line breaks as spaces,
// trailing spaces cut, "no reason given by the image library" when nothing is left.
std::string oneLine(std::string message);

}  // namespace strata

namespace strata::detail {
[[noreturn]] void throwInternalError(const char* file, int line, const char* condition);
}  // namespace strata::detail

#define STRATA_REQUIRE(cond, message)                         \
  do {                                                        \
    if (!(cond)) throw ::strata::Error(std::string(message)); \
  } while (0)

#define STRATA_CHECK(cond)                                                        \
  do {                                                                            \
    if (!(cond)) ::strata::detail::throwInternalError(__FILE__, __LINE__, #cond); \
  } while (0)
