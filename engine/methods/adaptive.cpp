// `adaptive`: adaptive transparency (Salvi, Montgomery and Lefohn, HPG 2011), an approximate
// method: one launch per frame that walks each tile twice in drawing order, first building each
// pixel's visibility function as settings.k nodes in the tile's local memory (compressed by the
// paper's least-area rule when a fragment would make k + 1), then compositing every fragment
// through it, and resolves (kernels/adaptive.cl). Exact while a pixel has at most k fragments.
#include "engine/frontend/local_layers.h"

namespace strata {

std::unique_ptr<ClMethod> makeAdaptiveMethod() {
  // Its own local tables: fragment counts, report scratch, the ordered walk's round and the
  // colour sums; a node is a transmittance and a depth, with one spare node per pixel.
  return std::make_unique<LocalLayersMethod>("adaptive", "adaptive_blend_resolve", "blend+resolve",
                                             ST_TILE_PIXELS * (4 + 4 + 4 + 8 + 12), 1, 1);
}

}  // namespace strata
