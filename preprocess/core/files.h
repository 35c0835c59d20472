// Files written whole or not at all, and the per-user cache folder.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

namespace strata {

// A temporary name beside `target` that keeps its extension (so format-by-extension writers
// pick the same format): "<dir>/.<stem>.tmp-<pid>-<n><ext>". The counter keeps concurrent
// writes of one process apart.
std::filesystem::path temporaryPathFor(const std::filesystem::path& target);

// Writes `target` through a temporary file beside it: `write(temp)` creates and fills the
// temporary file (throwing on failure); it is flushed to the disk and only then renamed over
// `target`, in one step. On any failure the temporary file is removed, `target` is left as it
// was and strata::Error names `target` and the cause. `what` names the content in messages
// ("image", "stats"). A symbolic link keeps pointing at the file written (which keeps its
// permissions); an existing read-only file is refused; a device, FIFO or terminal (/dev/null,
// /dev/stdout) is written into once the content is complete, never replaced.
void writeFileAtomically(const std::filesystem::path& target, std::string_view what,
                         const std::function<void(const std::filesystem::path& temp)>& write);
// The same for bytes already in memory; a short write (a full disk) is an error.
void writeFileAtomically(const std::filesystem::path& target, std::string_view what,
                         std::string_view bytes);

// Cache files: the same, except that whatever stands at `target` (a FIFO, a device, a link) is
// replaced by the new file, never written into: a cache is strata's own, and a damaged one must
// not block or divert the write.
void writeCacheFileAtomically(const std::filesystem::path& target, std::string_view what,
                              const std::function<void(const std::filesystem::path& temp)>& write);
void writeCacheFileAtomically(const std::filesystem::path& target, std::string_view what,
                              std::string_view bytes);

// Reads a whole regular file of at most `max_bytes`; nullopt when it is missing, not a regular
// file (a FIFO or a device would hang or never end), larger than `max_bytes` or unreadable. For
// caches, where any of these means "rebuild".
std::optional<std::string> readCacheFile(const std::filesystem::path& path, size_t max_bytes);

// A cache payload framed for checking: the 8-byte `magic`, the payload's length and its FNV-1a 64
// checksum (u64 each, little-endian hosts), then the payload.
std::string frameCachePayload(const char (&magic)[8], std::string_view payload);
// The payload of a framed file, or nullopt when the magic, length or checksum does not match or
// the payload is empty.
std::optional<std::string_view> unframeCachePayload(const char (&magic)[8], std::string_view file);

// The size of `path`, a regular file that is not empty; otherwise an Error naming it: "no such
// file", "is a folder, not WHAT", "not a regular file" (a FIFO or a device would block or never
// end), "empty file (0 bytes), not WHAT".
uintmax_t inputFileSize(const std::string& path, std::string_view what);

void removeQuietly(const std::filesystem::path& path);

// Removes the temporary files (temporaryPathFor's names, and names made from them by adding an
// extension) left directly in `folder` by processes killed while writing a cache: those whose
// pid no process here has and that nothing has written to for ten minutes (the folder may be
// shared with other machines), and any older than a day (a pid may be reused). Once per folder
// per process; for strata's cache folders, called where each is opened (before it is read).
void removeStaleTemporaries(const std::filesystem::path& folder);

// A second temporary file of a write in progress (a side file a writer appends at the end),
// registered like the main one: removed on scope exit and by the signal handlers of
// removeTemporaryFilesOnSignals.
class ScopedTemporaryFile {
 public:
  explicit ScopedTemporaryFile(std::filesystem::path path);
  ~ScopedTemporaryFile();
  ScopedTemporaryFile(const ScopedTemporaryFile&) = delete;
  ScopedTemporaryFile& operator=(const ScopedTemporaryFile&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int slot_ = -1;
};

// Installs handlers for SIGINT, SIGTERM and SIGHUP (unless ignored) that remove the temporary
// files of writes in progress, then end the process as the signal would have. For programs
// (the command line), not for libraries embedded in a host with its own handlers.
void removeTemporaryFilesOnSignals();
// Removes the temporary files being written now (async-signal-safe): for a process about to
// _exit without unwinding.
void removeTemporaryFilesNow();

// $XDG_CACHE_HOME/strata/<sub>, else $HOME/.cache/strata/<sub>, else <tmp>/strata-cache/<sub>.
std::filesystem::path userCacheDir(std::string_view sub = {});

}  // namespace strata
