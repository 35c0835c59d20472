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
// temporary file (throwing on failure); only then is it renamed over `target`, in one step. On
// any failure the temporary file is removed, `target` is left as it was and strata::Error names
// `target` and the cause. `what` names the content in messages ("image", "stats").
void writeFileAtomically(const std::filesystem::path& target, std::string_view what,
                         const std::function<void(const std::filesystem::path& temp)>& write);
// The same for bytes already in memory; a short write (a full disk) is an error.
void writeFileAtomically(const std::filesystem::path& target, std::string_view what,
                         std::string_view bytes);

// Reads a whole regular file of at most `max_bytes`; nullopt when it is missing, not a regular
// file (a FIFO or a device would hang or never end), larger than `max_bytes` or unreadable. For
// caches, where any of these means "rebuild".
std::optional<std::string> readCacheFile(const std::filesystem::path& path, size_t max_bytes);

void removeQuietly(const std::filesystem::path& path);

// $XDG_CACHE_HOME/strata/<sub>, else $HOME/.cache/strata/<sub>, else <tmp>/strata-cache/<sub>.
std::filesystem::path userCacheDir(std::string_view sub = {});

}  // namespace strata
