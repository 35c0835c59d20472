// Frame statistics as JSON (the `--stats` file) and as a readable line.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "engine/renderer.h"

namespace strata {

nlohmann::json statsToJson(const FrameStats& stats, const std::string& scene);
// Writes text to `path` through a temporary file and a rename; throws Error naming the path.
void writeTextFileAtomically(const std::string& path, const std::string& text);

}  // namespace strata
