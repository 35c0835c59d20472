// Shared by the libFuzzer targets: a private work folder, inputs split into a main file and its
// companions, and the rules every error message must keep (the same rules the command line's
// users rely on). A broken rule aborts, so libFuzzer keeps the input as a crash.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <string_view>
#include <vector>

#include "preprocess/core/check.h"

namespace strata::fuzz {

// One folder per process, emptied before each input, so companions of one input never leak into
// the next.
inline const std::filesystem::path& workFolder() {
  static const std::filesystem::path folder = [] {
    std::string templ = (std::filesystem::temp_directory_path() / "strata-fuzz-XXXXXX").string();
    if (!mkdtemp(templ.data())) {
      std::perror("strata-fuzz: mkdtemp");
      std::abort();
    }
    return std::filesystem::path(templ);
  }();
  return folder;
}

inline void writeFile(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  if (!out) {
    std::fprintf(stderr, "strata-fuzz: cannot write %s\n", path.c_str());
    std::abort();
  }
}

// An input is the main file, optionally followed by companion files, each introduced by a line
// "\n@@file NAME\n" (NAME: letters, digits, '.', '_', '-'; no leading '.'). So an OBJ seed carries
// its MTL and texture, and a glTF seed its buffers and images, and the mutator changes them all.
// Writes them into the (emptied) work folder; returns the main file's path.
inline std::filesystem::path writeInput(std::string_view input, const std::string& main_name) {
  namespace fs = std::filesystem;
  const fs::path& folder = workFolder();
  std::error_code ec;
  for (const fs::directory_entry& e : fs::directory_iterator(folder, ec))
    fs::remove_all(e.path(), ec);
  constexpr std::string_view kMarker = "\n@@file ";
  std::string name = main_name;
  fs::path main_path = folder / main_name;
  while (true) {
    const size_t at = input.find(kMarker);
    writeFile(folder / name, input.substr(0, at));
    if (at == std::string_view::npos) break;
    input.remove_prefix(at + kMarker.size());
    const size_t eol = input.find('\n');
    std::string next(input.substr(0, eol));
    input.remove_prefix(eol == std::string_view::npos ? input.size() : eol + 1);
    bool ok = !next.empty() && next.size() <= 64 && next[0] != '.' && next != main_name;
    for (char c : next)
      ok = ok && (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-');
    name = ok ? next : "ignored.companion";
  }
  return main_path;
}

// Every failure is a strata::Error whose message names the file (here: a path in the work folder,
// or the label given) and is not an internal error; what the CLI prints of it is one line of at
// most a few hundred bytes.
inline void checkErrorMessage(const std::string& what, const std::string& must_name) {
  bool bad = false;
  if (what.find(must_name) == std::string::npos) {
    std::fprintf(stderr, "strata-fuzz: the message does not name '%s'\n", must_name.c_str());
    bad = true;
  }
  // STRATA_CHECK's form ("internal error: FILE.cpp:LINE: ..."), not the words quoted from input.
  static const std::regex internal(R"(internal error: [A-Za-z0-9_]+\.(cpp|h):[0-9]+: )");
  if (std::regex_search(what, internal)) {
    std::fprintf(stderr, "strata-fuzz: an internal error\n");
    bad = true;
  }
  const std::string shown = printableMessage(what);
  if (shown.find('\n') != std::string::npos || shown.size() > 480) {
    std::fprintf(stderr, "strata-fuzz: the printed message is not one short line\n");
    bad = true;
  }
  if (bad) {
    std::fprintf(stderr, "strata-fuzz: message: %s\n", printableMessage(what, 2000).c_str());
    std::abort();
  }
}

}  // namespace strata::fuzz
