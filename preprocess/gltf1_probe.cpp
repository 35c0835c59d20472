// Telling glTF 1.0 from 2.0 without reading the whole file: the binary header's version, or
// asset.version found by a SAX pass over the JSON that stops there.
#include <cstring>
#include <fstream>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "preprocess/gltf1_loader.h"

namespace strata::loader {

namespace {

using json = nlohmann::json;

class VersionProbe : public nlohmann::json_sax<json> {
 public:
  // Decision from what was seen, also after a parse error (a cut file is judged by its start).
  bool isVersion1() const {
    if (version_string_)
      return version_string_->size() >= 1 && (*version_string_)[0] == '1' &&
             (version_string_->size() == 1 || (*version_string_)[1] == '.');
    if (version_number_) return *version_number_ >= 1.0 && *version_number_ < 2.0;
    return top_is_object_ && dictionaries_ && !arrays_;
  }

  bool null() override { return scalar(); }
  bool boolean(bool) override { return scalar(); }
  bool number_integer(number_integer_t v) override { return number(double(v)); }
  bool number_unsigned(number_unsigned_t v) override { return number(double(v)); }
  bool number_float(number_float_t v, const string_t&) override { return number(v); }
  bool string(string_t& s) override {
    if (atVersion()) {
      version_string_ = s;
      return false;  // found: stop reading
    }
    return true;
  }
  bool binary(binary_t&) override { return true; }
  bool start_object(std::size_t) override { return open(true); }
  bool end_object() override { return close(); }
  bool start_array(std::size_t) override { return open(false); }
  bool end_array() override { return close(); }
  bool key(string_t& k) override {
    if (depth_ == 1) key1_ = k;
    if (depth_ == 2) key2_ = k;
    return true;
  }
  bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override {
    return false;
  }

 private:
  bool atVersion() const {
    return depth_ == 2 && asset_is_object_ && key1_ == "asset" && key2_ == "version";
  }
  bool scalar() { return depth_ > 0; }  // a bare scalar at the top is not glTF: stop
  bool number(double v) {
    if (atVersion()) {
      version_number_ = v;
      return false;
    }
    return depth_ > 0;
  }
  bool open(bool object) {
    if (depth_ == 0) {
      top_is_object_ = object;
      if (!object) return false;
    } else if (depth_ == 1) {
      key2_.clear();
      if (key1_ == "asset") asset_is_object_ = object;
      if (key1_ == "accessors" || key1_ == "bufferViews" || key1_ == "buffers" ||
          key1_ == "meshes" || key1_ == "nodes" || key1_ == "materials" || key1_ == "scenes")
        (object ? dictionaries_ : arrays_) = true;
    }
    ++depth_;
    return true;
  }
  bool close() {
    --depth_;
    return true;
  }

  int depth_ = 0;
  std::string key1_, key2_;
  bool top_is_object_ = false, asset_is_object_ = false;
  bool dictionaries_ = false, arrays_ = false;
  std::optional<std::string> version_string_;
  std::optional<double> version_number_;
};

}  // namespace

bool isGltf1File(const std::string& path) {
  try {
    std::ifstream in(path, std::ios::binary);
    if (!in) return false;
    unsigned char header[8] = {};
    in.read(reinterpret_cast<char*>(header), sizeof header);
    if (in.gcount() >= 4 && std::memcmp(header, "glTF", 4) == 0)
      return in.gcount() == 8 && (uint32_t(header[4]) | uint32_t(header[5]) << 8 |
                                  uint32_t(header[6]) << 16 | uint32_t(header[7]) << 24) == 1;
    in.clear();
    in.seekg(0);
    VersionProbe probe;
    json::sax_parse(in, &probe);
    return probe.isVersion1();
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace strata::loader
