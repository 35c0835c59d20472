// strata::Error: every user-facing failure (bad file, bad option, bad input arrays, device fault)
// is reported as an Error whose message is one line naming the file or the call and the problem.
#pragma once

#include <stdexcept>

namespace strata {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace strata
