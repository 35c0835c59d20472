// `mlab`: multi-layer alpha blending (Salvi and Vaidyanathan, I3D 2014), an approximate method:
// one geometry pass in which each pixel keeps settings.k layers sorted by depth in the tile's
// local memory, merging the last two when a fragment would make k + 1, and a resolve in the same
// launch (kernels/mlab.cl, which also says how the tile walk replaces the paper's pixel
// synchronisation). Exact while a pixel has at most k fragments. The paper's 1 to 16 layers take
// up to 20 KB of local memory a tile; more, up to ST_MAX_K, where the device holds them (a CPU
// does).
#include "engine/frontend/local_layers.h"

namespace strata {

std::unique_ptr<ClMethod> makeMlabMethod() {
  // Its own local tables: fragment counts, report scratch, the ordered walk's round.
  return std::make_unique<LocalLayersMethod>("mlab", "mlab_blend_resolve", "blend+resolve",
                                             ST_TILE_PIXELS * (4 + 4 + 4 + 8));
}

}  // namespace strata
