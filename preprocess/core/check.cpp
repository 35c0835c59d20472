#include "preprocess/core/check.h"

#include <cstring>

namespace strata::detail {

void throwInternalError(const char* file, int line, const char* condition) {
  const char* base = std::strrchr(file, '/');
  throw Error(std::string("internal error: ") + (base ? base + 1 : file) + ":" +
              std::to_string(line) + ": " + condition);
}

}  // namespace strata::detail
