// `hybrid`: hybrid transparency (Maule, Comba, Torchelsen and Bastos, I3D 2013), an approximate
// method: one geometry pass in which each pixel keeps its settings.k nearest fragments exactly,
// sorted in the tile's local memory, and blends the others order-independently (Bavoil and
// Myers' weighted average), resolved in the same launch (kernels/hybrid.cl). Exact while a pixel
// has at most k fragments.
#include "engine/frontend/local_layers.h"

namespace strata {

std::unique_ptr<ClMethod> makeHybridMethod() {
  // Its own local tables: fragment counts, report scratch, the ordered walk's round, and the
  // tail's colour, opacity and count sums.
  return std::make_unique<LocalLayersMethod>("hybrid", "hybrid_blend_resolve", "blend+resolve",
                                             ST_TILE_PIXELS * (4 + 4 + 4 + 8 + 16 + 4));
}

}  // namespace strata
