#include "preprocess/core/files.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <system_error>

#include "strata/error.h"

namespace strata {

namespace fs = std::filesystem;

fs::path temporaryPathFor(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  const std::string name = "." + target.stem().string() + ".tmp-" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter.fetch_add(1)) + target.extension().string();
  return target.parent_path() / name;
}

void removeQuietly(const fs::path& path) {
  std::error_code ec;
  fs::remove(path, ec);
}

void writeFileAtomically(const fs::path& target, std::string_view what,
                         const std::function<void(const fs::path& temp)>& write) {
  const std::string name = target.string();
  if (target.filename().empty()) throw Error(name + ": not a file name");
  const fs::path temp = temporaryPathFor(target);
  try {
    write(temp);
  } catch (...) {
    removeQuietly(temp);
    throw;
  }
  std::error_code ec;
  fs::rename(temp, target, ec);
  if (ec) {
    removeQuietly(temp);
    throw Error(name + ": cannot move the finished " + std::string(what) + " into place (" +
                ec.message() + ")");
  }
}

void writeFileAtomically(const fs::path& target, std::string_view what, std::string_view bytes) {
  writeFileAtomically(target, what, [&](const fs::path& temp) {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    if (!out)
      throw Error(target.string() + ": cannot write the " + std::string(what) + " (" +
                  std::strerror(errno) + ")");
    out.write(bytes.data(), std::streamsize(bytes.size()));
    out.close();
    if (!out)
      throw Error(target.string() + ": writing the " + std::string(what) + " failed (disk full?)");
  });
}

std::optional<std::string> readCacheFile(const fs::path& path, size_t max_bytes) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return std::nullopt;
  const uintmax_t size = fs::file_size(path, ec);
  if (ec || size > max_bytes) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::string bytes(size_t(size), '\0');
  in.read(bytes.data(), std::streamsize(bytes.size()));
  if (size_t(in.gcount()) != bytes.size()) return std::nullopt;
  return bytes;
}

fs::path userCacheDir(std::string_view sub) {
  fs::path root;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x)
    root = fs::path(x) / "strata";
  else if (const char* home = std::getenv("HOME"); home && *home)
    root = fs::path(home) / ".cache" / "strata";
  else
    root = fs::temp_directory_path() / "strata-cache";
  return sub.empty() ? root : root / std::string(sub);
}

}  // namespace strata
