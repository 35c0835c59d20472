// glTF 1.0 loading (tinygltf reads only glTF 2.0): .gltf files with external, embedded (data:
// URI) or KHR_binary_glTF buffers, and binary glTF 1.0 (.glb, KHR_binary_glTF). Not part of the
// public interface.
//
// What is read: the default scene's node hierarchy (matrix or translation/rotation/scale, the
// node's `meshes` array) to instances, one per (node, triangle primitive), sharing the node's
// object id; primitives in mode 4 (triangles), 5 (strip) and 6 (fan) with POSITION, TEXCOORD_0
// and indices; materials' `values.diffuse` (an RGBA colour or a texture id; also from
// KHR_materials_common and from the technique's parameter defaults) to the colour or the decoded
// texture with its sampler. Points and lines are skipped with a warning; techniques, shaders,
// animations, skins, cameras and lights are ignored.
//
// Like the glTF 2.0 loader, every accessor is bounds checked before it is read, external files
// may only come from the asset's own folder (absolute URIs and URIs resolving outside it are
// refused), and every problem is an Error whose one-line message names the file and the problem.
#pragma once

#include <string>

#include "preprocess/scene/scene.h"

namespace strata::loader {

// True when `path` holds glTF 1.0: a binary glTF with header version 1, or JSON whose
// asset.version is 1.x (a string such as "1.0" or "1.0.1", or the number 1, as some exporters
// wrote it); without asset.version, when its top-level collections are dictionaries keyed by id
// (glTF 1.0) rather than arrays (2.0). Reads only as far as it needs (the JSON is scanned with a
// SAX parser that stops at asset.version). Never throws: an unreadable file is not glTF 1.0,
// so the caller's normal loader reports it.
bool isGltf1File(const std::string& path);

// Loads a glTF 1.0 file (.gltf or binary; the kind is told by the content, not the extension).
// Throws Error("<path>: <problem>").
Scene loadGltf1(const std::string& path);

}  // namespace strata::loader
