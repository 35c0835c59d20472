// Render-state bits of a material: what a draw unit's state key is made of (textured, two-sided,
// alpha mode, effect, kernel variant, texture binding). The scene model computes them per
// material; batching and draw sorting (engine/features/draw_sort.h) order draws by them.
#pragma once

#include <cstdint>

namespace strata {

namespace draw_state {
inline constexpr uint64_t kTextured = 1ull << 0;
inline constexpr uint64_t kTwoSided = 1ull << 1;
inline constexpr uint64_t kAlphaBlend = 1ull << 2;  // alpha mode: blend
inline constexpr uint64_t kAlphaMask = 1ull << 3;   // alpha mode: mask (cut-out)
inline constexpr uint64_t kTransparent = 1ull << 4;
inline constexpr int kEffectShift = 8;          // effect id, one bit per effect (8 bits)
inline constexpr int kKernelVariantShift = 16;  // kernel variant, one bit per variant (16 bits)
// The texture bound to a draw when there is no atlas (--atlas off): entry + 1, 24 bits.
inline constexpr int kTextureBindingShift = 40;
}  // namespace draw_state

}  // namespace strata
