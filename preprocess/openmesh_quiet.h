// Silences OpenMesh's error stream (omerr) for a scope: add_face reports every face it refuses,
// which real inputs have and the callers report in their own terms. Include only from .cpp
// files that use OpenMesh.
#pragma once

#include <OpenMesh/Core/System/omstream.hh>

namespace strata {

class QuietOmerr {
 public:
  QuietOmerr() : was_enabled_(::omerr().is_enabled()) { ::omerr().disable(); }
  ~QuietOmerr() {
    if (was_enabled_) ::omerr().enable();
  }
  QuietOmerr(const QuietOmerr&) = delete;
  QuietOmerr& operator=(const QuietOmerr&) = delete;

 private:
  bool was_enabled_;
};

}  // namespace strata
