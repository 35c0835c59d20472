// Placeholder until the method lands.
#include "engine/cl_pipeline.h"

namespace strata {

std::unique_ptr<ClMethod> makeMdtsMethod(bool) {
  throw Error("this method is not implemented yet");
}

}  // namespace strata
