#include "preprocess/core/files.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <mutex>
#include <set>
#include <system_error>

#include "preprocess/core/hash.h"
#include "strata/error.h"

namespace strata {

namespace fs = std::filesystem;

fs::path temporaryPathFor(const fs::path& target) {
  static std::atomic<unsigned> counter{0};
  const std::string name = "." + target.stem().string() + ".tmp-" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter.fetch_add(1)) + target.extension().string();
  return target.parent_path() / name;
}

uintmax_t inputFileSize(const std::string& path, std::string_view what) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (ec || !fs::exists(status)) throw Error(path + ": no such file");
  if (fs::is_directory(status)) throw Error(path + ": is a folder, not " + std::string(what));
  if (!fs::is_regular_file(status)) throw Error(path + ": not a regular file");
  const uintmax_t bytes = fs::file_size(path, ec);
  if (ec) throw Error(path + ": cannot read the file size: " + ec.message());
  if (bytes == 0) throw Error(path + ": empty file (0 bytes), not " + std::string(what));
  return bytes;
}

void removeQuietly(const fs::path& path) {
  std::error_code ec;
  fs::remove(path, ec);
}

namespace {

// Temporary files being written, removed by the signal handler if the process is interrupted.
// Fixed slots of plain bytes: the handler may only make async-signal-safe calls (unlink).
constexpr int kTempSlots = 32;
constexpr size_t kTempPathMax = 4096;
std::atomic<bool> temp_claimed[kTempSlots];  // a writer owns the slot
std::atomic<bool> temp_live[kTempSlots];     // its path is complete: the handler may remove it
char temp_paths[kTempSlots][kTempPathMax];

void unlinkLiveTemporaries() {
  for (int i = 0; i < kTempSlots; ++i)
    if (temp_live[i].load()) ::unlink(temp_paths[i]);
}

void removeTemporariesAndReraise(int sig) {
  unlinkLiveTemporaries();
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

// A slot of the signal handler's list holding `path` (-1 when all are taken or it is too long).
int claimTemporarySlot(const fs::path& path) {
  const std::string& text = path.native();
  if (text.size() >= kTempPathMax) return -1;
  for (int i = 0; i < kTempSlots; ++i) {
    bool expected = false;
    if (!temp_claimed[i].compare_exchange_strong(expected, true)) continue;
    std::memcpy(temp_paths[i], text.c_str(), text.size() + 1);
    temp_live[i].store(true);
    return i;
  }
  return -1;
}

void releaseTemporarySlot(int slot) {
  if (slot < 0) return;
  temp_live[slot].store(false);
  temp_claimed[slot].store(false);
}

// Registers a temporary file for the whole of its write; removes it on scope exit unless kept.
class TemporaryFile {
 public:
  explicit TemporaryFile(fs::path path)
      : path_(std::move(path)), slot_(claimTemporarySlot(path_)) {}
  ~TemporaryFile() {
    if (!kept_) removeQuietly(path_);
    releaseTemporarySlot(slot_);
  }
  TemporaryFile(const TemporaryFile&) = delete;
  TemporaryFile& operator=(const TemporaryFile&) = delete;
  void keep() { kept_ = true; }
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
  int slot_ = -1;
  bool kept_ = false;
};

// Where an output really goes.
struct OutputTarget {
  fs::path path;                  // the file replaced: the final target of a symbolic link
  bool in_place = false;          // a device, FIFO or terminal: written into, never replaced
  std::optional<fs::perms> mode;  // an existing file's permissions, kept
};

OutputTarget resolveOutput(const fs::path& target, std::string_view what) {
  const std::string name = target.string();
  std::error_code ec;
  const fs::file_status st = fs::status(target, ec);  // through symbolic links
  if (fs::exists(st)) {
    if (fs::is_directory(st)) throw Error(name + ": is a folder, not a file");
    if (!fs::is_regular_file(st)) return {target, true, std::nullopt};
  }
  // A symbolic link stays a link: the file it names is replaced.
  fs::path real = target;
  for (int hops = 0; fs::is_symlink(fs::symlink_status(real, ec)); ++hops) {
    if (hops == 40) throw Error(name + ": too many levels of symbolic links");
    const fs::path next = fs::read_symlink(real, ec);
    if (ec) throw Error(name + ": cannot read the symbolic link (" + ec.message() + ")");
    real = next.is_absolute() ? next : real.parent_path() / next;
  }
  OutputTarget out{real, false, std::nullopt};
  if (fs::exists(st)) {
    const fs::perms p = st.permissions();
    const fs::perms writable =
        fs::perms::owner_write | fs::perms::group_write | fs::perms::others_write;
    if ((p & writable) == fs::perms::none || ::access(real.c_str(), W_OK) != 0)
      throw Error(name + ": the existing " + std::string(what) + " is read-only (not replaced)");
    out.mode = p;
  }
  return out;
}

// Writes all of `bytes` to an open descriptor; false on any error (a full disk).
bool writeAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= size_t(n);
  }
  return true;
}

// Flushes a finished temporary file to the disk, so a full disk or an I/O error shows here and
// not after the rename.
void syncFile(const fs::path& temp, const std::string& name, std::string_view what) {
  const int fd = ::open(temp.c_str(), O_RDONLY | O_CLOEXEC);
  const bool ok = fd >= 0 && ::fsync(fd) == 0;
  const int err = errno;
  if (fd >= 0) ::close(fd);
  if (!ok)
    throw Error(name + ": writing the " + std::string(what) + " failed (" + std::strerror(err) +
                ")");
}

// Copies a finished temporary file into a device, FIFO or terminal.
void copyInto(const fs::path& temp, const fs::path& target, std::string_view what) {
  const std::string name = target.string();
  const std::optional<std::string> bytes = readCacheFile(temp, SIZE_MAX);
  if (!bytes) throw Error(name + ": cannot read back the finished " + std::string(what));
  const int fd = ::open(target.c_str(), O_WRONLY | O_CLOEXEC | O_NOCTTY);
  if (fd < 0)
    throw Error(name + ": cannot write the " + std::string(what) + " (" + std::strerror(errno) +
                ")");
  const bool ok = writeAll(fd, bytes->data(), bytes->size());
  const int err = errno;
  ::close(fd);
  if (!ok)
    throw Error(name + ": writing the " + std::string(what) + " failed (" + std::strerror(err) +
                ")");
}

// Writes through a temporary file: outputs resolved (resolveOutput), caches replaced as named.
void writeThroughTemporary(const fs::path& target, std::string_view what, bool cache,
                           const std::function<void(const fs::path& temp)>& write) {
  const std::string name = target.string();
  if (target.filename().empty()) throw Error(name + ": not a file name");
  const OutputTarget out =
      cache ? OutputTarget{target, false, std::nullopt} : resolveOutput(target, what);
  // Beside the file it replaces (one file system, so the rename is one step); for a device,
  // FIFO or terminal in the temporary folder instead (never a new file in /dev).
  TemporaryFile temp(out.in_place
                         ? fs::temp_directory_path() / temporaryPathFor(out.path).filename()
                         : temporaryPathFor(out.path));
  write(temp.path());
  syncFile(temp.path(), name, what);
  if (out.in_place) {
    copyInto(temp.path(), out.path, what);
    return;
  }
  std::error_code ec;
  if (out.mode) fs::permissions(temp.path(), *out.mode, ec);  // the replaced file's permissions
  fs::rename(temp.path(), out.path, ec);
  if (ec)
    throw Error(name + ": cannot move the finished " + std::string(what) + " into place (" +
                ec.message() + ")");
  temp.keep();
}

// Writes `bytes` to a new file at `temp`, every write checked.
void writeBytes(const fs::path& target, const fs::path& temp, std::string_view what,
                std::string_view bytes) {
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
  if (fd < 0)
    throw Error(target.string() + ": cannot write the " + std::string(what) + " (" +
                std::strerror(errno) + ")");
  const bool ok = writeAll(fd, bytes.data(), bytes.size());
  const int err = errno;
  const bool closed = ::close(fd) == 0;
  if (!ok || !closed)
    throw Error(target.string() + ": writing the " + std::string(what) + " failed (" +
                std::strerror(ok ? errno : err) + ")");
}

}  // namespace

void removeTemporaryFilesNow() { unlinkLiveTemporaries(); }

void removeTemporaryFilesOnSignals() {
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction old {};
    if (::sigaction(sig, nullptr, &old) != 0 || old.sa_handler == SIG_IGN) continue;
    struct sigaction action {};
    action.sa_handler = removeTemporariesAndReraise;
    sigemptyset(&action.sa_mask);
    ::sigaction(sig, &action, nullptr);
  }
}

void writeFileAtomically(const fs::path& target, std::string_view what,
                         const std::function<void(const fs::path& temp)>& write) {
  writeThroughTemporary(target, what, false, write);
}

void writeFileAtomically(const fs::path& target, std::string_view what, std::string_view bytes) {
  writeThroughTemporary(target, what, false,
                        [&](const fs::path& temp) { writeBytes(target, temp, what, bytes); });
}

void writeCacheFileAtomically(const fs::path& target, std::string_view what,
                              const std::function<void(const fs::path& temp)>& write) {
  writeThroughTemporary(target, what, true, write);
}

void writeCacheFileAtomically(const fs::path& target, std::string_view what,
                              std::string_view bytes) {
  writeThroughTemporary(target, what, true,
                        [&](const fs::path& temp) { writeBytes(target, temp, what, bytes); });
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

std::string frameCachePayload(const char (&magic)[8], std::string_view payload) {
  std::string out(magic, 8);
  const uint64_t size = payload.size(), sum = fnv1a64(payload);
  out.append(reinterpret_cast<const char*>(&size), 8);
  out.append(reinterpret_cast<const char*>(&sum), 8);
  out.append(payload);
  return out;
}

std::optional<std::string_view> unframeCachePayload(const char (&magic)[8], std::string_view file) {
  constexpr size_t kHeader = 24;
  if (file.size() < kHeader || file.compare(0, 8, std::string_view(magic, 8)) != 0)
    return std::nullopt;
  uint64_t size = 0, sum = 0;
  std::memcpy(&size, file.data() + 8, 8);
  std::memcpy(&sum, file.data() + 16, 8);
  const std::string_view payload = file.substr(kHeader);
  if (size == 0 || size != payload.size() || fnv1a64(payload) != sum) return std::nullopt;
  return payload;
}

ScopedTemporaryFile::ScopedTemporaryFile(fs::path path)
    : path_(std::move(path)), slot_(claimTemporarySlot(path_)) {}

ScopedTemporaryFile::~ScopedTemporaryFile() {
  removeQuietly(path_);
  releaseTemporarySlot(slot_);
}

void removeStaleTemporaries(const fs::path& folder) {
  static std::mutex mutex;
  static std::set<std::string> tidied;
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (!tidied.insert(folder.string()).second) return;
  }
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  const auto day_ago = now - std::chrono::hours(24), quiet_since = now - std::chrono::minutes(10);
  size_t seen = 0;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end && seen < 100000;
       it.increment(ec), ++seen) {
    // ".<stem>.tmp-<pid>-<n><ext>[.<more>]"
    const std::string name = it->path().filename().string();
    const size_t at = name.find(".tmp-");
    if (name.empty() || name[0] != '.' || at == std::string::npos) continue;
    const char* digits = name.c_str() + at + 5;
    char* after = nullptr;
    const long pid = std::strtol(digits, &after, 10);
    if (after == digits || *after != '-' || pid <= 0 || pid > long(INT32_MAX)) continue;
    std::error_code file_ec;
    if (!it->is_regular_file(file_ec)) continue;
    // A cache folder may be shared by machines (a network home under an MPI job), where the pid
    // is another machine's: a file is taken for a dead process's only when no process here has
    // its pid and nothing has written to it for ten minutes (writers append as they go).
    const auto written = it->last_write_time(file_ec);
    if (file_ec) continue;
    const bool dead = pid != long(::getpid()) && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH &&
                      written < quiet_since;
    if (dead || written < day_ago) removeQuietly(it->path());
  }
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
