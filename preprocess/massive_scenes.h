// Massive procedural scenes for the octree method, deterministic (integer hashing only, no
// library random generator), in world space (identity instances), so `strata export` hands any
// other tool the same triangles:
//   builtin:hairball:N  N thin closed tubes winding through a ball; depth complexity 100+ at the
//                       default 1200 tubes (about 2.9M triangles)
//   builtin:city:N      an N x N grid of blocks of tessellated buildings and towers, touching and
//                       coplanar walls, open walls (a box missing a face), dangling single
//                       triangles (signs); about 2M triangles at the default N = 32
//   builtin:shells:N    N nested closed bumpy shells (the medical isosurface stack), one mesh
//                       and material each; 65,024 triangles each, opacity 0.2
//   builtin:soup:N      N random triangle-soup faces: self-intersecting, coplanar overlapping,
//                       exact duplicates, fans of more than two faces on one edge, slivers
#pragma once

#include "preprocess/scene/scene.h"

namespace strata {

inline constexpr int kDefaultHairballTubes = 1200;
inline constexpr int kDefaultCityBlocks = 32;
inline constexpr int kDefaultShells = 8;
inline constexpr int kDefaultSoupTriangles = 200000;

Scene makeHairball(int tubes);
Scene makeCity(int blocks_per_side);
Scene makeShells(int shells);
Scene makeSoup(int triangles);

}  // namespace strata
