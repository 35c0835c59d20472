// tinygltf's file access confined to a glTF asset's folder (what may be read is decided by
// uriRefusal, loader_internal.h, shared with the glTF 1.0 reader). Internal to preprocess/.
//
// tinygltf resolves a URI by decoding its %-escapes, joining it to the asset's folder (and then,
// as a fallback, to the current directory) and asking these callbacks whether the file exists
// and for its bytes. Its decoder is HTML form decoding, not RFC 3986: '+' becomes a space and a
// malformed escape ("%zz") a NUL byte. So the guard reads the URIs as written from the asset's
// own bytes (which tinygltf reads first, through the same callbacks) and opens what
// percentDecode makes of them, as the glTF 1.0 reader does.
#pragma once

#include <tiny_gltf.h>

#include <filesystem>
#include <map>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace strata::loader {

class AssetFolderGuard {
 public:
  explicit AssetFolderGuard(const std::string& asset_path);

  const std::string& assetFile() const { return asset_file_; }
  // One message per refused URI, naming it.
  const std::vector<std::string>& rejections() const { return rejected_; }

  tinygltf::FsCallbacks callbacks();

 private:
  // The file to open for a path tinygltf asks about: the asset itself, or the asset's folder
  // joined with the URI as percentDecode decodes it; empty when it may not be read (tinygltf's
  // fallback probe of the current directory, or a URI uriRefusal refuses).
  std::string resolve(const std::string& path);

  // The asset's JSON: the whole of a .gltf file, a GLB's first chunk.
  static std::string_view jsonChunk(const std::vector<unsigned char>& bytes);

  // The buffer and image URIs of the asset's JSON (a .gltf file, or a GLB's JSON chunk), keyed
  // by what tinygltf's decoder makes of them. Unparsable JSON adds none: tinygltf then fails.
  void learnUris(const std::vector<unsigned char>& bytes);

  // tinygltf's URI decoding (dlib's urldecode), to recognise the URIs it asks about.
  static std::string libraryDecode(const std::string& s);

  bool reject(const std::string& reason);

  static bool fileExists(const std::string& path, void* self);

  static std::string expandFilePath(const std::string& path, void*);

  static bool readWholeFile(std::vector<unsigned char>* out, std::string* err,
                            const std::string& path, void* self_pointer);

  static bool writeWholeFile(std::string* err, const std::string&,
                             const std::vector<unsigned char>&, void*);

  std::string asset_file_;
  std::string base_prefix_;
  std::filesystem::path folder_;
  // tinygltf's decoding of a URI -> the URI as written and its percentDecode.
  std::map<std::string, std::pair<std::string, std::string>> uris_;
  std::vector<std::string> rejected_;
};

}  // namespace strata::loader
