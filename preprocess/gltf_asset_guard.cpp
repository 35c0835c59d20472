#include "preprocess/gltf_asset_guard.h"

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>

#include "preprocess/core/json_nesting.h"
#include "preprocess/loader_internal.h"

namespace strata::loader {

namespace fs = std::filesystem;

AssetFolderGuard::AssetFolderGuard(const std::string& asset_path) {
  std::error_code ec;
  asset_file_ = fs::absolute(asset_path, ec).lexically_normal().string();
  folder_ = confinementFolder(fs::path(asset_file_).parent_path());
  // tinygltf's base directory is the asset path up to its last slash, joined with "/".
  const size_t slash = asset_file_.find_last_of('/');
  base_prefix_ = asset_file_.substr(0, slash + 1);
}

tinygltf::FsCallbacks AssetFolderGuard::callbacks() {
  tinygltf::FsCallbacks cb;
  cb.FileExists = &fileExists;
  cb.ExpandFilePath = &expandFilePath;
  cb.ReadWholeFile = &readWholeFile;
  cb.WriteWholeFile = &writeWholeFile;
  cb.user_data = this;
  return cb;
}

// The file to open for a path tinygltf asks about: the asset itself, or the asset's folder
// joined with the URI as percentDecode decodes it; empty when it may not be read (tinygltf's
// fallback probe of the current directory, or a URI uriRefusal refuses).
std::string AssetFolderGuard::resolve(const std::string& path) {
  if (path == asset_file_) return path;
  if (path.compare(0, base_prefix_.size(), base_prefix_) != 0) {
    // tinygltf's fallback probe relative to the current directory: assets resolve against
    // their own folder only. Not a rejection of the URI itself.
    return {};
  }
  std::string uri = path.substr(base_prefix_.size()), decoded = uri;
  if (const auto it = uris_.find(uri); it != uris_.end()) {
    uri = it->second.first;
    decoded = it->second.second;
  }
  // The path checked is the one opened: checking one name and opening another would let a
  // crafted URI through.
  const std::string opened = base_prefix_ + decoded;
  const std::string refusal = uriRefusal(uri, decoded, fs::path(opened), folder_);
  if (!refusal.empty()) {
    reject(refusal);
    return {};
  }
  return opened;
}

// The asset's JSON: the whole of a .gltf file, a GLB's first chunk.
std::string_view AssetFolderGuard::jsonChunk(const std::vector<unsigned char>& bytes) {
  const char* begin = reinterpret_cast<const char*>(bytes.data());
  size_t size = bytes.size();
  if (bytes.size() >= 20 && std::memcmp(begin, "glTF", 4) == 0) {
    uint32_t length = 0;
    std::memcpy(&length, begin + 12, 4);
    begin += 20;
    size = std::min<size_t>(length, bytes.size() - 20);
  }
  return std::string_view(begin, size);
}

// The buffer and image URIs of the asset's JSON (a .gltf file, or a GLB's JSON chunk), keyed
// by what tinygltf's decoder makes of them. Unparsable JSON adds none: tinygltf then fails.
void AssetFolderGuard::learnUris(const std::vector<unsigned char>& bytes) {
  const std::string_view json = jsonChunk(bytes);
  const nlohmann::json doc = nlohmann::json::parse(json.begin(), json.end(), nullptr, false);
  if (!doc.is_object()) return;
  for (const char* list : {"buffers", "images"}) {
    const auto it = doc.find(list);
    if (it == doc.end() || !it->is_array()) continue;
    for (const nlohmann::json& item : *it) {
      if (!item.is_object() || !item.contains("uri") || !item["uri"].is_string()) continue;
      const std::string raw = item["uri"].get<std::string>();
      if (raw.rfind("data:", 0) == 0) continue;
      uris_.emplace(libraryDecode(raw), std::make_pair(raw, percentDecode(raw)));
    }
  }
}

// tinygltf's URI decoding (dlib's urldecode), to recognise the URIs it asks about.
std::string AssetFolderGuard::libraryDecode(const std::string& s) {
  auto hex = [](char c) { return unsigned(std::max(hexValue(c), 0)); };  // 0 for a non-digit
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%' && s.size() > i + 2) {
      out += static_cast<char>((hex(s[i + 1]) << 4) | hex(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

bool AssetFolderGuard::reject(const std::string& reason) {
  if (std::find(rejected_.begin(), rejected_.end(), reason) == rejected_.end())
    rejected_.push_back(reason);
  return false;
}

bool AssetFolderGuard::fileExists(const std::string& path, void* self) {
  const std::string opened = static_cast<AssetFolderGuard*>(self)->resolve(path);
  if (opened.empty()) return false;
  std::error_code ec;
  return fs::is_regular_file(opened, ec);
}

std::string AssetFolderGuard::expandFilePath(const std::string& path, void*) {
  return path;  // no ~ or $VAR expansion: URIs are data, not shell words
}

bool AssetFolderGuard::readWholeFile(std::vector<unsigned char>* out, std::string* err,
                                     const std::string& path, void* self_pointer) {
  AssetFolderGuard* self = static_cast<AssetFolderGuard*>(self_pointer);
  const std::string opened = self->resolve(path);
  if (opened.empty()) {
    if (err) *err += "refusing to read outside the asset folder: " + path + "\n";
    return false;
  }
  std::ifstream in(opened, std::ios::binary);
  if (!in) {
    if (err) *err += "cannot open " + path + "\n";
    return false;
  }
  out->assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) {
    if (err) *err += "read error on " + path + "\n";
    return false;
  }
  if (opened == self->asset_file_) {
    const std::string_view json = jsonChunk(*out);
    if (jsonNestingDepth(json) > kMaxJsonNesting) {
      self->reject("the JSON nests arrays and objects more than " +
                   std::to_string(kMaxJsonNesting) + " deep");
      if (err) *err += "JSON nested too deep\n";
      return false;
    }
    self->learnUris(*out);
  }
  return true;
}

bool AssetFolderGuard::writeWholeFile(std::string* err, const std::string&,
                                      const std::vector<unsigned char>&, void*) {
  if (err) *err += "the loader never writes files\n";
  return false;
}

}  // namespace strata::loader
